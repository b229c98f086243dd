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
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import numpy.typing as npt
from numba import njit

from ..errors import InputError
from .mesh import load_obj

__all__ = [
    "SAMBA_BOUNDS_M",
    "SAMBA_VIEW_DIR",
    "PinholeCamera",
    "fit_camera_to_bounds",
    "look_at",
    "mesh_bounds",
    "render_depth",
    "render_mesh_sequence",
    "samba_camera_and_pose",
]

#: Axis-aligned bounds (metres, world frame: Y up) of the Samba dancer over all 175 meshes
#: ``mesh_0000.obj`` … ``mesh_0174.obj`` (measured, rounded outwards to 1 cm).
SAMBA_BOUNDS_M: tuple[tuple[float, float, float], tuple[float, float, float]] = (
    (-1.05, 0.01, -0.67),
    (0.86, 1.80, 0.57),
)

#: Default viewing direction for Samba (world frame): along −X, i.e. from the +X side, which
#: shows the dancer from the front during the first ~70 frames.
SAMBA_VIEW_DIR: tuple[float, float, float] = (-1.0, 0.0, 0.0)

Pose = npt.ArrayLike | tuple[npt.ArrayLike, npt.ArrayLike] | None
Background = float | tuple[npt.ArrayLike, float] | None


@dataclass(frozen=True)
class PinholeCamera:
    """Ideal pinhole camera (no distortion).

    Attributes
    ----------
    fx, fy : float
        Focal lengths in px.
    cx, cy : float
        Principal point in px (image coordinates, pixel (i, j) centred at (u, v) = (j, i)).
    width, height : int
        Image size in px; rendered images have shape (height, width).
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self) -> None:
        for name in ("fx", "fy", "cx", "cy"):
            val = getattr(self, name)
            if not math.isfinite(float(val)):
                raise InputError(f"camera {name} must be finite, got {val!r}")
        if self.fx <= 0 or self.fy <= 0:
            raise InputError(f"focal lengths must be > 0 px, got fx={self.fx}, fy={self.fy}")
        for name in ("width", "height"):
            val = getattr(self, name)
            if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or val < 1:
                raise InputError(f"camera {name} must be a positive integer, got {val!r}")

    @classmethod
    def from_fov(
        cls, width: int, height: int, fov_x_deg: float, *, fov_y_deg: float | None = None
    ) -> PinholeCamera:
        """Camera with the principal point at the image centre ((w−1)/2, (h−1)/2).

        Parameters
        ----------
        width, height : int
            Image size in px.
        fov_x_deg : float
            Horizontal field of view in degrees, edge to edge of the image (the outer borders of
            the first and last columns): fx = (width / 2) / tan(fov_x / 2).
        fov_y_deg : float, optional
            Vertical field of view; default: square pixels (fy = fx).
        """
        if not 0 < fov_x_deg < 180:
            raise InputError(f"fov_x_deg must be in (0, 180), got {fov_x_deg}")
        fx = (width / 2.0) / math.tan(math.radians(fov_x_deg) / 2.0)
        if fov_y_deg is None:
            fy = fx
        else:
            if not 0 < fov_y_deg < 180:
                raise InputError(f"fov_y_deg must be in (0, 180), got {fov_y_deg}")
            fy = (height / 2.0) / math.tan(math.radians(fov_y_deg) / 2.0)
        return cls(fx, fy, (width - 1) / 2.0, (height - 1) / 2.0, int(width), int(height))

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape (height, width) in px."""
        return (self.height, self.width)

    @property
    def K(self) -> npt.NDArray[np.float64]:
        """3×3 intrinsic matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def scaled(self, factor: float | Fraction) -> PinholeCamera:
        """The camera with the same field of view at a resolution ``factor`` times larger.

        Follows ``SPEC.md`` §1: f' = s·f and c' = s·(c + 0.5) − 0.5, i.e. pixel i of this camera
        sits at coordinate (i + 0.5)·s − 0.5 of the new one. ``factor`` may be a fraction 1/r.

        Parameters
        ----------
        factor : float or Fraction
            Scale s > 0; ``width·s`` and ``height·s`` must be integers (to within 1e−6).

        Raises
        ------
        InputError
            s ≤ 0, or the scaled image size is not a whole number of pixels.
        """
        s = float(factor)
        if not math.isfinite(s) or s <= 0:
            raise InputError(f"scale factor must be > 0, got {factor!r}")
        size = []
        for n in (self.width, self.height):
            m = n * s
            if abs(m - round(m)) > 1e-6 or round(m) < 1:
                raise InputError(
                    f"scaling {self.width}×{self.height} px by {factor} does not give a whole "
                    "number of pixels"
                )
            size.append(round(m))
        return PinholeCamera(
            self.fx * s,
            self.fy * s,
            s * (self.cx + 0.5) - 0.5,
            s * (self.cy + 0.5) - 0.5,
            size[0],
            size[1],
        )

    def rays(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Per-pixel ray slopes (X/Z, Y/Z) at the pixel centres, each of shape (height, width)."""
        xs = (np.arange(self.width, dtype=np.float64) - self.cx) / self.fx
        ys = (np.arange(self.height, dtype=np.float64) - self.cy) / self.fy
        return np.broadcast_to(xs[None, :], self.shape), np.broadcast_to(ys[:, None], self.shape)


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


