"""The speckle removal of :func:`upsr.method.outliers.remove_speckles` by OpenCV's speckle
filter of stereo matching (``cv2.filterSpeckles``, a labelling of every region): the
straightforward path of :mod:`upsr.research.oracle`, the same result (the tests compare them).
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from upsr.method.outliers import speckle_units

__all__ = ["remove_speckles_opencv"]


def remove_speckles_opencv(
    depth_mm: npt.ArrayLike, max_size_px: int, max_diff_mm: float = 100.0
) -> np.ndarray:
    """:func:`upsr.method.outliers.remove_speckles` (same parameters, same result) by
    ``cv2.filterSpeckles`` on the depths in whole units (int16)."""
    depth = np.array(depth_mm, dtype=np.float32, copy=True)
    valid = depth > 0  # NaN compares False: unknown
    depth[~valid] = 0.0
    if max_size_px == 0 or not valid.any():
        return depth
    unit, max_diff = speckle_units(depth, max_diff_mm)
    q = np.rint(depth / np.float32(unit))
    np.maximum(q, 1.0, out=q, where=valid)
    q = q.astype(np.int16)
    cv2.filterSpeckles(q, 0, int(max_size_px), max_diff)
    if not (q != 0).any():  # (speckles only: kept, as remove_speckles keeps them)
        return depth
    depth[q == 0] = 0.0
    return depth
