""":func:`upsr.method.edges.vote_surface` in plain NumPy, for the straightforward path
(:func:`upsr.research.oracle.super_resolve_straightforward`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from upsr.method.config import UPSRConfig
from upsr.method.consistency import hole_backgrounds
from upsr.method.edges import SURFACE_GAP, edge_band

#: "No depth" among the sorted samples: beyond every depth, finite (an absent sample is +inf).
_NO_DEPTH = np.float32(1e30)


def edge_votes_numpy(
    lowres: np.ndarray,
    maps: Sequence[np.ndarray],
    offsets: np.ndarray | None,
    stack: np.ndarray,
    fused: np.ndarray,
    ref: int,
    config: UPSRConfig,
    edge_mm: float,
) -> np.ndarray:
    """The fused frame with the surface of each pixel near the reference's depth edges
    (:func:`upsr.method.edges.edge_band`) from the bilinear votes of the four samples around
    every frame's registered position (see :mod:`upsr.method.edges`).

    Parameters
    ----------
    lowres : ndarray (N, h, w)
        The window's frames (mm; < 0: a removed sample, which abstains).
    maps : sequence of N ndarray (r·h, r·w, 2)
        Motion from the reference to each frame on the output grid (output px).
    offsets : ndarray (N, h, w) or None
        Radial offsets subtracted from frame k's samples at each reference pixel.
    stack : ndarray (N, r·h, r·w)
        The fusion's registered samples (NaN: the frame abstains at the pixel).
    fused : ndarray (r·h, r·w)
        The fusion's output.
    ref : int
        Index of the reference.
    config : UPSRConfig
        ``scale``; ``edge_votes`` (False: ``fused`` as it is); ``check_registration``
        (samples over ``edge_mm`` nearer than the farthest depth around a hole of the
        reference abstain there, the fusion's ``hole_floors``).
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    ndarray float32 (r·h, r·w)
    """
    if not config.edge_votes:
        return fused
    n, h, w = lowres.shape
    r = config.scale
    band = edge_band(lowres[ref], edge_mm)
    ys, xs = np.nonzero(np.repeat(np.repeat(band, r, axis=0), r, axis=1))
    if ys.size == 0:
        return fused
    holes = hole_backgrounds(lowres[ref]) if config.check_registration else np.zeros((h, w))
    bg = holes[ys // r, xs // r]
    floor = np.where(bg > 0, bg - np.float32(edge_mm), -np.inf)
    vals, wts = [], []
    for k in range(n):
        u = (ys + maps[k][ys, xs, 1] + 0.5) / r - 0.5
        v = (xs + maps[k][ys, xs, 0] + 0.5) / r - 0.5
        i0, j0 = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
        fy, fx = u - i0, v - j0
        off = 0.0 if offsets is None else offsets[k, ys // r, xs // r]
        votes = ~np.isnan(stack[k, ys, xs])
        for di in (0, 1):
            for dj in (0, 1):
                z = lowres[k, np.clip(i0 + di, 0, h - 1), np.clip(j0 + dj, 0, w - 1)]
                wt = (fy if di else 1.0 - fy) * (fx if dj else 1.0 - fx)
                val = np.where(z > 0, z - off, _NO_DEPTH).astype(np.float32)
                present = votes & (wt > 0) & (z >= 0) & (val >= floor)
                vals.append(np.where(present, val, np.float32(np.inf)))
                wts.append(np.where(present, wt, 0.0).astype(np.float32))
    order = np.argsort(np.stack(vals), axis=0, kind="stable")
    s = np.take_along_axis(np.stack(vals), order, axis=0)
    wt = np.take_along_axis(np.stack(wts), order, axis=0)
    present = np.isfinite(s)
    count = present.sum(axis=0)
    cols = np.arange(s.shape[1])
    last = s[np.maximum(count - 1, 0), cols]
    # the surfaces: runs without a gap beyond edge_mm ("no depth" a run of its own)
    with np.errstate(invalid="ignore"):
        gap = np.diff(s, axis=0) > edge_mm
    gid = np.cumsum(np.vstack([np.zeros((1, s.shape[1]), bool), gap]), axis=0)
    weight = np.zeros(s.shape, np.float64)
    np.add.at(weight, (gid, np.broadcast_to(cols, s.shape)), wt)
    best = np.argmax(weight, axis=0)  # the first (nearest) of equal weights, as the kernel
    win = (gid == best) & present
    lo = np.where(win, s, np.inf).min(axis=0)
    hi = np.where(win, s, -np.inf).max(axis=0)
    f = fused[ys, xs]
    gap = SURFACE_GAP * edge_mm
    with np.errstate(invalid="ignore"):  # (no sample: inf − inf)
        change = (count > 0) & (last - s[0] > edge_mm) & (f > 0) & (lo < _NO_DEPTH)
        change &= ~((lo - gap <= f) & (f <= hi + gap))
    # the weighted median of the winning surface
    cum = np.cumsum(np.where(win, wt, 0.0), axis=0)
    half = 0.5 * weight[best, cols]
    at = np.argmax(win & (cum >= half), axis=0)
    out = fused.copy()
    out[ys[change], xs[change]] = s[at, cols][change]
    return out
