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

import functools

import numba as nb
import numpy as np
import numpy.typing as npt

from .registration import interpolation_tables, weight_table

__all__ = [
    "OUTSIDE",
    "register_and_fuse",
    "sorting_network",
    "splat_nearest",
    "splat_points",
    "temporal_median",
]

#: LLVM fast-math flags that keep NaN and ∞ semantics (NaN marks "outside", +∞ "invalid")
_SAFE_FASTMATH = {"nsz", "arcp", "contract", "afn", "reassoc"}

#: Marker of a registered sample that fell outside its frame (abstains in the fusion).
OUTSIDE = np.float32(np.nan)


@nb.njit(cache=True, nogil=True, inline="always")
def _median_sorted(vals, lo, hi):  # pragma: no cover - numba
    """Median of the sorted vals[lo:hi] (mean of the two middle values for an even count)."""
    m = lo + (hi - lo) // 2
    if (hi - lo) % 2 == 1:
        return vals[m]
    return 0.5 * (vals[m - 1] + vals[m])


@nb.njit(cache=True, nogil=True, inline="always")
def _sort8(v):  # pragma: no cover - numba
    """Sort v[0:8] in place in registers: the 19 comparators of
    ``sorting_network(8)``, unrolled (generated; checked by tests/test_fusion.py)."""
    a0, a1, a2, a3, a4, a5, a6, a7 = v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]
    a0, a1 = min(a0, a1), max(a0, a1)
    a2, a3 = min(a2, a3), max(a2, a3)
    a0, a2 = min(a0, a2), max(a0, a2)
    a1, a3 = min(a1, a3), max(a1, a3)
    a1, a2 = min(a1, a2), max(a1, a2)
    a4, a5 = min(a4, a5), max(a4, a5)
    a6, a7 = min(a6, a7), max(a6, a7)
    a4, a6 = min(a4, a6), max(a4, a6)
    a5, a7 = min(a5, a7), max(a5, a7)
    a5, a6 = min(a5, a6), max(a5, a6)
    a0, a4 = min(a0, a4), max(a0, a4)
    a2, a6 = min(a2, a6), max(a2, a6)
    a2, a4 = min(a2, a4), max(a2, a4)
    a1, a5 = min(a1, a5), max(a1, a5)
    a3, a7 = min(a3, a7), max(a3, a7)
    a3, a5 = min(a3, a5), max(a3, a5)
    a1, a2 = min(a1, a2), max(a1, a2)
    a3, a4 = min(a3, a4), max(a3, a4)
    a5, a6 = min(a5, a6), max(a5, a6)
    v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7] = a0, a1, a2, a3, a4, a5, a6, a7


