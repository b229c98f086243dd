"""Depth rendering of triangle meshes with a pinhole camera (z-buffer rasteriser).

Conventions
-----------
* Camera frame (OpenCV): x right, y down, z forward along the optical axis.
* Projection of a camera-frame point (X, Y, Z): u = fx·X/Z + cx (column), v = fy·Y/Z + cy (row).
* Pixel (i, j) (row i, column j) is sampled at its centre, image coordinates (u, v) = (j, i).
* Depth is Z along the optical axis (not the length of the ray), in millimetres; 0 where no
  surface is seen. The nearest surface wins.
* Resolution changes follow ``SPEC.md`` §1: the low-res pixel i sits at the high-res coordinate
  (i + 0.5)·r − 0.5, so a camera scaled by s has f' = s·f and c' = s·(c + 0.5) − 0.5
  (:meth:`PinholeCamera.scaled`).

Rasterisation is exact at pixel centres: a pixel is covered when its centre lies inside the
projected triangle (top-left rule on shared edges, so closed meshes have no cracks), and the
depth is perspective correct (1/Z is interpolated linearly in the image, which is exact for a
planar triangle). Triangles crossing the near plane are clipped.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera

__all__ = ["Background", "Pose", "look_at", "render_depth"]

Pose = npt.ArrayLike | tuple[npt.ArrayLike, npt.ArrayLike] | None
Background = float | tuple[npt.ArrayLike, float] | None


# --------------------------------------------------------------------------------------------
# Poses
# --------------------------------------------------------------------------------------------


def _as_pose(world_to_camera: Pose) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Normalise a pose (None, (R, t) or 4×4) to (R (3, 3), t (3,)) as float64."""
    if world_to_camera is None:
        return np.eye(3), np.zeros(3)
    if isinstance(world_to_camera, tuple) and len(world_to_camera) == 2:
        rot = np.asarray(world_to_camera[0], dtype=np.float64)
        trans = np.asarray(world_to_camera[1], dtype=np.float64).reshape(-1)
    else:
        mat = np.asarray(world_to_camera, dtype=np.float64)
        if mat.shape not in ((4, 4), (3, 4)):
            raise InputError(f"world_to_camera must be (R, t), 3×4 or 4×4, got shape {mat.shape}")
        rot, trans = mat[:3, :3], mat[:3, 3]
    if rot.shape != (3, 3) or trans.shape != (3,):
        raise InputError(
            f"pose needs R of shape (3, 3) and t of shape (3,), got {rot.shape}, {trans.shape}"
        )
    if not (np.isfinite(rot).all() and np.isfinite(trans).all()):
        raise InputError("pose must be finite")
    return rot, trans


def look_at(
    eye: npt.ArrayLike, target: npt.ArrayLike, up: npt.ArrayLike = (0.0, 1.0, 0.0)
) -> npt.NDArray[np.float64]:
    """World-to-camera 4×4 matrix of a camera at ``eye`` looking at ``target``.

    Parameters
    ----------
    eye, target : array_like, shape (3,)
        Camera centre and a point on the optical axis, world frame (same unit as the mesh, m).
    up : array_like, shape (3,)
        World direction that appears upwards in the image (the camera y axis points down).

    Returns
    -------
    ndarray, shape (4, 4)
        ``M`` such that ``X_cam = M[:3, :3] @ X_world + M[:3, 3]`` (OpenCV camera frame).
    """
    eye = np.asarray(eye, dtype=np.float64)
    fwd = np.asarray(target, dtype=np.float64) - eye
    norm = np.linalg.norm(fwd)
    if norm == 0:
        raise InputError("look_at: eye and target coincide")
    fwd /= norm
    right = np.cross(fwd, np.asarray(up, dtype=np.float64))
    if np.linalg.norm(right) < 1e-12:
        raise InputError("look_at: up is parallel to the viewing direction")
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)  # (right, down, fwd) is right-handed
    rot = np.stack([right, down, fwd])
    mat = np.eye(4)
    mat[:3, :3] = rot
    mat[:3, 3] = -rot @ eye
    return mat


# --------------------------------------------------------------------------------------------
# Rasteriser
# --------------------------------------------------------------------------------------------


