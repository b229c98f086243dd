"""Isolated depth outliers ("speckles") removed from the output (beyond the paper).

At high noise a pixel of the fused frame can be the median of few samples (at a silhouette,
where only some frames see the surface), and keep a noise outlier hundreds of mm off its
surface. The deblurring leaves it alone on purpose: depth is not an image, and BTV pairs
across a jump larger than ``edge_mm`` are not regularised. Such an outlier is a small island:
no neighbour lies within ``edge_mm`` of it. :func:`remove_speckles` finds the connected
regions of the depth map (4-neighbours closer than ``max_diff_mm``) and marks as unknown (0)
those of at most ``max_size_px`` pixels: a region smaller than one low-res pixel's footprint
(r² high-res px) is one sample's worth of evidence, indistinguishable from a noise outlier, and
"no measurement" is better than a flying pixel. The same connected-component test as the
speckle filter of stereo matching (``cv2.filterSpeckles``), with the same result
(``tests/method/test_outliers.py`` compares them), computed by a flood fill that stops as soon
as a region is known to be large: more than ``max_size_px`` pixels, or joined to a region
already known to be large, and a pixel joined to its left or upper neighbour in a large region
is in it: a dense depth map costs about one look at a neighbour per pixel rather than a
labelling of every region (640×480 outputs of the dense room: 0.93 against 2.28 ms,
``benchmarks/speed_eval.py``'s ``kernel_benchmark``).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError

__all__ = ["INT16_MAX", "remove_speckles", "speckle_units"]

#: The largest depth in whole units of the removal (int16, as OpenCV's speckle filter).
INT16_MAX = 32767


@nb.njit(cache=True, nogil=True)
def _speckle_kernel(depth, unit, max_size, max_diff):  # pragma: no cover - numba
    """Set to 0 in ``depth`` (0: no pixel) the 4-connected regions of at most ``max_size``
    pixels whose neighbours' depths, in whole ``unit``s (int16, at least 1), differ by at most
    ``max_diff``. state: 0 unknown, 1 done (in a large region or removed), 2 in the region
    being filled."""
    h, w = depth.shape
    q = np.empty((h, w), np.int16)
    for i in range(h):
        for j in range(w):
            d = depth[i, j]
            q[i, j] = np.int16(max(np.rint(d / unit), 1.0)) if d > 0 else np.int16(0)
    state = np.zeros((h, w), np.uint8)
    region = np.empty(max_size + 1, np.int64)
    stack = np.empty(4 * (max_size + 1) + 1, np.int64)
    for i0 in range(h):
        for j0 in range(w):
            v0 = np.int32(q[i0, j0])
            if v0 == 0 or state[i0, j0] != 0:
                continue
            # (the common case, a pixel of a large surface: joined to its left or upper
            # neighbour, already known to be large; a neighbour done, which has depth, and
            # joined to the pixel is never a speckle, which would have taken the pixel in)
            if (
                j0 > 0 and state[i0, j0 - 1] == 1 and abs(np.int32(q[i0, j0 - 1]) - v0) <= max_diff
            ) or (
                i0 > 0 and state[i0 - 1, j0] == 1 and abs(np.int32(q[i0 - 1, j0]) - v0) <= max_diff
            ):
                state[i0, j0] = 1
                continue
            n = 0
            stack[0] = i0 * w + j0
            top = 1
            state[i0, j0] = 2
            large = False
            while top > 0 and not large:
                top -= 1
                p = stack[top]
                region[n] = p
                n += 1
                if n > max_size:
                    large = True
                    break
                i = p // w
                j = p % w
                v = np.int32(q[i, j])
                for k in range(4):
                    a = i + (1 if k == 0 else (-1 if k == 1 else 0))
                    b = j + (1 if k == 2 else (-1 if k == 3 else 0))
                    if a < 0 or a >= h or b < 0 or b >= w or q[a, b] == 0:
                        continue
                    if abs(np.int32(q[a, b]) - v) > max_diff:
                        continue
                    if state[a, b] == 1:
                        large = True
                    elif state[a, b] == 0:
                        state[a, b] = 2
                        stack[top] = a * w + b
                        top += 1
            # every pixel reached is in the region (the stack's too): large, or a speckle
            for t in range(n + top):
                p = region[t] if t < n else stack[t - n]
                state[p // w, p % w] = 1  # (done: never a seed again)
                if not large:
                    depth[p // w, p % w] = 0.0


def remove_speckles(
    depth_mm: npt.ArrayLike, max_size_px: int, max_diff_mm: float = 100.0
) -> np.ndarray:
    """Set to 0 the small islands of depth cut off from everything around them.

    Parameters
    ----------
    depth_mm : array_like (H, W)
        Depth in mm; 0 = unknown (never part of a region).
    max_size_px : int
        Regions of at most this many pixels are removed (0: nothing is removed).
    max_diff_mm : float
        Two 4-neighbours belong to one region when their depths differ by at most this (mm).

    Returns
    -------
    ndarray float32 (H, W): a copy of ``depth_mm`` with the speckles set to 0; every other
    value is unchanged. An image made of speckles only (e.g. a 1×1 input upsampled) is
    returned unchanged: islands are cut off from something, and nothing would be left.
    """
    depth = np.array(depth_mm, dtype=np.float32, copy=True)
    if depth.ndim != 2:
        raise InputError(f"remove_speckles expects a 2-D depth image, got shape {depth.shape}")
    if isinstance(max_size_px, bool) or not isinstance(max_size_px, (int, np.integer)):
        raise InputError(f"max_size_px must be an integer >= 0, got {max_size_px!r}")
    if max_size_px < 0:
        raise InputError(f"max_size_px must be an integer >= 0, got {max_size_px!r}")
    if not (math.isfinite(max_diff_mm) and max_diff_mm > 0):
        raise InputError(f"max_diff_mm must be a finite number > 0, got {max_diff_mm!r}")
    valid = depth > 0  # NaN compares False: unknown
    depth[~valid] = 0.0
    if max_size_px == 0 or not valid.any():
        return depth
    unit, max_diff = speckle_units(depth, max_diff_mm)
    kept = depth.copy()
    _speckle_kernel(depth, np.float32(unit), int(max_size_px), max_diff)
    return depth if (depth > 0).any() else kept


def speckle_units(depth_mm: np.ndarray, max_diff_mm: float) -> tuple[float, int]:
    """The unit (mm) of the int16 depths the speckle removal compares, as OpenCV's speckle
    filter does (whole mm up to 32.7 m, coarser beyond), and ``max_diff_mm`` in that unit
    (at least 1)."""
    unit = max(1.0, math.ceil(float(depth_mm.max()) / INT16_MAX))
    return unit, max(int(max_diff_mm / unit), 1)
