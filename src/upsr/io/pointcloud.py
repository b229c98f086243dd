"""Point clouds from depth frames: back-projection and coloured binary PLY files (plyfile).

The colours are given per pixel (see :mod:`upsr.viz.pointcloud_colors` for colour-coded
depth or a registered colour image).

Points are in the camera frame of OpenCV / ROS (x right, y down, z forward), in **metres**
(the unit point-cloud tools expect; depth itself stays in mm everywhere else): for the pixel
(i, j) with depth Z, X = (j − cx)·Z/fx, Y = (i − cy)·Z/fy (SPEC §1 pixel centres). Pixels
without depth (0) are skipped. Writing needs ``plyfile`` (``pip install 'upsr[io]'``).
"""

from __future__ import annotations

import io as pyio
import os
from pathlib import Path

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.method.validation import as_depth_frame

__all__ = ["backproject", "ply_bytes", "write_ply"]


def backproject(depth_mm: npt.ArrayLike, camera: PinholeCamera) -> tuple[np.ndarray, np.ndarray]:
    """3-D points (metres) of the valid pixels of a depth frame.

    Parameters
    ----------
    depth_mm : array_like, (h, w)
        Depth in mm; 0 or NaN = no measurement.
    camera : PinholeCamera
        Intrinsics of this frame's resolution (``camera.shape == depth.shape``).

    Returns
    -------
    points : ndarray float32 (n, 3)
        X, Y, Z in metres, camera frame, row-major pixel order.
    valid : ndarray bool (h, w)
        Which pixels gave a point.
    """
    d = as_depth_frame(depth_mm, name="depth")
    if d.shape != camera.shape:
        raise InputError(
            f"intrinsics are for {camera.width}x{camera.height} images, the depth frame is "
            f"{d.shape[1]}x{d.shape[0]} (scale them with the frame, see upsr.geometry.intrinsics)"
        )
    valid = d > 0
    ii, jj = np.nonzero(valid)
    z = d[valid].astype(np.float64) / 1000.0
    x = (jj - camera.cx) * z / camera.fx
    y = (ii - camera.cy) * z / camera.fy
    return np.stack([x, y, z], axis=1).astype(np.float32), valid


def ply_bytes(points_m: npt.ArrayLike, colors_rgb: npt.ArrayLike | None = None) -> bytes:
    """A binary little-endian PLY of points (n, 3) in metres with optional RGB uint8 colours."""
    from upsr.io.registry import require

    plyfile = require("plyfile", "writing PLY point clouds")
    pts = np.asarray(points_m, dtype=np.float32).reshape(-1, 3)
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if colors_rgb is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    vertex = np.empty(len(pts), dtype=fields)
    vertex["x"], vertex["y"], vertex["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    if colors_rgb is not None:
        col = np.asarray(colors_rgb, dtype=np.uint8).reshape(-1, 3)
        if len(col) != len(pts):
            raise InputError(f"{len(col)} colours for {len(pts)} points")
        vertex["red"], vertex["green"], vertex["blue"] = col[:, 0], col[:, 1], col[:, 2]
    element = plyfile.PlyElement.describe(vertex, "vertex")
    buf = pyio.BytesIO()
    plyfile.PlyData(
        [element],
        text=False,
        byte_order="<",
        comments=["upsr point cloud: metres, camera frame (x right, y down, z forward)"],
    ).write(buf)
    return buf.getvalue()


def write_ply(
    path: str | os.PathLike[str],
    depth_mm: npt.ArrayLike,
    camera: PinholeCamera,
    colors_bgr: npt.ArrayLike | None = None,
) -> Path:
    """Back-project a depth frame and write it as a coloured PLY, atomically.

    Parameters
    ----------
    path : path-like
        Destination ``.ply``.
    depth_mm : array_like (h, w)
        Depth in mm, 0 = skipped.
    camera : PinholeCamera
        Intrinsics at this resolution.
    colors_bgr : array_like (h, w, 3) uint8, optional
        Per-pixel colours (OpenCV BGR order), e.g. from
        :func:`upsr.viz.pointcloud_colors.color_for_depth`; only those of the pixels with
        depth are written.

    Returns
    -------
    pathlib.Path
        The path written.
    """
    from upsr._atomic import write_bytes_atomic

    points, valid = backproject(depth_mm, camera)
    rgb = None
    if colors_bgr is not None:
        col = np.asarray(colors_bgr)
        if col.shape != (*valid.shape, 3):
            raise InputError(f"colours of shape {col.shape} for a {valid.shape} depth frame")
        rgb = col[valid][:, ::-1]
    return write_bytes_atomic(path, ply_bytes(points, rgb))