@njit(cache=True)
def _raster_triangle(zbuf, fx, fy, cx, cy, p0, p1, p2):  # pragma: no cover - numba
    """Z-buffer one camera-frame triangle (all corners with Z > 0) into ``zbuf``."""
    height, width = zbuf.shape
    z0, z1, z2 = p0[2], p1[2], p2[2]
    x0 = fx * p0[0] / z0 + cx
    y0 = fy * p0[1] / z0 + cy
    x1 = fx * p1[0] / z1 + cx
    y1 = fy * p1[1] / z1 + cy
    x2 = fx * p2[0] / z2 + cx
    y2 = fy * p2[1] / z2 + cy
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    if not (abs(area) > 1e-12):  # also rejects NaN
        return
    if area < 0:  # make the winding positive so that the top-left rule below applies
        x1, x2 = x2, x1
        y1, y2 = y2, y1
        z1, z2 = z2, z1
        area = -area
    xmin = min(x0, x1, x2)
    xmax = max(x0, x1, x2)
    ymin = min(y0, y1, y2)
    ymax = max(y0, y1, y2)
    if xmax < 0 or ymax < 0 or xmin > width - 1 or ymin > height - 1:
        return
    j0 = math.ceil(max(xmin, 0.0))  # clamp first: huge coordinates near the near plane
    j1 = math.floor(min(xmax, width - 1.0))
    i0 = math.ceil(max(ymin, 0.0))
    i1 = math.floor(min(ymax, height - 1.0))
    inv_area = 1.0 / area
    iz0 = 1.0 / z0
    iz1 = 1.0 / z1
    iz2 = 1.0 / z2
    # Edge e_k is the edge opposite corner k, oriented so that the inside is positive.
    # Top-left rule (y down, positive winding): edge a->b owns its points when dy < 0, or
    # dy == 0 and dx > 0.
    dx0 = x2 - x1
    dy0 = y2 - y1
    dx1 = x0 - x2
    dy1 = y0 - y2
    dx2 = x1 - x0
    dy2 = y1 - y0
    tl0 = dy0 < 0 or (dy0 == 0 and dx0 > 0)
    tl1 = dy1 < 0 or (dy1 == 0 and dx1 > 0)
    tl2 = dy2 < 0 or (dy2 == 0 and dx2 > 0)
    # Evaluate each edge function from its lexicographically smaller end point, so that the
    # two triangles sharing an edge get exactly opposite values (no crack, no double cover).
    s0 = 1.0 if (x1, y1) < (x2, y2) else -1.0
    s1 = 1.0 if (x2, y2) < (x0, y0) else -1.0
    s2 = 1.0 if (x0, y0) < (x1, y1) else -1.0
    bx0, by0 = (x1, y1) if s0 > 0 else (x2, y2)
    bx1, by1 = (x2, y2) if s1 > 0 else (x0, y0)
    bx2, by2 = (x0, y0) if s2 > 0 else (x1, y1)
    for i in range(i0, i1 + 1):
        py = float(i)
        for j in range(j0, j1 + 1):
            px = float(j)
            w0 = s0 * ((s0 * dx0) * (py - by0) - (s0 * dy0) * (px - bx0))
            w1 = s1 * ((s1 * dx1) * (py - by1) - (s1 * dy1) * (px - bx1))
            w2 = s2 * ((s2 * dx2) * (py - by2) - (s2 * dy2) * (px - bx2))
            if w0 < 0 or w1 < 0 or w2 < 0:
                continue
            if (w0 == 0 and not tl0) or (w1 == 0 and not tl1) or (w2 == 0 and not tl2):
                continue
            inv_z = (w0 * iz0 + w1 * iz1 + w2 * iz2) * inv_area
            if inv_z <= 0:
                continue
            z = 1.0 / inv_z
            if z < zbuf[i, j]:
                zbuf[i, j] = z


@njit(cache=True)
def _rasterize(zbuf, pts, faces, fx, fy, cx, cy, near):  # pragma: no cover - numba
    """Render all ``faces`` of camera-frame points ``pts`` (mm) into ``zbuf`` (inf = empty)."""
    poly = np.empty((4, 3))
    for k in range(faces.shape[0]):
        a = faces[k, 0]
        b = faces[k, 1]
        c = faces[k, 2]
        za = pts[a, 2]
        zb = pts[b, 2]
        zc = pts[c, 2]
        n_in = int(za >= near) + int(zb >= near) + int(zc >= near)
        if n_in == 3:
            _raster_triangle(zbuf, fx, fy, cx, cy, pts[a], pts[b], pts[c])
            continue
        if n_in == 0:
            continue
        # Sutherland-Hodgman clipping of the triangle against the plane Z = near.
        m = 0
        idx = (a, b, c)
        for e in range(3):
            p = pts[idx[e]]
            q = pts[idx[(e + 1) % 3]]
            p_in = p[2] >= near
            q_in = q[2] >= near
            if p_in:
                poly[m, :] = p
                m += 1
            if p_in != q_in:
                s = (near - p[2]) / (q[2] - p[2])
                poly[m, :] = p + s * (q - p)
                poly[m, 2] = near
                m += 1
        for e in range(1, m - 1):
            _raster_triangle(zbuf, fx, fy, cx, cy, poly[0], poly[e], poly[e + 1])


