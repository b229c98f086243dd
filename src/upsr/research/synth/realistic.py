"""Evaluation scenes of real depth cameras: thin fast parts, camera motion, large motion, rooms.

Each scene is a small triangle mesh rendered with the z-buffer rasteriser
(:func:`upsr.geometry.rendering.render_depth`) through a pinhole camera
(:class:`upsr.geometry.camera.PinholeCamera`). The low-res frames are point samples at the
low-res pixel centres (camera ``camera``), the truth point samples at the high-res centres of
``camera.scaled(r)`` (same field of view, ``SPEC.md`` §1 pixel geometry). Sensor models are
applied afterwards with :func:`degrade` (the ToF footprint model averages the truth itself).

Lengths given "in px" are low-res pixels at the depth of the object they size; depths are in
mm, time in frames. The scenes (all seeded and sized by ``lowres_shape``):

* :func:`galloping_animal` — a body with four thin legs and two antlers (1–2 px wide) whose
  feet move up to ``leg_speed_px`` (5) px per frame, in front of a wall or of nothing;
* :func:`camera_toward_wall` — a static wall with boxes on it, the camera moving 25 mm per
  frame towards it;
* :func:`deforming_body` — a breathing torso with swinging arms and a head that moves up to
  ``head_speed_px`` (25) px per frame, in front of a wall;
* :func:`moving_camera_room` — a closed room (every pixel measured) with boxes, seen by a
  camera that translates and turns;
* :func:`spinning_fan` — three thin blades turning with their tips at ``tip_speed_px`` (6) px
  per frame, a ball coming ``ball_speed_mm`` (50) mm nearer per frame, a box whose top meets
  its front at a crease, before a wall (out of sample: added after the rules were built).

Typical sizes: 56×64 (h×w, ToF class) and 120×160 or 240×320 (Kinect class).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

import upsr.research.synth.degradation as _deg
from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.rendering import look_at, render_depth
from upsr.research.synth.primitives import Mesh, box, cylinder, ellipsoid, merge

__all__ = [
    "SCENES",
    "SENSORS",
    "RealisticVideo",
    "camera_toward_wall",
    "deforming_body",
    "degrade",
    "galloping_animal",
    "make_realistic",
    "moving_camera_room",
    "spinning_fan",
]

Sensor = Literal["clean", "laplace", "gaussian", "tof", "tof_gaussian", "kinect"]
SENSORS: tuple[str, ...] = ("clean", "laplace", "gaussian", "tof", "tof_gaussian", "kinect")


@dataclass(frozen=True, eq=False)
class RealisticVideo:
    """A clean rendered depth video with its high-res truth and its moving-part mask.

    Attributes
    ----------
    name : str
        Scene name (a key of :data:`SCENES`).
    lowres : ndarray, float32 (T, h, w)
        Clean low-res frames (mm), point-sampled; 0 = no surface. Degrade with :func:`degrade`.
    truth : ndarray, float32 (T, r·h, r·w)
        Ground truth (mm); 0 = no surface.
    moving : ndarray, bool (T, r·h, r·w)
        Truth pixels whose surface moves relative to the camera: the moving bodies for a
        static camera, every valid pixel when the camera moves.
    scale : int
        SR factor r.
    camera : PinholeCamera
        Low-res camera (the truth's is ``camera.scaled(scale)``).
    static_camera : bool
        True when only the bodies move (a temporal mean is a fair peer on the static parts).
    max_motion_px : float
        Largest displacement (low-res px) of a mesh vertex in the image between two
        consecutive frames (vertices in front of the camera and inside the image).
    world_to_camera : ndarray float64 (T, 4, 4) or None
        The moving camera's pose in each frame (metres; the true motion of every pixel between
        two frames, :func:`upsr.method.camera_motion.reproject`); None for a static camera.
    """

    name: str
    lowres: np.ndarray
    truth: np.ndarray
    moving: np.ndarray
    scale: int
    camera: PinholeCamera
    static_camera: bool
    max_motion_px: float
    world_to_camera: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        """Number of frames T."""
        return int(self.truth.shape[0])


# --------------------------------------------------------------------------------------------
# Rendering helpers
# --------------------------------------------------------------------------------------------


def _check_shape(lowres_shape: tuple[int, int]) -> tuple[int, int]:
    if not isinstance(lowres_shape, (tuple, list)) or len(lowres_shape) != 2:
        raise InputError(f"lowres_shape must be (h, w), got {lowres_shape!r}")
    h, w = (_check_int(v, "lowres_shape", 16) for v in lowres_shape)
    return h, w


def _sizes(
    lowres_shape: tuple[int, int], scale: int, n_frames: int, seed: int
) -> tuple[int, int, int, int, np.random.Generator]:
    """Checked (h, w, r, T) and the scene's random generator."""
    h, w = _check_shape(lowres_shape)
    r, n = _check_int(scale, "scale", 1), _check_int(n_frames, "n_frames", 1)
    return h, w, r, n, np.random.default_rng(_check_int(seed, "seed", 0))