@nb.njit(cache=True, nogil=True, inline="always")
def _sort9(v):  # pragma: no cover - numba
    """Sort v[0:9] in place in registers: the 28 comparators of
    ``sorting_network(9)``, unrolled (generated; checked by tests/test_fusion.py)."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]
    a0, a1 = min(a0, a1), max(a0, a1)
    a2, a3 = min(a2, a3), max(a2, a3)
    a0, a2 = min(a0, a2), max(a0, a2)
    a1, a3 = min(a1, a3), max(a1, a3)
    a1, a2 = min(a1, a2), max(a1, a2)
    a4, a5 = min(a4, a5), max(a4, a5)
    a6, a7 = min(a6, a7), max(a6, a7)
    a4, a6 = min(a4, a6), max(a4, a6)
    a5, a7 = min(a5, a7), max(a5, a7)
    a5, a6 = min(a5, a6), max(a5, a6)
    a0, a4 = min(a0, a4), max(a0, a4)
    a2, a6 = min(a2, a6), max(a2, a6)
    a2, a4 = min(a2, a4), max(a2, a4)
    a1, a5 = min(a1, a5), max(a1, a5)
    a3, a7 = min(a3, a7), max(a3, a7)
    a3, a5 = min(a3, a5), max(a3, a5)
    a1, a2 = min(a1, a2), max(a1, a2)
    a3, a4 = min(a3, a4), max(a3, a4)
    a5, a6 = min(a5, a6), max(a5, a6)
    a0, a8 = min(a0, a8), max(a0, a8)
    a4, a8 = min(a4, a8), max(a4, a8)
    a2, a4 = min(a2, a4), max(a2, a4)
    a6, a8 = min(a6, a8), max(a6, a8)
    a3, a5 = min(a3, a5), max(a3, a5)
    a1, a2 = min(a1, a2), max(a1, a2)
    a3, a4 = min(a3, a4), max(a3, a4)
    a5, a6 = min(a5, a6), max(a5, a6)
    a7, a8 = min(a7, a8), max(a7, a8)
    v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8] = a0, a1, a2, a3, a4, a5, a6, a7, a8


@nb.njit(cache=True, nogil=True, inline="always")
def _sort16(v):  # pragma: no cover - numba
    """Sort v[0:16] in place in registers: the 63 comparators of
    ``sorting_network(16)``, unrolled (generated; checked by tests/test_fusion.py)."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12, a13, a14, a15 = (
        v[0],
        v[1],
        v[2],
        v[3],
        v[4],
        v[5],
        v[6],
        v[7],
        v[8],
        v[9],
        v[10],
        v[11],
        v[12],
        v[13],
        v[14],
        v[15],
    )
    a0, a1 = min(a0, a1), max(a0, a1)
    a2, a3 = min(a2, a3), max(a2, a3)
    a0, a2 = min(a0, a2), max(a0, a2)
    a1, a3 = min(a1, a3), max(a1, a3)
    a1, a2 = min(a1, a2), max(a1, a2)
    a4, a5 = min(a4, a5), max(a4, a5)
    a6, a7 = min(a6, a7), max(a6, a7)
    a4, a6 = min(a4, a6), max(a4, a6)
    a5, a7 = min(a5, a7), max(a5, a7)
    a5, a6 = min(a5, a6), max(a5, a6)
    a0, a4 = min(a0, a4), max(a0, a4)
    a2, a6 = min(a2, a6), max(a2, a6)
    a2, a4 = min(a2, a4), max(a2, a4)
    a1, a5 = min(a1, a5), max(a1, a5)
    a3, a7 = min(a3, a7), max(a3, a7)
    a3, a5 = min(a3, a5), max(a3, a5)
    a1, a2 = min(a1, a2), max(a1, a2)
    a3, a4 = min(a3, a4), max(a3, a4)
    a5, a6 = min(a5, a6), max(a5, a6)
    a8, a9 = min(a8, a9), max(a8, a9)
    a10, a11 = min(a10, a11), max(a10, a11)
    a8, a10 = min(a8, a10), max(a8, a10)
    a9, a11 = min(a9, a11), max(a9, a11)
    a9, a10 = min(a9, a10), max(a9, a10)
    a12, a13 = min(a12, a13), max(a12, a13)
    a14, a15 = min(a14, a15), max(a14, a15)
    a12, a14 = min(a12, a14), max(a12, a14)
    a13, a15 = min(a13, a15), max(a13, a15)
    a13, a14 = min(a13, a14), max(a13, a14)
    a8, a12 = min(a8, a12), max(a8, a12)
    a10, a14 = min(a10, a14), max(a10, a14)
    a10, a12 = min(a10, a12), max(a10, a12)
    a9, a13 = min(a9, a13), max(a9, a13)
    a11, a15 = min(a11, a15), max(a11, a15)
    a11, a13 = min(a11, a13), max(a11, a13)
    a9, a10 = min(a9, a10), max(a9, a10)
    a11, a12 = min(a11, a12), max(a11, a12)
    a13, a14 = min(a13, a14), max(a13, a14)
    a0, a8 = min(a0, a8), max(a0, a8)
    a4, a12 = min(a4, a12), max(a4, a12)
    a4, a8 = min(a4, a8), max(a4, a8)
    a2, a10 = min(a2, a10), max(a2, a10)
    a6, a14 = min(a6, a14), max(a6, a14)
    a6, a10 = min(a6, a10), max(a6, a10)
    a2, a4 = min(a2, a4), max(a2, a4)
    a6, a8 = min(a6, a8), max(a6, a8)
    a10, a12 = min(a10, a12), max(a10, a12)
    a1, a9 = min(a1, a9), max(a1, a9)
    a5, a13 = min(a5, a13), max(a5, a13)
    a5, a9 = min(a5, a9), max(a5, a9)
    a3, a11 = min(a3, a11), max(a3, a11)
    a7, a15 = min(a7, a15), max(a7, a15)
    a7, a11 = min(a7, a11), max(a7, a11)
    a3, a5 = min(a3, a5), max(a3, a5)
    a7, a9 = min(a7, a9), max(a7, a9)
    a11, a13 = min(a11, a13), max(a11, a13)
    a1, a2 = min(a1, a2), max(a1, a2)
    a3, a4 = min(a3, a4), max(a3, a4)
    a5, a6 = min(a5, a6), max(a5, a6)
    a7, a8 = min(a7, a8), max(a7, a8)
    a9, a10 = min(a9, a10), max(a9, a10)
    a11, a12 = min(a11, a12), max(a11, a12)
    a13, a14 = min(a13, a14), max(a13, a14)
    (
        v[0],
        v[1],
        v[2],
        v[3],
        v[4],
        v[5],
        v[6],
        v[7],
        v[8],
        v[9],
        v[10],
        v[11],
        v[12],
        v[13],
        v[14],
        v[15],
    ) = a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12, a13, a14, a15