def _background_depth(camera: PinholeCamera, background_mm: Background) -> npt.NDArray[np.float64]:
    """Analytic depth (mm) of the background plane per pixel; inf where it is not seen."""
    if background_mm is None:
        return np.full(camera.shape, np.inf)
    if isinstance(background_mm, tuple):
        if len(background_mm) != 2:
            raise InputError("background_mm plane must be (normal (3,), offset_mm)")
        normal = np.asarray(background_mm[0], dtype=np.float64).reshape(-1)
        offset = float(background_mm[1])
        if normal.shape != (3,) or not np.isfinite(normal).all() or not np.any(normal):
            raise InputError("background plane normal must be a finite non-zero 3-vector")
        if not math.isfinite(offset):
            raise InputError("background plane offset must be finite")
    else:
        dist = float(background_mm)
        if not (math.isfinite(dist) and dist > 0):
            raise InputError(f"background distance must be > 0 mm, got {background_mm!r}")
        return np.full(camera.shape, dist)
    sx, sy = camera.rays()
    denom = normal[0] * sx + normal[1] * sy + normal[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        z = offset / denom
    return np.where(np.isfinite(z) & (z > 0), z, np.inf)


def render_depth(
    vertices_m: npt.ArrayLike,
    faces: npt.ArrayLike,
    camera: PinholeCamera,
    *,
    world_to_camera: Pose = None,
    background_mm: Background = None,
    near_mm: float = 1.0,
) -> npt.NDArray[np.float32]:
    """Render the depth map (mm) of a triangle mesh seen by a pinhole camera.

    Parameters
    ----------
    vertices_m : array_like, shape (V, 3)
        Vertex positions in metres (world frame, or camera frame if ``world_to_camera`` is
        None).
    faces : array_like of int, shape (F, 3)
        Zero-based vertex indices of the triangles. Both windings are rendered (no culling).
    camera : PinholeCamera
        Intrinsics and image size (px).
    world_to_camera : (R, t), 3×4 or 4×4 array, optional
        Rigid transform X_cam = R·X_world + t (t in metres) into the OpenCV camera frame
        (x right, y down, z forward). Default: identity.
    background_mm : float or (normal, offset_mm), optional
        Optional back wall, rendered analytically per pixel behind (z-tested against) the mesh.
        A float d is the fronto-parallel plane Z = d mm; a pair ``(n, d)`` is the plane
        {X : n·X = d} in camera coordinates (mm). Default: no wall, background 0.
    near_mm : float
        Near clipping plane (mm); geometry closer than that is clipped away.

    Returns
    -------
    ndarray of float32, shape (camera.height, camera.width)
        Depth Z along the optical axis in mm at each pixel centre, 0 where no surface.

    Raises
    ------
    InputError
        Malformed vertices/faces (shape, non-finite values, indices out of range) or pose.
    """
    verts = np.asarray(vertices_m, dtype=np.float64)
    if verts.ndim != 2 or verts.shape[1] != 3:
        raise InputError(f"vertices must have shape (V, 3), got {verts.shape}")
    if not np.isfinite(verts).all():
        raise InputError("vertices must be finite")
    tri = np.asarray(faces)
    if tri.size == 0:
        tri = tri.reshape(0, 3)
    if tri.ndim != 2 or tri.shape[1] != 3 or not np.issubdtype(tri.dtype, np.integer):
        raise InputError(
            f"faces must be an integer array of shape (F, 3), got {tri.shape} {tri.dtype}"
        )
    if tri.size and (tri.min() < 0 or tri.max() >= len(verts)):
        raise InputError(f"face indices must lie in [0, {len(verts) - 1}]")
    if not (math.isfinite(near_mm) and near_mm > 0):
        raise InputError(f"near_mm must be > 0, got {near_mm}")
    rot, trans = _as_pose(world_to_camera)
    pts = np.ascontiguousarray((verts @ rot.T + trans) * 1000.0)
    zbuf = np.ascontiguousarray(_background_depth(camera, background_mm))
    if len(tri):
        _rasterize(
            zbuf,
            pts,
            np.ascontiguousarray(tri, dtype=np.int64),
            float(camera.fx),
            float(camera.fy),
            float(camera.cx),
            float(camera.cy),
            float(near_mm),
        )
    zbuf[~np.isfinite(zbuf)] = 0.0
    return zbuf.astype(np.float32)