# --------------------------------------------------------------------------------------------
# Camera placement and sequences
# --------------------------------------------------------------------------------------------


def mesh_bounds(
    obj_paths: Iterable[str | os.PathLike[str]],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Axis-aligned bounds (min (3,), max (3,)) over all vertices of a sequence of OBJ files."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for path in obj_paths:
        verts, _ = load_obj(path)
        lo = np.minimum(lo, verts.min(axis=0))
        hi = np.maximum(hi, verts.max(axis=0))
    if not np.isfinite(lo).all():
        raise InputError("mesh_bounds: no OBJ file given")
    return lo, hi


def fit_camera_to_bounds(
    bounds_min: npt.ArrayLike,
    bounds_max: npt.ArrayLike,
    *,
    width: int,
    height: int,
    fov_x_deg: float,
    view_dir: npt.ArrayLike = (0.0, 0.0, -1.0),
    up: npt.ArrayLike = (0.0, 1.0, 0.0),
    margin: float = 0.05,
) -> tuple[PinholeCamera, npt.NDArray[np.float64]]:
    """Place a camera that sees a whole axis-aligned box as large as possible.

    The camera looks along ``view_dir`` through the centre of the box; its distance is the
    smallest at which all eight corners project inside the image shrunk by ``margin`` on
    every side.

    Parameters
    ----------
    bounds_min, bounds_max : array_like, shape (3,)
        Box corners, world frame (m).
    width, height : int
        Image size (px).
    fov_x_deg : float
        Horizontal field of view (degrees); square pixels.
    view_dir : array_like, shape (3,)
        Viewing direction in the world frame (need not be normalised).
    up : array_like, shape (3,)
        World direction shown upwards in the image.
    margin : float
        Fraction of the half-width/half-height kept free on each side, in [0, 1).

    Returns
    -------
    camera : PinholeCamera
    world_to_camera : ndarray, shape (4, 4)
        Pose (metres), see :func:`look_at`.
    """
    lo = np.asarray(bounds_min, dtype=np.float64)
    hi = np.asarray(bounds_max, dtype=np.float64)
    if lo.shape != (3,) or hi.shape != (3,) or (hi < lo).any():
        raise InputError("bounds must be two 3-vectors with bounds_min <= bounds_max")
    if not 0 <= margin < 1:
        raise InputError(f"margin must be in [0, 1), got {margin}")
    camera = PinholeCamera.from_fov(width, height, fov_x_deg)
    centre = (lo + hi) / 2.0
    direction = np.asarray(view_dir, dtype=np.float64)
    direction = direction / np.linalg.norm(direction)
    rot = look_at(centre - direction, centre, up)[:3, :3]
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    local = (corners - centre) @ rot.T  # camera-aligned offsets from the box centre
    # The optical axis passes through the centre: a corner at (a, b, c) is seen at
    # u - cx = fx·a / (D + c); it fits when |a| <= t·(D + c), t = (1 - margin)·(half size)/f.
    half_w = camera.width / 2.0 - 0.5  # outermost pixel centres
    half_h = camera.height / 2.0 - 0.5
    tx = (1.0 - margin) * half_w / camera.fx
    ty = (1.0 - margin) * half_h / camera.fy
    dist = max(
        float(np.max(np.abs(local[:, 0]) / tx - local[:, 2])),
        float(np.max(np.abs(local[:, 1]) / ty - local[:, 2])),
    )
    dist = max(dist, float(np.max(-local[:, 2])) + 1e-3)  # keep the whole box in front
    return camera, look_at(centre - dist * direction, centre, up)


def samba_camera_and_pose(
    *,
    width: int = 1024,
    height: int = 588,
    fov_x_deg: float = 60.0,
    bounds_m: tuple[npt.ArrayLike, npt.ArrayLike] = SAMBA_BOUNDS_M,
    view_dir: npt.ArrayLike = SAMBA_VIEW_DIR,
    margin: float = 0.05,
) -> tuple[PinholeCamera, npt.NDArray[np.float64]]:
    """A fixed camera for the Samba sequence (Vlasic et al. 2008).

    The Samba meshes are in metres with Y up. During the first ~70 frames the dancer faces +X
    (she later turns and drifts towards −X), so by default the camera stands on the +X side at
    the height of the box centre, looks horizontally along −X (frontal view) and is placed by
    :func:`fit_camera_to_bounds` so that ``bounds_m`` fills the frame: with landscape images
    the dancer's height (≈ 1.8 m) spans most of the rows. The camera never moves; pass the
    bounds of the frames you render (:func:`mesh_bounds`) to frame them tightly, or the default
    bounds of the whole sequence (:data:`SAMBA_BOUNDS_M`) to use one camera for all 175 meshes.

    Parameters
    ----------
    width, height : int
        High-res image size (px); the paper uses 1024×588 (low res 256×147 at r = 4).
    fov_x_deg : float
        Horizontal field of view (degrees), square pixels.
    bounds_m : pair of 3-vectors
        World-frame box to frame (m); default :data:`SAMBA_BOUNDS_M` (whole sequence).
    view_dir : array_like, shape (3,)
        Viewing direction in the world frame; default :data:`SAMBA_VIEW_DIR` = (−1, 0, 0).
    margin : float
        Free fraction kept on each side of the image.

    Returns
    -------
    camera : PinholeCamera
    world_to_camera : ndarray, shape (4, 4)
        Pose in metres (X_cam = R·X_world + t), see :func:`look_at`.
    """
    return fit_camera_to_bounds(
        bounds_m[0],
        bounds_m[1],
        width=width,
        height=height,
        fov_x_deg=fov_x_deg,
        view_dir=view_dir,
        up=(0.0, 1.0, 0.0),
        margin=margin,
    )


def render_mesh_sequence(
    obj_paths: Sequence[str | os.PathLike[str]],
    camera: PinholeCamera,
    world_to_camera: Pose = None,
    *,
    background_mm: Background = None,
    callback: Callable[[int, int], None] | None = None,
) -> npt.NDArray[np.float32]:
    """Render one depth frame per OBJ file with a fixed camera.

    Parameters
    ----------
    obj_paths : sequence of path-like
        Mesh files in temporal order (vertices in metres).
    camera : PinholeCamera
    world_to_camera : pose, optional
        See :func:`render_depth`; the same for all frames.
    background_mm : float or (normal, offset_mm), optional
        Optional back wall, see :func:`render_depth`.
    callback : callable, optional
        Called as ``callback(k, T)`` after frame k of T is rendered (progress reporting).

    Returns
    -------
    ndarray of float32, shape (T, camera.height, camera.width)
        Depth in mm, 0 = no surface.
    """
    paths = list(obj_paths)
    if not paths:
        raise InputError("render_mesh_sequence: no OBJ file given")
    out = np.empty((len(paths), camera.height, camera.width), dtype=np.float32)
    for k, path in enumerate(paths):
        verts, faces = load_obj(path)
        out[k] = render_depth(
            verts, faces, camera, world_to_camera=world_to_camera, background_mm=background_mm
        )
        if callback is not None:
            callback(k, len(paths))
    return out