def sorting_network(n: int) -> np.ndarray:
    """Comparators (i, j), i < j, of Batcher's odd–even merge sort for n keys, as an (m, 2) array.

    Built for the next power of two and pruned of every comparator that touches a padding
    position ≥ n (padding keys are +∞, already in place, so those never swap). For the usual
    window lengths: 9 keys in 28 compare-exchanges, branch-free, instead of an insertion sort.
    """
    size = 1
    while size < n:
        size *= 2
    pairs: list[tuple[int, int]] = []

    def merge(lo: int, length: int, step: int) -> None:
        double = step * 2
        if double < length:
            merge(lo, length, double)
            merge(lo + step, length, double)
            pairs.extend((i, i + step) for i in range(lo + step, lo + length - step, double))
        else:
            pairs.append((lo, lo + step))

    def sort(lo: int, length: int) -> None:
        if length > 1:
            half = length // 2
            sort(lo, half)
            sort(lo + half, half)
            merge(lo, length, 1)

    sort(0, size)
    kept = [(i, j) for i, j in pairs if j < n]
    return np.array(kept, np.int64).reshape(-1, 2)


@nb.njit(cache=True, nogil=True, inline="always")
def _fuse_pixel(
    vals, wts, nv, w_in, w_valid, ref_value, g, guide_bonus, min_valid_fraction, edge_mm, network
):  # pragma: no cover - numba
    """The fused depth of one pixel from its samples: vals[k] > 0 valid (else +inf) with vote
    weights wts[k] (0 for invalid ones); nv valid samples; w_in, w_valid the weight of the
    in-frame and of the valid samples; ref_value the reference's sample (0 if none); g the
    guide (≤ 0 or NaN: none). Sorts vals/wts in place."""
    frac = w_valid / w_in
    if frac < min_valid_fraction or (frac == min_valid_fraction and ref_value == 0.0):
        return np.float32(0.0)
    # sort the keys (invalid ones are +inf and end up last), weights alongside
    for c in range(network.shape[0]):
        a = network[c, 0]
        b = network[c, 1]
        if vals[a] > vals[b]:
            tv = vals[a]
            vals[a] = vals[b]
            vals[b] = tv
            tw = wts[a]
            wts[a] = wts[b]
            wts[b] = tw
    if vals[nv - 1] - vals[0] <= edge_mm:
        return _median_sorted(vals, 0, nv)
    # samples from several surfaces (a depth edge): the surface with the largest vote
    # weight wins (a tie: the reference's surface); the surface of the guide (the nearest
    # forward-registered sample) gets a bonus; its median is the output
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
    return _median_sorted(vals, best_lo, best_hi)


@nb.njit(cache=True, nogil=True, parallel=True)
def _median_kernel(
    stack, weights, guide, guide_bonus, ref, min_valid_fraction, edge_mm, network, out
):  # pragma: no cover - numba
    n, h, w = stack.shape
    inf = np.float32(np.inf)
    for i in nb.prange(h):
        vals = np.empty(n, np.float32)
        wts = np.empty(n, np.float32)
        for j in range(w):
            nv = 0
            w_in = 0.0
            w_valid = 0.0
            for k in range(n):
                v = stack[k, i, j]
                wk = weights[k, i, j]
                vals[k] = inf
                wts[k] = 0.0
                if v != v:  # NaN: outside the frame, abstains
                    continue
                w_in += wk
                if v > 0:
                    w_valid += wk
                    vals[k] = v
                    wts[k] = wk
                    nv += 1
            if nv == 0:
                out[i, j] = 0.0
                continue
            r = stack[ref, i, j]
            ref_value = r if (r == r and r > 0) else 0.0
            out[i, j] = _fuse_pixel(
                vals,
                wts,
                nv,
                w_in,
                w_valid,
                ref_value,
                guide[i, j],
                guide_bonus,
                min_valid_fraction,
                edge_mm,
                network,
            )


