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
speckle filter of stereo matching (``cv2.filterSpeckles``).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError

__all__ = ["remove_speckles"]

_INT16_MAX = 32767


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
    value is unchanged.
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
    # cv2.filterSpeckles works on int16: quantise to whole units of `unit` mm (1 mm up to
    # 32.7 m), 0 staying "unknown" (the filter never labels its new value)
    unit = max(1.0, math.ceil(float(depth.max()) / _INT16_MAX))
    q = np.rint(depth / np.float32(unit))
    np.maximum(q, 1.0, out=q, where=valid)
    q = q.astype(np.int16)
    cv2.filterSpeckles(q, 0, int(max_size_px), max(int(max_diff_mm / unit), 1))
    depth[q == 0] = 0.0
    return depth
