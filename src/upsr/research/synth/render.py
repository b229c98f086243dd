"""Samba-style sequences: camera placement around meshes and rendering of OBJ sequences.

The rasteriser and the camera live in :mod:`upsr.geometry` (re-exported here).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.rendering import Background, Pose, look_at, render_depth
from upsr.research.synth.mesh import load_obj

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