def _check_int(value: int, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _project(camera: PinholeCamera, pts_m: np.ndarray) -> np.ndarray:
    """Image coordinates (u, v) of camera-frame points; NaN behind or outside the image."""
    z = pts_m[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = np.stack(
            [camera.fx * pts_m[:, 0] / z + camera.cx, camera.fy * pts_m[:, 1] / z + camera.cy], 1
        )
    inside = (z > 0) & (uv[:, 0] > -0.5) & (uv[:, 0] < camera.width - 0.5)
    inside &= (uv[:, 1] > -0.5) & (uv[:, 1] < camera.height - 0.5)
    uv[~inside] = np.nan
    return uv


def _max_motion(camera: PinholeCamera, frames_pts: Sequence[np.ndarray]) -> float:
    """Largest image displacement of corresponding vertices between consecutive frames."""
    best = 0.0
    for a, b in itertools.pairwise(frames_pts):
        d = np.linalg.norm(_project(camera, a) - _project(camera, b), axis=1)
        if np.isfinite(d).any():
            best = max(best, float(np.nanmax(d)))
    return best


class _Frame:
    """Pixel ↔ metre conversion for one low-res camera."""

    def __init__(self, camera: PinholeCamera) -> None:
        self.cam = camera

    def point(self, u: float, v: float, z_mm: float) -> np.ndarray:
        """Camera-frame point (m) seen at low-res (column u, row v) px at depth z (mm)."""
        z = z_mm / 1000.0
        return np.array(
            [(u - self.cam.cx) * z / self.cam.fx, (v - self.cam.cy) * z / self.cam.fy, z]
        )

    def size(self, px: float, z_mm: float) -> float:
        """Metric length (m) of ``px`` low-res pixels at depth z (mm)."""
        return px * z_mm / 1000.0 / self.cam.fx


def _render_static_camera(
    name: str,
    camera: PinholeCamera,
    r: int,
    n_frames: int,
    static: Mesh,
    moving_at: Callable[[int], Mesh],
    wall_mm: float | None,
) -> RealisticVideo:
    """Render a static camera looking at ``static`` + ``moving_at(t)`` (+ a wall)."""
    hi_cam = camera.scaled(r)
    low = np.empty((n_frames, camera.height, camera.width), np.float32)
    truth = np.empty((n_frames, hi_cam.height, hi_cam.width), np.float32)
    moving = np.empty(truth.shape, bool)
    pts = []
    for t in range(n_frames):
        mv = moving_at(t)
        pts.append(mv[0])
        verts, faces = merge([static, mv])
        low[t] = render_depth(verts, faces, camera, background_mm=wall_mm)
        truth[t] = render_depth(verts, faces, hi_cam, background_mm=wall_mm)
        mv_only = render_depth(mv[0], mv[1], hi_cam)
        moving[t] = (mv_only > 0) & (np.abs(mv_only - truth[t]) < 1e-3)
    return RealisticVideo(name, low, truth, moving, r, camera, True, _max_motion(camera, pts))


# --------------------------------------------------------------------------------------------
# Scenes
# --------------------------------------------------------------------------------------------


def galloping_animal(
    lowres_shape: tuple[int, int] = (56, 64),
    *,
    scale: int = 4,
    n_frames: int = 9,
    background: Literal["wall", "none"] = "wall",
    leg_speed_px: float = 5.0,
    leg_width_px: float = 1.5,
    antler_width_px: float = 1.0,
    body_speed_px: float = 1.0,
    gait_period: float = 6.0,
    body_depth_mm: float = 2000.0,
    wall_depth_mm: float = 3000.0,
    fov_x_deg: float = 60.0,
    seed: int = 0,
) -> RealisticVideo:
    """An animal-like body on thin legs, with thin antlers, galloping across the image.

    The body (an ellipsoid ≈ 0.44 w px long) moves ``body_speed_px`` per frame sideways and
    bobs; its four legs (cylinders ``leg_width_px`` wide, 0.3 h px long) swing with period
    ``gait_period`` frames, the amplitude set so that the feet move up to ``leg_speed_px``
    per frame in the image (body motion included, swing angle ≤ 1 rad); two antlers
    (``antler_width_px`` wide) sway on the head. Behind: a fronto-parallel wall at
    ``wall_depth_mm`` or nothing (``background="none"``: no return).

    Parameters
    ----------
    lowres_shape : (int, int)
        Low-res size (h, w) px, each ≥ 16.
    scale : int
        SR factor r (truth is r·h × r·w).
    n_frames : int
        Frames T.
    background : {"wall", "none"}
    leg_speed_px, leg_width_px, antler_width_px, body_speed_px : float
        Low-res px (per frame for speeds).
    gait_period : float
        Frames per stride.
    body_depth_mm, wall_depth_mm : float
        Depths (mm).
    fov_x_deg : float
        Horizontal field of view (degrees).
    seed : int
        Direction of travel and gait phase.

    Returns
    -------
    RealisticVideo
    """
    h, w = _check_shape(lowres_shape)
    r, n = _check_int(scale, "scale", 1), _check_int(n_frames, "n_frames", 1)
    if background not in ("wall", "none"):
        raise InputError(f"background must be 'wall' or 'none', got {background!r}")
    rng = np.random.default_rng(_check_int(seed, "seed", 0))
    cam = PinholeCamera.from_fov(w, h, fov_x_deg)
    fr = _Frame(cam)
    z0 = float(body_depth_mm)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    phase0 = rng.uniform(0, 2 * np.pi)
    rx, ry, rz = 0.22 * w, 0.09 * h, 0.12 * w  # body radii (px; rz in px at body depth)
    leg_len = 0.3 * h
    omega = 2 * np.pi / float(gait_period)
    amp = min(1.0, max(0.0, leg_speed_px - abs(body_speed_px)) / (leg_len * omega))
    t_mid = 0.5 * (n - 1)
    hips = ((0.7, -0.5, 0.0), (0.7, 0.5, np.pi), (-0.7, -0.5, np.pi / 2), (-0.7, 0.5, 1.5 * np.pi))

    def moving_at(t: int) -> Mesh:
        cx = 0.5 * w + sign * body_speed_px * (t - t_mid)
        cy = 0.42 * h + 0.4 * math.sin(omega * t + phase0)
        parts = [ellipsoid(fr.point(cx, cy, z0), [fr.size(q, z0) for q in (rx, ry, rz)])]
        for hx, hz, ph in hips:
            hip_u, hip_z = cx + hx * rx, z0 + hz * fr.size(rz, z0) * 1000.0
            ang = amp * math.sin(omega * t + phase0 + ph)
            foot_u = hip_u + leg_len * math.sin(ang)
            foot_v = cy + 0.5 * ry + leg_len * math.cos(ang)
            parts.append(
                cylinder(
                    fr.point(hip_u, cy, hip_z),
                    fr.point(foot_u, foot_v, hip_z),
                    fr.size(0.5 * leg_width_px, hip_z),
                    n=8,
                )
            )
        head_u, head_v = cx + sign * 1.15 * rx, cy - 1.4 * ry
        parts.append(
            ellipsoid(fr.point(head_u, head_v, z0), [fr.size(q, z0) for q in (0.25 * rx, ry, ry)])
        )
        for side in (-1.0, 1.0):
            sway = 0.15 * math.sin(omega * t + side)
            tip = (head_u + side * 0.12 * h + 0.2 * h * math.sin(sway), head_v - 0.2 * h)
            parts.append(
                cylinder(
                    fr.point(head_u, head_v - 0.5 * ry, z0),
                    fr.point(tip[0], tip[1], z0),
                    fr.size(0.5 * antler_width_px, z0),
                    n=6,
                )
            )
        return merge(parts)

    wall = float(wall_depth_mm) if background == "wall" else None
    return _render_static_camera("gallop", cam, r, n, merge([]), moving_at, wall)


def deforming_body(
    lowres_shape: tuple[int, int] = (56, 64),
    *,
    scale: int = 4,
    n_frames: int = 9,
    head_speed_px: float = 25.0,
    head_period: float = 5.0,
    body_depth_mm: float = 1800.0,
    wall_depth_mm: float = 2800.0,
    fov_x_deg: float = 60.0,
    seed: int = 0,
) -> RealisticVideo:
    """A deforming body in front of a wall: breathing torso, swinging arms, a fast head.

    The head sways sideways as x(t) = x0 + A·sin(2πt/P + φ) on a neck that stretches with it;
    A = ``head_speed_px`` / (2·sin(π/P)), so its largest displacement between two frames is
    ``head_speed_px`` (capped so that the head stays in the image). The torso's radii
    oscillate by ±6 % (period 7 frames) and the arms swing by ±0.5 rad.

    Parameters
    ----------
    lowres_shape : (int, int)
        Low-res size (h, w) px, each ≥ 16.
    scale, n_frames : int
        SR factor r and number of frames T.
    head_speed_px : float
        Largest head displacement per frame (low-res px).
    head_period : float
        Period P (frames) of the head's sway.
    body_depth_mm, wall_depth_mm : float
        Depths (mm).
    fov_x_deg : float
        Horizontal field of view (degrees).
    seed : int
        Phases of the motions.

    Returns
    -------
    RealisticVideo
    """
    h, w, r, n, rng = _sizes(lowres_shape, scale, n_frames, seed)
    cam = PinholeCamera.from_fov(w, h, fov_x_deg)
    fr = _Frame(cam)
    z0 = float(body_depth_mm)
    phase = rng.uniform(0, 2 * np.pi, 3)
    head_r = 0.08 * min(h, w) * 1.2
    amp = float(head_speed_px) / (2 * math.sin(math.pi / float(head_period)))
    amp = min(amp, 0.5 * w - 1.2 * head_r)
    sx, sy = 0.5 * w, 0.55 * h  # torso centre

    def moving_at(t: int) -> Mesh:
        b = 0.06 * math.sin(2 * np.pi * t / 7.0 + phase[0])
        trx, try_ = 0.16 * w * (1 + b), 0.26 * h * (1 - b)
        parts = [
            ellipsoid(
                fr.point(sx, sy, z0), [fr.size(trx, z0), fr.size(try_, z0), fr.size(0.1 * w, z0)]
            )
        ]
        hx = sx + amp * math.sin(2 * np.pi * t / head_period + phase[1])
        hy = sy - try_ - 1.6 * head_r
        parts.append(ellipsoid(fr.point(hx, hy, z0 - 50), [fr.size(head_r, z0)] * 3))
        parts.append(
            cylinder(
                fr.point(sx, sy - 0.8 * try_, z0),
                fr.point(hx, hy, z0 - 50),
                fr.size(0.35 * head_r, z0),
            )
        )
        for side in (-1.0, 1.0):
            ang = side * (0.5 + 0.5 * math.sin(2 * np.pi * t / 6.0 + phase[2] + side))
            sh = (sx + side * 0.9 * trx, sy - 0.6 * try_)
            hand = (sh[0] + side * 0.35 * h * abs(math.sin(ang)), sh[1] + 0.35 * h * math.cos(ang))
            parts.append(
                cylinder(fr.point(*sh, z0 - 80), fr.point(*hand, z0 - 120), fr.size(0.03 * w, z0))
            )
        return merge(parts)

    return _render_static_camera("deforming", cam, r, n, merge([]), moving_at, float(wall_depth_mm))


def spinning_fan(
    lowres_shape: tuple[int, int] = (56, 64),
    *,
    scale: int = 4,
    n_frames: int = 9,
    tip_speed_px: float = 6.0,
    blade_width_px: float = 1.5,
    fan_depth_mm: float = 1600.0,
    ball_speed_mm: float = 50.0,
    wall_depth_mm: float = 3100.0,
    fov_x_deg: float = 60.0,
    seed: int = 0,
) -> RealisticVideo:
    """A spinning fan and a ball flying at the camera, a box and a wall: a static camera.

    Three blades (cylinders ``blade_width_px`` wide, 0.33 h px long) turn about a hub so that
    their tips move ``tip_speed_px`` per frame (a rotation: every point of a blade moves in
    another direction); a ball (radius 0.12 w px) comes ``ball_speed_mm`` nearer per frame
    while it drifts sideways by up to 1.5 px per frame (radial motion of a body before a
    static camera); a box stands on the image's lower edge, its top seen at a grazing angle
    meeting its front face at a crease (a slope change without a depth edge); behind, a
    fronto-parallel wall. Not tuned to: an out-of-sample scene for the rules built on the four
    others.

    Parameters
    ----------
    lowres_shape : (int, int)
        Low-res size (h, w) px, each ≥ 16.
    scale : int
        SR factor r.
    n_frames : int
        Frames T.
    tip_speed_px, blade_width_px : float
        Low-res px (per frame for the speed).
    fan_depth_mm, ball_speed_mm, wall_depth_mm : float
        Depths (mm) and the ball's approach (mm per frame).
    fov_x_deg : float
        Horizontal field of view (degrees).
    seed : int
        Sense of rotation, phase, hub position, ball drift and the depths (±10 %).

    Returns
    -------
    RealisticVideo
    """
    h, w, r, n, rng = _sizes(lowres_shape, scale, n_frames, seed)
    cam = PinholeCamera.from_fov(w, h, fov_x_deg)
    fr = _Frame(cam)
    zf = float(fan_depth_mm) * rng.uniform(0.95, 1.05)
    blade = 0.33 * h
    omega = float(tip_speed_px) / blade
    phase, sense = rng.uniform(0, 2 * np.pi), rng.choice([-1.0, 1.0])
    hub = (w * rng.uniform(0.32, 0.42), 0.45 * h)
    z_ball, ball_u, drift = 2600.0 * rng.uniform(0.95, 1.05), 0.72 * w, rng.uniform(-1.5, 1.5)
    t_mid = 0.5 * (n - 1)
    z_box = 2400.0
    top = box(
        fr.point(0.5 * w, 0.9 * h, z_box),
        [fr.size(0.25 * w, z_box), fr.size(0.08 * h, z_box), 0.2],
    )

    def moving_at(t: int) -> Mesh:
        parts = [ellipsoid(fr.point(*hub, zf), [fr.size(1.5, zf), fr.size(1.5, zf), 0.03])]
        for k in range(3):
            a = phase + sense * omega * t + 2 * np.pi * k / 3
            tip = (hub[0] + blade * math.cos(a), hub[1] + blade * math.sin(a))
            parts.append(
                cylinder(
                    fr.point(*hub, zf), fr.point(*tip, zf), fr.size(0.5 * blade_width_px, zf), n=8
                )
            )
        zb = z_ball - float(ball_speed_mm) * t
        centre = fr.point(ball_u + drift * (t - t_mid), 0.6 * h, zb)
        parts.append(ellipsoid(centre, [fr.size(0.12 * w, z_ball)] * 3))
        return merge(parts)

    wall = float(wall_depth_mm) * rng.uniform(0.95, 1.05)
    return _render_static_camera("fan", cam, r, n, top, moving_at, wall)


def _render_moving_camera(
    name: str,
    camera: PinholeCamera,
    r: int,
    poses: Sequence[np.ndarray],
    mesh: Mesh,
    wall_mm: Callable[[int], float | None],
) -> RealisticVideo:
    hi_cam = camera.scaled(r)
    n = len(poses)
    low = np.empty((n, camera.height, camera.width), np.float32)
    truth = np.empty((n, hi_cam.height, hi_cam.width), np.float32)
    for t, pose in enumerate(poses):
        low[t] = render_depth(*mesh, camera, world_to_camera=pose, background_mm=wall_mm(t))
        truth[t] = render_depth(*mesh, hi_cam, world_to_camera=pose, background_mm=wall_mm(t))
    pts = [mesh[0] @ np.asarray(p)[:3, :3].T + np.asarray(p)[:3, 3] for p in poses]
    motion = _max_motion(camera, pts)
    poses_4x4 = np.stack([np.vstack([np.asarray(p, np.float64)[:3], [0, 0, 0, 1]]) for p in poses])
    return RealisticVideo(name, low, truth, truth > 0, r, camera, False, motion, poses_4x4)


def camera_toward_wall(
    lowres_shape: tuple[int, int] = (56, 64),
    *,
    scale: int = 4,
    n_frames: int = 9,
    speed_mm: float = 25.0,
    wall_depth_mm: float = 2500.0,
    n_boxes: int = 6,
    fov_x_deg: float = 60.0,
    seed: int = 0,
) -> RealisticVideo:
    """A camera moving straight towards a static wall with boxes on it.

    The fronto-parallel wall is at ``wall_depth_mm`` in frame 0 and ``speed_mm`` nearer in
    each following frame (the camera translates along its optical axis). ``n_boxes`` boxes
    (seeded sizes 0.08–0.25 w px, protruding 80–400 mm) give the wall relief in depth.

    Parameters
    ----------
    lowres_shape : (int, int)
        Low-res size (h, w) px, each ≥ 16.
    scale, n_frames : int
        SR factor r and number of frames T.
    speed_mm : float
        Camera motion per frame along the optical axis (mm).
    wall_depth_mm : float
        Wall depth in frame 0 (mm).
    n_boxes : int
        Boxes on the wall.
    fov_x_deg : float
        Horizontal field of view (degrees).
    seed : int
        Box layout.

    Returns
    -------
    RealisticVideo
        ``moving`` is every valid pixel (the camera moves).
    """
    h, w, r, n, rng = _sizes(lowres_shape, scale, n_frames, seed)
    cam = PinholeCamera.from_fov(w, h, fov_x_deg)
    fr = _Frame(cam)
    zw = float(wall_depth_mm)
    boxes = []
    for _ in range(_check_int(n_boxes, "n_boxes", 0)):
        u, v = rng.uniform(0.1 * w, 0.9 * w), rng.uniform(0.1 * h, 0.9 * h)
        half_u, half_v = rng.uniform(0.04, 0.125, 2) * w
        depth = rng.uniform(80.0, 400.0)
        c = fr.point(u, v, zw - 0.5 * depth)
        boxes.append(box(c, [fr.size(half_u, zw), fr.size(half_v, zw), 0.5 * depth / 1000.0]))
    poses = [np.array(_translation(0.0, 0.0, -float(speed_mm) * t / 1000.0)) for t in range(n)]
    return _render_moving_camera(
        "toward_wall", cam, r, poses, merge(boxes), lambda t: zw - float(speed_mm) * t
    )


def _translation(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def moving_camera_room(
    lowres_shape: tuple[int, int] = (56, 64),
    *,
    scale: int = 4,
    n_frames: int = 9,
    step_mm: float = 30.0,
    yaw_deg_per_frame: float = 0.5,
    n_boxes: int = 5,
    fov_x_deg: float = 60.0,
    seed: int = 0,
) -> RealisticVideo:
    """A closed room (4 × 2.6 × 5.5 m: floor, ceiling, walls) with boxes, seen while moving.

    The camera (1.4 m above the floor, 1 m in front of the back wall behind it) translates
    sideways by ``step_mm`` and forwards by ``step_mm`` / 3 per frame and turns by
    ``yaw_deg_per_frame``. Every pixel sees a surface (dense truth). ``n_boxes`` seeded
    boxes (0.3–0.9 m) stand on the floor 1.5–4 m ahead, plus a table-like slab.

    Parameters
    ----------
    lowres_shape : (int, int)
        Low-res size (h, w) px, each ≥ 16.
    scale, n_frames : int
        SR factor r and number of frames T.
    step_mm : float
        Lateral camera motion per frame (mm).
    yaw_deg_per_frame : float
        Camera rotation about the vertical per frame (degrees).
    n_boxes : int
        Boxes on the floor.
    fov_x_deg : float
        Horizontal field of view (degrees).
    seed : int
        Seed of the box layout.

    Returns
    -------
    RealisticVideo
        Every pixel is measured (a closed room) and, as the camera moves, ``moving``.
    """
    h, w, r, n, rng = _sizes(lowres_shape, scale, n_frames, seed)
    cam = PinholeCamera.from_fov(w, h, fov_x_deg)
    floor_y = 1.4  # y down: the floor is below the camera
    room = [box((0.0, floor_y - 1.3, 1.75), (2.0, 1.3, 2.75))]  # seen from inside
    for _ in range(_check_int(n_boxes, "n_boxes", 0)):
        size = rng.uniform(0.3, 0.9, 3)
        x, z = rng.uniform(-1.6, 1.6), rng.uniform(1.5, 4.0)
        room.append(box((x, floor_y - 0.5 * size[1], z), 0.5 * size))
    room.append(box((rng.uniform(-1, 1), floor_y - 0.75, 2.2), (0.6, 0.03, 0.4)))  # slab
    mesh = merge(room)
    side = 1.0 if rng.random() < 0.5 else -1.0
    t_mid = 0.5 * (n - 1)
    poses = []
    for t in range(n):
        eye = np.array([side * step_mm * (t - t_mid), 0.0, step_mm / 3.0 * t]) / 1000.0
        yaw = math.radians(side * yaw_deg_per_frame * (t - t_mid))
        ahead = eye + np.array([math.sin(yaw), 0.0, math.cos(yaw)])
        poses.append(look_at(eye, ahead, up=(0.0, -1.0, 0.0)))
    return _render_moving_camera("room", cam, r, poses, mesh, lambda t: None)


SCENES: dict[str, Callable[..., RealisticVideo]] = {
    "gallop": galloping_animal,
    "toward_wall": camera_toward_wall,
    "deforming": deforming_body,
    "fan": spinning_fan,
    "room": moving_camera_room,
}


def make_realistic(name: str, lowres_shape: tuple[int, int] = (56, 64), **kwargs) -> RealisticVideo:
    """Build the scene ``name`` (a key of :data:`SCENES`; ``"gallop_none"``: no wall)."""
    if name == "gallop_none":
        return galloping_animal(lowres_shape, background="none", **kwargs)
    if name not in SCENES:
        raise InputError(f"unknown scene {name!r}; choose from {sorted(SCENES)} or 'gallop_none'")
    return SCENES[name](lowres_shape, **kwargs)


# --------------------------------------------------------------------------------------------
# Sensors
# --------------------------------------------------------------------------------------------


def degrade(
    video: RealisticVideo,
    sensor: Sensor,
    rng: np.random.Generator,
    *,
    sigma_mm: float = 10.0,
    dropout_fraction: float = 0.0,
) -> np.ndarray:
    """Low-res input frames of ``video`` as a sensor would deliver them.

    Parameters
    ----------
    video : RealisticVideo
    sensor : {"clean", "laplace", "gaussian", "tof", "tof_gaussian", "kinect"}
        ``clean``: the point samples; ``laplace`` / ``gaussian``: i.i.d. noise of std
        ``sigma_mm`` on them; ``tof``: :func:`~upsr.research.synth.degradation.tof_footprint`
        of the truth (mixed pixels at edges, no return where the block is mostly empty) plus
        Laplacian noise of std ``sigma_mm``; ``tof_gaussian``: the same with Gaussian noise
        (a ToF camera's shot noise); ``kinect``:
        :func:`~upsr.research.synth.degradation.kinect` with the image focal length of
        ``video.camera`` (shadows, Nguyen et al. noise, 1/8 px disparity, 1 % dropouts).
    rng : numpy.random.Generator
    sigma_mm : float
        Noise std (mm) of the ``laplace``, ``gaussian``, ``tof`` and ``tof_gaussian`` sensors.
    dropout_fraction : float
        Share of the pixels of the ``laplace``, ``gaussian`` and ``tof`` sensors that return
        nothing (0), drawn independently after the noise
        (:func:`~upsr.research.synth.degradation.dropout`; the ``kinect`` sensor has its own
        1 %).

    Returns
    -------
    ndarray of float32 (T, h, w), mm, 0 = no return.
    """
    if sensor == "clean":
        return video.lowres.copy()
    if sensor == "kinect":
        return _deg.kinect(video.lowres, rng, image_focal_px=video.camera.fx)
    if sensor == "laplace":
        low = _deg.add_laplacian_noise(video.lowres, sigma_mm, rng)
    elif sensor == "gaussian":
        low = _deg.add_depth_dependent_noise(video.lowres, float(sigma_mm), rng, law="gaussian")
    elif sensor == "tof":
        low = _deg.add_laplacian_noise(_deg.tof_footprint(video.truth, video.scale), sigma_mm, rng)
    elif sensor == "tof_gaussian":
        footprint = _deg.tof_footprint(video.truth, video.scale)
        low = _deg.add_depth_dependent_noise(footprint, float(sigma_mm), rng, law="gaussian")
    else:
        raise InputError(f"unknown sensor {sensor!r}; choose from {SENSORS}")
    return _deg.dropout(low, dropout_fraction, rng)