@nb.njit(cache=True, nogil=True, parallel=True, fastmath=_SAFE_FASTMATH)
def _register_fuse_kernel(
    lowres,
    maps,
    scale,
    ratio,
    cols,
    fx,
    rows,
    fy,
    table,
    step,
    floor,
    guide,
    guide_bonus,
    ref,
    min_valid_fraction,
    edge_mm,
    measured,
    network,
    out,
):  # pragma: no cover - numba
    n = lowres.shape[0]
    hh, ww = out.shape
    inf = np.float32(np.inf)
    last = table.size - 1
    padded = 8 if n <= 8 else (9 if n == 9 else (16 if n <= 16 else n))
    # low-res index of a high-res index, and the high-res coordinate of that pixel's centre
    big = max(hh, ww)
    low_of = np.empty(big, np.int64)
    centre_of = np.empty(big, np.float32)
    for x in range(big):
        low_of[x] = x // scale
        centre_of[x] = (x // scale + 0.5) * scale - 0.5
    for i in nb.prange(hh):
        y0 = rows[i, 0]
        y1 = rows[i, 1]
        gy = fy[i]
        # padded to the unrolled network's size (8, 9 or 16): the padding stays +inf
        vals = np.full(padded, inf, np.float32)
        wts = np.empty(n, np.float32)
        raw = np.empty(n, np.float32)
        ex = np.empty(n, np.float32)  # distance (px) to the sampled low-res pixel's centre
        ey = np.empty(n, np.float32)
        mrow = measured[low_of[i]]
        for j in range(ww):
            if not mrow[low_of[j]]:
                # no frame of the window measured this low-res pixel: never invent depth
                out[i, j] = 0.0
                continue
            a = cols[j, 0]
            b = cols[j, 1]
            gx = fx[j]
            # bilinear weights of the four flow-grid neighbours, times r/s
            w00 = (1 - gx) * (1 - gy) * ratio
            w01 = gx * (1 - gy) * ratio
            w10 = (1 - gx) * gy * ratio
            w11 = gx * gy * ratio
            n_in = 0
            nv = 0
            spread_lo = inf
            spread_hi = -inf
            for k in range(n):
                dx = (
                    maps[k, y0, a, 0] * w00
                    + maps[k, y0, b, 0] * w01
                    + maps[k, y1, a, 0] * w10
                    + maps[k, y1, b, 0] * w11
                )
                dy = (
                    maps[k, y0, a, 1] * w00
                    + maps[k, y0, b, 1] * w01
                    + maps[k, y1, a, 1] * w10
                    + maps[k, y1, b, 1] * w11
                )
                qx = j + dx
                qy = i + dy
                if not (-0.5 <= qx < ww - 0.5 and -0.5 <= qy < hh - 0.5):
                    raw[k] = np.nan  # outside the frame: abstains
                    continue
                xi = int(qx + 0.5)  # qx + 0.5 >= 0: truncation is the floor
                yi = int(qy + 0.5)
                li = low_of[yi]
                lj = low_of[xi]
                v = lowres[k, li, lj]
                raw[k] = v
                n_in += 1
                ex[k] = abs(qx - centre_of[xi])
                ey[k] = abs(qy - centre_of[yi])
                if v > 0:
                    nv += 1
                    spread_lo = min(spread_lo, v)
                    spread_hi = max(spread_hi, v)
            if nv == 0:
                out[i, j] = 0.0
                continue
            if nv == n_in and spread_hi - spread_lo <= edge_mm:
                # the common case: every in-frame sample valid, one surface: the plain
                # median, by a branch-free min/max sorting network
                for k in range(n):
                    v = raw[k]
                    vals[k] = v if v == v else inf
                if padded == 8:
                    _sort8(vals)
                elif padded == 9:
                    _sort9(vals)
                elif padded == 16:
                    _sort16(vals)
                else:
                    for c in range(network.shape[0]):
                        p = network[c, 0]
                        q = network[c, 1]
                        lo_v = min(vals[p], vals[q])
                        vals[q] = max(vals[p], vals[q])
                        vals[p] = lo_v
                out[i, j] = _median_sorted(vals, 0, nv)
                continue
            # some samples invalid, or samples from several surfaces: the vote weights
            # matter (and are only computed) here
            w_in = 0.0
            w_valid = 0.0
            for k in range(n):
                v = raw[k]
                vals[k] = inf
                wts[k] = 0.0
                if v != v:
                    continue
                gx_k = table[min(int(ex[k] * step + 0.5), last)]
                gy_k = table[min(int(ey[k] * step + 0.5), last)]
                wk = floor + (1.0 - floor) * gx_k * gy_k
                w_in += wk
                if v > 0:
                    w_valid += wk
                    vals[k] = v
                    wts[k] = wk
            r = raw[ref]
            ref_value = r if (r == r and r > 0) else 0.0
            out[i, j] = _fuse_pixel(
                vals,
                wts,
                nv,
                w_in,
                w_valid,
                ref_value,
                guide[i, j],
                guide_bonus,
                min_valid_fraction,
                edge_mm,
                network,
            )


@functools.lru_cache(maxsize=16)
def _network(n: int) -> np.ndarray:
    return sorting_network(n)


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
        arr,
        wts,
        gd,
        float(guide_bonus),
        ref,
        float(min_valid_fraction),
        float(edge_mm),
        _network(n),
        out,
    )
    return out


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
        (:func:`upsr.registration.trace_to_reference`).
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
        (:func:`upsr.registration.flows_to_reference`), read at the high-res pixel nearest to
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


