"""Fusion of the registered frames by an invalid-aware temporal median (paper eq. 26–28).

Under i.i.d. Laplacian noise the pixel-wise median of the registered upsampled frames is the
maximum-likelihood estimate of z_t0 = B x_t0 (eq. 28). Depth sensors add two kinds of missing
samples, kept apart here:

* **no return** (0 or NaN in the frame, e.g. background out of range, random dropout): these do
  not vote on the depth, but they do vote on *whether there is depth*: a pixel is valid only if
  more than ``min_valid_fraction`` of its in-frame samples are valid (a tie follows the
  reference frame). A random dropout is therefore filled from the other frames, while one stray
  valid sample among "no return"s never invents depth.
* **outside** (the motion points outside the frame, marked NaN in the warped stack by
  :func:`upsr.registration.warp_nearest`): abstains entirely.

Where the valid samples come from several surfaces (sorted samples separated by gaps larger than
``edge_mm``: a depth edge, an occlusion), the surface with the largest vote wins and the output
is the median of its samples only. The fusion therefore never averages foreground with
background, even for an even number of samples: no flying pixels.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import numpy.typing as npt

__all__ = ["OUTSIDE", "temporal_median"]

#: Marker of a registered sample that fell outside its frame (abstains in the fusion).
OUTSIDE = np.float32(np.nan)


@nb.njit(cache=True, nogil=True, inline="always")
def _median_sorted(vals, lo, hi):  # pragma: no cover - numba
    """Median of the sorted vals[lo:hi] (mean of the two middle values for an even count)."""
    m = lo + (hi - lo) // 2
    if (hi - lo) % 2 == 1:
        return vals[m]
    return 0.5 * (vals[m - 1] + vals[m])


@nb.njit(cache=True, nogil=True, parallel=True)
def _median_kernel(stack, weights, guide, guide_bonus, ref, min_valid_fraction, edge_mm, out):
    n, h, w = stack.shape
    for i in nb.prange(h):
        vals = np.empty(n, np.float32)
        wts = np.empty(n, np.float32)
        for j in range(w):
            nv = 0
            w_in = 0.0
            w_valid = 0.0
            for k in range(n):
                v = stack[k, i, j]
                if v != v:  # NaN: outside the frame, abstains
                    continue
                wk = weights[k, i, j]
                w_in += wk
                if v > 0:
                    w_valid += wk
                    # insertion sort into vals[0:nv], weights alongside
                    p = nv
                    while p > 0 and vals[p - 1] > v:
                        vals[p] = vals[p - 1]
                        wts[p] = wts[p - 1]
                        p -= 1
                    vals[p] = v
                    wts[p] = wk
                    nv += 1
            if nv == 0:
                out[i, j] = 0.0
                continue
            r = stack[ref, i, j]
            ref_value = r if (r == r and r > 0) else 0.0
            frac = w_valid / w_in
            if frac < min_valid_fraction or (frac == min_valid_fraction and ref_value == 0.0):
                out[i, j] = 0.0
                continue
            if vals[nv - 1] - vals[0] <= edge_mm:
                out[i, j] = _median_sorted(vals, 0, nv)
                continue
            # samples from several surfaces (a depth edge): the surface with the largest vote
            # weight wins (a tie: the reference's surface); the surface of the guide (the
            # nearest forward-registered sample) gets a bonus; its median is the output
            g = guide[i, j]
            best_lo = 0
            best_hi = 0
            best_w = -np.inf
            lo = 0
            acc = wts[0]
            for p in range(1, nv + 1):
                if p == nv or vals[p] - vals[p - 1] > edge_mm:
                    has_ref = vals[lo] <= ref_value <= vals[p - 1]
                    if g > 0 and vals[lo] - edge_mm <= g <= vals[p - 1] + edge_mm:
                        acc += guide_bonus * w_valid
                    if acc > best_w or (acc == best_w and has_ref):
                        best_w = acc
                        best_lo = lo
                        best_hi = p
                    lo = p
                    acc = 0.0
                if p < nv:
                    acc += wts[p]
            out[i, j] = _median_sorted(vals, best_lo, best_hi)


def temporal_median(
    stack: npt.ArrayLike,
    ref: int | None = None,
    *,
    weights: npt.ArrayLike | None = None,
    guide: npt.ArrayLike | None = None,
    guide_bonus: float = 0.35,
    min_valid_fraction: float = 0.5,
    edge_mm: float = 100.0,
) -> np.ndarray:
    """Invalid-aware pixel-wise temporal median of registered frames (eq. 28).

    Parameters
    ----------
    stack : array_like, (N, H, W)
        Registered frames y_t^{t0}↑ in mm: > 0 valid, 0 = no return, NaN = outside the frame.
    ref : int, optional
        Index of the reference frame in the stack (tie-breaks); default the middle one.
    weights : array_like (N, H, W), optional
        Vote weight of each sample (default 1). They decide whether a pixel is valid (weighted
        share of valid samples) and, where the samples come from several surfaces (spread >
        ``edge_mm``), which surface the pixel belongs to; the depth itself is always the plain
        median of the samples of that surface.
    guide : array_like (H, W), optional
        Where > 0 and the samples come from several surfaces, the surface holding this depth
        gets ``guide_bonus`` × the total valid weight added to its vote (see
        :func:`splat_nearest`).
    guide_bonus : float
        Weight of the guide, as a share of the total valid vote weight.
    min_valid_fraction : float
        A pixel is valid if the share of valid samples among in-frame samples is larger than
        this (equal: valid if the reference sample is).
    edge_mm : float
        Samples further apart than this (mm, a gap in their sorted order) belong to different
        surfaces; only the winning surface's samples form the median.

    Returns
    -------
    ndarray float32 (H, W): the fused depth, 0 where nothing is known.
    """
    arr = np.ascontiguousarray(stack, dtype=np.float32)
    if arr.ndim != 3:
        raise ValueError(f"stack must be (N, H, W), got shape {arr.shape}")
    n = arr.shape[0]
    ref = (n - 1) // 2 if ref is None else int(ref)
    if not 0 <= ref < n:
        raise ValueError(f"ref must be in [0, {n}), got {ref}")
    if weights is None:
        wts = np.ones(arr.shape, np.float32)
    else:
        wts = np.ascontiguousarray(np.broadcast_to(weights, arr.shape), dtype=np.float32)
    if guide is None:
        gd = np.zeros(arr.shape[1:], np.float32)
    else:
        gd = np.ascontiguousarray(guide, dtype=np.float32)
    out = np.empty(arr.shape[1:], np.float32)
    _median_kernel(
        arr, wts, gd, float(guide_bonus), ref, float(min_valid_fraction), float(edge_mm), out
    )
    return out


@nb.njit(cache=True, nogil=True)
def _splat_kernel(lowres, maps, scale, radius, best_d, best_v):  # pragma: no cover - numba
    n, h, w = lowres.shape
    hh, ww = best_d.shape
    half = 0.5 * scale - 0.5
    for k in range(n):
        for i in range(h):
            cy = i * scale + half
            yi = min(int(cy + 0.5), hh - 1)
            for j in range(w):
                cx = j * scale + half
                xi = min(int(cx + 0.5), ww - 1)
                qx = cx + maps[k, yi, xi, 0]
                qy = cy + maps[k, yi, xi, 1]
                v = lowres[k, i, j]
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


def splat_nearest(
    lowres: npt.ArrayLike, to_reference: npt.ArrayLike, scale: int, radius_px: float = 1.0
) -> np.ndarray:
    """Forward-register every low-res sample of a window and keep the nearest per pixel.

    Each low-res pixel of frame t is a point sample of the scene at its centre (high-res
    coordinate (i+0.5)·r − 0.5, ``SPEC.md`` §1). Moved to the reference with its own motion
    C_{t→t0} (shift-and-add, Farsiu et al. 2004), the samples of a moving surface land at
    sub-pixel positions that outline the surface at the reference time far more precisely
    than the r×r blocks of dense upsampling. The depth of the nearest sample within
    ``radius_px`` tells on which surface each high-res pixel lies (the guide of
    :func:`temporal_median`).

    Parameters
    ----------
    lowres : array_like (N, h, w)
        The low-res frames of the window (mm, 0 = no return).
    to_reference : array_like (N, r·h, r·w, 2)
        Motion of each frame to the reference on its own high-res grid
        (:func:`upsr.registration.flows_to_reference`).
    scale : int
        SR factor r.
    radius_px : float
        Largest distance (high-res px) between a pixel and the sample it takes.

    Returns
    -------
    ndarray float32 (r·h, r·w): the nearest sample's depth, NaN where none is in reach.
    """
    lr = np.ascontiguousarray(lowres, dtype=np.float32)
    maps = np.ascontiguousarray(to_reference, dtype=np.float32)
    hh, ww = maps.shape[1:3]
    best_d = np.full((hh, ww), radius_px * radius_px, np.float64)
    best_v = np.full((hh, ww), np.nan, np.float32)
    _splat_kernel(lr, maps, int(scale), float(radius_px), best_d, best_v)
    return best_v
