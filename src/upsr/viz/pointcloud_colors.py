"""Per-pixel colours of a depth frame for a point cloud (:func:`upsr.io.pointcloud.write_ply`).

Either a colour image registered to the depth (seen from the same viewpoint), resized to the
depth's size, or the depth itself colour-coded (TURBO).
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method.validation import as_depth_frame
from upsr.viz.colormaps import colorize_depth

__all__ = ["color_for_depth"]


def color_for_depth(
    depth_mm: npt.ArrayLike,
    color: npt.ArrayLike | None = None,
    *,
    vmin_mm: float | None = None,
    vmax_mm: float | None = None,
) -> np.ndarray:
    """Per-pixel BGR colours (h, w, 3) uint8 for a depth frame.

    Parameters
    ----------
    depth_mm : array_like (h, w)
        Depth in mm; 0 or NaN = no measurement.
    color : array_like, optional
        A BGR(A) or grey uint8/uint16 image (h', w'[, 3|4]) registered to the depth, resized
        to (h, w) (bilinear when enlarging, area when shrinking; SPEC §1 pixel geometry).
        Without it the depth is colour-coded (TURBO, ``vmin_mm`` … ``vmax_mm``).
    vmin_mm, vmax_mm : float, optional
        Depth range of the colour code in mm (default: that of the frame).

    Returns
    -------
    ndarray uint8 (h, w, 3)
        OpenCV BGR order.

    Raises
    ------
    InputError
        A colour image that is not uint8/uint16 with 1, 3 or 4 channels.
    """
    d = as_depth_frame(depth_mm, name="depth")
    if color is None:
        return colorize_depth(d, vmin_mm, vmax_mm)
    img = np.asarray(color)
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    if img.dtype != np.uint8 or img.ndim not in (2, 3) or img.size == 0:
        raise InputError(f"colour image: expected uint8 (h, w[, 3]), got {img.dtype} {img.shape}")
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    elif img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    elif img.shape[2] != 3:
        raise InputError(f"colour image: expected 1, 3 or 4 channels, got {img.shape[2]}")
    if img.shape[:2] != d.shape:
        interp = cv2.INTER_LINEAR if img.shape[0] < d.shape[0] else cv2.INTER_AREA
        img = cv2.resize(img, (d.shape[1], d.shape[0]), interpolation=interp)
    return img
