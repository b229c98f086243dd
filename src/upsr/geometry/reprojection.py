"""Where the pixels of a depth image lie in another view of a rigid scene.

A pixel (u, v) of camera A with depth Z (mm) is the camera-frame point
Z·((u − cx)/fx, (v − cy)/fy, 1) (the conventions of :mod:`upsr.geometry.rendering`); with the
world-to-camera poses of A and B it is carried to B's frame and projected there. Of a static
scene seen by a moving camera this is the true motion of every pixel between two frames (the
optical flow an ideal registration would find), used by ``benchmarks/registration_oracle.py``
to measure how much of UP-SR's error the estimated motion costs.

References
----------
Hartley, R. & Zisserman, A. (2004). *Multiple View Geometry in Computer Vision*, 2nd ed.,
§6.1 (the projective camera) and §9.1 (the point transfer between two views).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.rendering import Pose, _as_pose

__all__ = ["reproject"]


def reproject(
    depth_mm: npt.ArrayLike,
    camera: PinholeCamera,
    from_pose: Pose,
    to_pose: Pose,
    *,
    u: npt.ArrayLike | None = None,
    v: npt.ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image positions and depths in view B of the points seen with ``depth_mm`` in view A.

    Parameters
    ----------
    depth_mm : array_like, shape (H, W) (or the shape of ``u``)
        Depth Z (mm) along A's optical axis; 0 or NaN = no point.
    camera : PinholeCamera
        The camera of both views (px).
    from_pose, to_pose : pose
        World-to-camera poses of A and B, in metres: (R, t), 3×4 or 4×4, or None (identity).
    u, v : array_like, optional
        Image coordinates (px) in A of each depth, e.g. the centres of a coarser grid; default
        the centres of ``camera``'s pixels (u = column, v = row).

    Returns
    -------
    (u_b, v_b, z_b) : ndarray float64, the shape of ``depth_mm``
        Position in B (px, pixel centres at integers) and depth along B's optical axis (mm);
        NaN where there is no point or the point lies behind B.

    Examples
    --------
    A camera 25 mm nearer a wall at 2.5 m sees it 1 % larger about its principal point:

    >>> cam = PinholeCamera(100.0, 100.0, 31.5, 27.5, 64, 56)
    >>> ahead = np.eye(4); ahead[2, 3] = -0.025
    >>> ub, vb, zb = reproject(np.full((56, 64), 2500.0), cam, None, ahead)
    >>> round(float(ub[0, 63] - cam.cx) / (63 - cam.cx), 4)
    1.0101
    >>> float(zb[0, 0])
    2475.0
    """
    z = np.asarray(depth_mm, dtype=np.float64)
    if u is None or v is None:
        if u is not None or v is not None:
            raise InputError("give both u and v, or neither")
        if z.shape != camera.shape:
            raise InputError(f"depth of shape {z.shape} for a camera of shape {camera.shape}")
        us, vs = np.meshgrid(np.arange(camera.width, dtype=np.float64),
                             np.arange(camera.height, dtype=np.float64))  # fmt: skip
    else:
        us, vs = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
        if us.shape != z.shape or vs.shape != z.shape:
            raise InputError(f"u {us.shape} and v {vs.shape} must have the depth's shape {z.shape}")
    rot_a, t_a = _as_pose(from_pose)
    rot_b, t_b = _as_pose(to_pose)
    with np.errstate(invalid="ignore"):
        ok = z > 0
    zm = np.where(ok, z, np.nan) / 1000.0
    pts = np.stack([(us - camera.cx) / camera.fx * zm, (vs - camera.cy) / camera.fy * zm, zm], -1)
    # B's frame: R_b·(R_aᵀ·(X − t_a)) + t_b
    rot = rot_b @ rot_a.T
    pts_b = pts @ rot.T + (t_b - rot @ t_a)
    with np.errstate(invalid="ignore", divide="ignore"):
        front = pts_b[..., 2] > 0
        zb = np.where(front, pts_b[..., 2], np.nan)
        return (
            camera.fx * pts_b[..., 0] / zb + camera.cx,
            camera.fy * pts_b[..., 1] / zb + camera.cy,
            1000.0 * zb,
        )
