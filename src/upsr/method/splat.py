"""Forward registration of the low-res samples (shift-and-add): the nearest forward-registered
sample per high-res pixel, the guide of the fusion's surface competition
(:mod:`upsr.method.fusion`)."""

from __future__ import annotations

import numba as nb
import numpy as np
import numpy.typing as npt

__all__ = ["splat_nearest", "splat_points"]


@nb.njit(cache=True, nogil=True)
def _splat_kernel(values, positions, radius, best_d, best_v):  # pragma: no cover - numba
    n, h, w = values.shape
    hh, ww = best_d.shape
    for k in range(n):
        for i in range(h):
            for j in range(w):
                qx = positions[k, i, j, 0]
                qy = positions[k, i, j, 1]
                v = values[k, i, j]
                y0 = max(int(np.ceil(qy - radius)), 0)
                y1 = min(int(np.floor(qy + radius)), hh - 1)
                x0 = max(int(np.ceil(qx - radius)), 0)
                x1 = min(int(np.floor(qx + radius)), ww - 1)
                for u in range(y0, y1 + 1):
                    for vv in range(x0, x1 + 1):
                        d = (u - qy) ** 2 + (vv - qx) ** 2
                        if d < best_d[u, vv]:
                            best_d[u, vv] = d
                            best_v[u, vv] = v


def splat_points(
    values: npt.ArrayLike,
    positions_px: npt.ArrayLike,
    shape: tuple[int, int],
    radius_px: float = 1.0,
) -> np.ndarray:
    """Nearest forward-registered sample per high-res pixel (shift-and-add, Farsiu et al. 2004).

    Each low-res pixel of frame t is a point sample of the scene at its centre (high-res
    coordinate (i+0.5)·r − 0.5, ``SPEC.md`` §1). Moved to the reference with its own motion
    C_{t→t0}, the samples of a moving surface land at sub-pixel positions that outline the
    surface at the reference time far more precisely than the r×r blocks of dense upsampling.
    The depth of the nearest sample within ``radius_px`` tells on which surface each high-res
    pixel lies (the guide of :func:`temporal_median`).

    Parameters
    ----------
    values : array_like (N, h, w)
        The low-res frames of the window (mm, 0 = no return).
    positions_px : array_like (N, h, w, 2)
        Where each sample lands on the reference grid, (x, y) in high-res px
        (:func:`upsr.method.registration.trace_to_reference`).
    shape : (H, W)
        Size of the high-res grid.
    radius_px : float
        Largest distance (high-res px) between a pixel and the sample it takes.

    Returns
    -------
    ndarray float32 (H, W): the nearest sample's depth, NaN where none is in reach.
    """
    vals = np.ascontiguousarray(values, dtype=np.float32)
    pos = np.ascontiguousarray(positions_px, dtype=np.float32)
    best_d = np.full(shape, radius_px * radius_px, np.float64)
    best_v = np.full(shape, np.nan, np.float32)
    _splat_kernel(vals, pos, float(radius_px), best_d, best_v)
    return best_v


def splat_nearest(
    lowres: npt.ArrayLike, to_reference: npt.ArrayLike, scale: int, radius_px: float = 1.0
) -> np.ndarray:
    """:func:`splat_points` with dense motion fields to the reference on the high-res grid.

    Parameters
    ----------
    lowres : array_like (N, h, w)
        The low-res frames of the window (mm, 0 = no return).
    to_reference : array_like (N, r·h, r·w, 2)
        Motion of each frame to the reference on its own high-res grid
        (:func:`upsr.method.registration.flows_to_reference`), read at the high-res pixel nearest to
        each low-res pixel centre.
    scale : int
        SR factor r.
    radius_px : float
        Largest distance (high-res px) between a pixel and the sample it takes.

    Returns
    -------
    ndarray float32 (r·h, r·w): the nearest sample's depth, NaN where none is in reach.
    """
    lr = np.asarray(lowres, dtype=np.float32)
    maps = np.asarray(to_reference, dtype=np.float32)
    _, h, w = lr.shape
    hh, ww = maps.shape[1:3]
    centre_y = np.arange(h) * scale + 0.5 * scale - 0.5
    centre_x = np.arange(w) * scale + 0.5 * scale - 0.5
    yi = np.minimum((centre_y + 0.5).astype(np.intp), hh - 1)
    xi = np.minimum((centre_x + 0.5).astype(np.intp), ww - 1)
    pos = maps[:, yi[:, None], xi[None, :], :].copy()
    pos[..., 0] += centre_x[None, None, :]
    pos[..., 1] += centre_y[None, :, None]
    return splat_points(lr, pos, (hh, ww), radius_px)