def register_and_fuse(
    lowres: npt.ArrayLike,
    maps: npt.ArrayLike,
    scale: int,
    ref: int | None = None,
    *,
    weight_sigma_px: float | None = None,
    weight_floor: float = 0.25,
    guide: npt.ArrayLike | None = None,
    guide_bonus: float = 0.35,
    min_valid_fraction: float = 0.5,
    edge_mm: float = 100.0,
    measured_only: bool = True,
) -> np.ndarray:
    """Registration (eq. 20) and invalid-aware median fusion (eq. 28) in one compiled pass.

    With a flow grid of the output size (s = r) this equals
    ``temporal_median(stack, ref, weights=w, ...)`` with ``stack[k] =
    warp_nearest(upsample_nearest(lowres[k], r), maps[k])`` and ``w = floor + (1 − floor)·
    exp(−d²/(2σ²))``, d from :func:`upsr.registration.sample_offsets` (the Gaussian is
    tabulated every 1/64 px), without building those (N, r·h, r·w) stacks: each output pixel
    reads its N samples straight from the low-res frames, and computes the vote weights only
    where they can matter (some samples invalid, or samples from several surfaces). A coarser
    flow grid (s < r) is interpolated bilinearly (pixel centres aligned, like ``cv2.resize``).

    Parameters
    ----------
    lowres : array_like (N, h, w)
        Low-res frames of the window (mm; 0 or NaN = no return).
    maps : array_like (N, s·h, s·w, 2)
        Motion from the reference to each frame on the flow grid (flow px).
    scale : int
        SR factor r.
    ref : int, optional
        Index of the reference frame (default the middle one).
    weight_sigma_px : float or None
        σ of the vote weights (high-res px); ``None``: equal votes.
    weight_floor : float
        Smallest vote weight.
    guide, guide_bonus, min_valid_fraction, edge_mm
        As in :func:`temporal_median`.
    measured_only : bool
        Output 0 wherever no frame of the window measured the low-res pixel the output pixel
        belongs to (never invent depth where the camera saw nothing, even when the motion
        brings samples there).

    Returns
    -------
    ndarray float32 (r·h, r·w): fused depth (mm), 0 where nothing is known.
    """
    lr = np.ascontiguousarray(lowres, np.float32)
    lr = np.where(np.isnan(lr), np.float32(0.0), lr)
    mp = np.ascontiguousarray(maps, np.float32)
    n, h, w = lr.shape
    ref = (n - 1) // 2 if ref is None else int(ref)
    if not 0 <= ref < n:
        raise ValueError(f"ref must be in [0, {n}), got {ref}")
    hh, ww = h * scale, w * scale
    (cols, fx), (rows, fy), ratio = interpolation_tables((hh, ww), mp.shape[1:3])
    table, step = weight_table(scale, weight_sigma_px)
    gd = (
        np.zeros((hh, ww), np.float32)
        if guide is None
        else np.ascontiguousarray(guide, dtype=np.float32)
    )
    measured = (lr > 0).any(axis=0) if measured_only else np.ones((h, w), np.bool_)
    out = np.empty((hh, ww), np.float32)
    _register_fuse_kernel(
        lr,
        mp,
        int(scale),
        ratio,
        cols,
        fx,
        rows,
        fy,
        table,
        step,
        float(weight_floor),
        gd,
        float(guide_bonus),
        ref,
        float(min_valid_fraction),
        float(edge_mm),
        measured,
        _network(n),
        out,
    )
    return out
