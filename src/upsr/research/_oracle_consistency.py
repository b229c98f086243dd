""":func:`upsr.method.consistency.registered_samples` and
:func:`upsr.method.consistency.misregistered` in plain NumPy, for the straightforward path
(:func:`upsr.research.oracle.super_resolve_straightforward`) and the tests."""

from __future__ import annotations

import numpy as np


def registered_samples_numpy(lowres: np.ndarray, maps: np.ndarray, scale: int) -> np.ndarray:
    """:func:`upsr.method.consistency.registered_samples` with NumPy: each frame's low-res
    sample at every reference pixel centre moved by the map at its nearest flow-grid node."""
    from upsr.method.consistency import maps_at_centres

    lr = np.nan_to_num(np.asarray(lowres, np.float32), nan=0.0)
    n, h, w = lr.shape
    r = int(scale)
    m = maps_at_centres(maps, (h, w))
    ratio = r * w / np.shape(maps)[2]
    qx = ((np.arange(w) + 0.5) * r - 0.5)[None, None, :] + m[..., 0] * ratio
    qy = ((np.arange(h) + 0.5) * r - 0.5)[None, :, None] + m[..., 1] * ratio
    inside = (qx >= -0.5) & (qx < w * r - 0.5) & (qy >= -0.5) & (qy < h * r - 0.5)
    xl = np.clip(((qx + 0.5) / r).astype(np.int64), 0, w - 1)
    yl = np.clip(((qy + 0.5) / r).astype(np.int64), 0, h - 1)
    k = np.arange(n)[:, None, None]
    return np.where(inside, lr[k, yl, xl], np.float32(np.nan)).astype(np.float32)


def misregistered_numpy(
    registered: np.ndarray,
    reference: np.ndarray,
    ref: int,
    *,
    edge_mm: float,
    offsets: np.ndarray | None = None,
    radius_px: int = 2,
    min_count: int | None = None,
    fraction: float | None = None,
) -> np.ndarray:
    """:func:`upsr.method.consistency.misregistered` with NumPy (shifted copies and box sums
    instead of loops; the same defaults)."""
    from upsr.method.consistency import MISMATCH_FRACTION, MISMATCH_MIN_COUNT

    min_count = MISMATCH_MIN_COUNT if min_count is None else min_count
    fraction = MISMATCH_FRACTION if fraction is None else fraction
    reg = np.asarray(registered, np.float32)
    z = np.nan_to_num(np.asarray(reference, np.float32), nan=0.0)
    h, w = reg.shape[1:]
    pad = np.pad(z, 1, constant_values=np.nan)
    interior = z > 0
    with np.errstate(invalid="ignore"):
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                u = pad[1 + di : 1 + di + h, 1 + dj : 1 + dj + w]
                # NaN: beyond the border, which does not count
                interior &= np.isnan(u) | ((u > 0) & (np.abs(u - z) <= edge_mm))
        offs = np.zeros(reg.shape, np.float32) if offsets is None else np.asarray(offsets)
        checked = interior & (reg > 0)
        bad = checked & ~(np.abs(reg - offs - z) <= edge_mm)
    rad = int(radius_px)

    def box(a: np.ndarray) -> np.ndarray:
        p = np.pad(a.astype(np.int64), ((0, 0), (rad, rad), (rad, rad)))
        win = np.lib.stride_tricks.sliding_window_view(p, (2 * rad + 1, 2 * rad + 1), (1, 2))
        return win.sum(axis=(-1, -2))

    nb_bad, nb_chk = box(bad), box(checked)
    out = (nb_bad >= min_count) & (nb_bad >= fraction * nb_chk)
    out[ref] = False
    return out
