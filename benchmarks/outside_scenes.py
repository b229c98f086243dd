"""The scenes of :mod:`outside_eval` (an audit of 7 Dec 2026, built outside the rules'
development): each a function returning a :class:`~upsr.research.synth.realistic.RealisticVideo`
rendered with the project's helpers, with the audit's parameters."""

from __future__ import annotations

import math

import numpy as np

from upsr.geometry.camera import PinholeCamera
from upsr.geometry.rendering import look_at
from upsr.research.synth.primitives import Mesh, box, cylinder, ellipsoid, merge
from upsr.research.synth.realistic import (
    RealisticVideo,
    _Frame,
    _render_moving_camera,
    _render_static_camera,
)

__all__ = [
    "corridor",
    "hand",
    "propeller",
    "slanted",
    "sphere_diag",
    "static_wall",
    "table_scene",
    "toward_slanted_wall",
    "walker",
]

#: A wall: a depth (mm), a plane (normal, offset mm: n·X = d in camera coordinates) or none.
Background = float | tuple[np.ndarray, float] | None
Shape = tuple[int, int]

# --------------------------------------------------------------------------------------------
# Scenes (the audit's generators, with its parameters)
# --------------------------------------------------------------------------------------------


def _camera(shape: Shape, fov_x_deg: float = 60.0) -> tuple[PinholeCamera, _Frame]:
    h, w = shape
    cam = PinholeCamera.from_fov(w, h, fov_x_deg)
    return cam, _Frame(cam)


def _capsule(p0: np.ndarray, p1: np.ndarray, radius: float, n: int = 10) -> Mesh:
    """A cylinder with a sphere at each end (a limb)."""
    return merge(
        [
            cylinder(p0, p1, radius, n=n),
            ellipsoid(p0, [radius] * 3, 8, 12),
            ellipsoid(p1, [radius] * 3, 8, 12),
        ]
    )


def _yawed_plane(yaw_deg: float, z_mm: float) -> tuple[np.ndarray, float]:
    """The plane through (0, 0, z) whose normal is turned ``yaw_deg`` about the vertical."""
    n = np.array([math.sin(math.radians(yaw_deg)), 0.0, math.cos(math.radians(yaw_deg))])
    return n, float(n @ np.array([0.0, 0.0, z_mm]))


def table_scene(
    shape: Shape = (56, 64),
    r: int = 4,
    n_frames: int = 15,
    leg_px: float = 1.2,
    z: float = 2000.0,
    wall: float = 3000.0,
    ball: bool = True,
) -> RealisticVideo:
    """A static table with thin legs (``leg_px`` wide), optionally a ball rolling under it."""
    h, w = shape
    cam, fr = _camera(shape)
    top_c = fr.point(0.5 * w, 0.5 * h, z)
    hw, hd = fr.size(0.3 * w, z), 0.35
    top = box(top_c, [hw, fr.size(0.8, z), hd])
    legs = []
    for sx in (-1, 1):
        for sz in (-1, 1):
            x, zz = top_c[0] + sx * 0.9 * hw, top_c[2] + sz * 0.9 * hd
            foot = [x, top_c[1] + fr.size(0.45 * h, z), zz]
            legs.append(cylinder([x, top_c[1], zz], foot, fr.size(leg_px / 2, z), n=8))
    static = merge([top, *legs])

    def moving_at(t: int) -> Mesh:
        if not ball:
            return merge([])
        u = 0.1 * w + 3.0 * t
        return ellipsoid(fr.point(u, 0.8 * h, z + 500), [fr.size(0.07 * w, z + 500)] * 3)

    return _render_static_camera("table", cam, r, n_frames, static, moving_at, wall)


def static_wall(
    shape: Shape = (60, 80), r: int = 2, n_frames: int = 15, z: float = 3000.0, yaw_deg: float = 0
) -> RealisticVideo:
    """A bare wall at ``z`` mm (on the optical axis) yawed ``yaw_deg``; field of view 57°."""
    cam, _ = _camera(shape, 57.0)
    plane: Background = _yawed_plane(yaw_deg, z)
    return _render_static_camera(
        "static_wall", cam, r, n_frames, merge([]), lambda t: merge([]), plane
    )


def slanted(shape: Shape = (56, 64), r: int = 4, n_frames: int = 15) -> RealisticVideo:
    """Static: a wall yawed 50° at 2.5 m, a floor seen at a grazing angle, a tilted panel."""
    h, w = shape
    cam, fr = _camera(shape)
    plane: Background = _yawed_plane(50.0, 2500.0)
    # the floor: the plane y = 0.9 m (below the camera) from 0.3 to 8 m
    floor_v = np.array([[-3, 0.9, 0.3], [3, 0.9, 0.3], [3, 0.9, 8], [-3, 0.9, 8]], float)
    floor = (floor_v, np.array([[0, 1, 2], [0, 2, 3]]))
    # a thin panel turned 35° about the vertical and 0.4 rad about the horizontal
    pv, pf = box([0, 0, 0], [0.25, 0.18, 0.01])
    th, ph = math.radians(35), 0.4
    yaw = np.array([[math.cos(th), 0, math.sin(th)], [0, 1, 0], [-math.sin(th), 0, math.cos(th)]])
    pitch = np.array([[1, 0, 0], [0, math.cos(ph), -math.sin(ph)], [0, math.sin(ph), math.cos(ph)]])
    panel = (pv @ (pitch @ yaw).T + fr.point(0.35 * w, 0.4 * h, 1800.0), pf)
    static = merge([floor, panel])
    return _render_static_camera("slanted", cam, r, n_frames, static, lambda t: merge([]), plane)


def walker(
    shape: Shape = (56, 64),
    r: int = 4,
    n_frames: int = 15,
    z: float = 2200.0,
    wall: float = 3200.0,
    speed: float = 1.5,
    limb_px: float = 2.0,
) -> RealisticVideo:
    """A person of capsules walking sideways ``speed`` px/frame, legs and arms swinging."""
    h, w = shape
    cam, fr = _camera(shape)
    u0 = 0.3 * w

    def s(px: float) -> float:
        return fr.size(px, z)

    def moving_at(t: int) -> Mesh:
        cx = u0 + speed * t
        ph = 2 * math.pi * t / 8.0
        bob = 0.4 * abs(math.sin(ph))
        hip, neck = (cx, 0.6 * h - bob), (cx, 0.3 * h - bob)
        parts = [
            _capsule(fr.point(*hip, z), fr.point(*neck, z), s(0.07 * w)),
            ellipsoid(fr.point(cx, 0.19 * h - bob, z - 30), [s(0.055 * w)] * 3),
        ]
        leg, arm = 0.38 * h, 0.28 * h
        for side, sgn in ((-1, 1), (1, -1)):
            a = 0.5 * math.sin(ph) * sgn
            knee = (hip[0] + 0.5 * leg * math.sin(a), hip[1] + 0.5 * leg * math.cos(a))
            foot = (knee[0] + 0.5 * leg * math.sin(a - 0.3 * abs(a)), knee[1] + 0.5 * leg)
            zl = z + side * 60
            parts += [
                _capsule(fr.point(*hip, zl), fr.point(*knee, zl), s(limb_px * 0.6)),
                _capsule(fr.point(*knee, zl), fr.point(*foot, zl), s(limb_px * 0.5)),
            ]
            b = -0.6 * math.sin(ph) * sgn
            sh = (neck[0], neck[1] + 0.03 * h)
            elbow = (sh[0] + 0.5 * arm * math.sin(b), sh[1] + 0.5 * arm * math.cos(b))
            hand = (
                elbow[0] + 0.5 * arm * math.sin(b + 0.4),
                elbow[1] + 0.5 * arm * math.cos(b + 0.4),
            )
            za = z + side * 90
            parts += [
                _capsule(fr.point(*sh, za), fr.point(*elbow, za), s(limb_px * 0.45)),
                _capsule(fr.point(*elbow, za), fr.point(*hand, za), s(limb_px * 0.4)),
            ]
        return merge(parts)

    return _render_static_camera("walker", cam, r, n_frames, merge([]), moving_at, wall)


def propeller(
    shape: Shape = (56, 64),
    r: int = 4,
    n_frames: int = 15,
    blade_px: float = 1.5,
    z: float = 1200.0,
    wall: float = 2200.0,
    tip0: float = 1.0,
    acc: float = 0.8,
) -> RealisticVideo:
    """Two thin blades on a hub spinning up (tip speed ``tip0 + acc·t`` px/frame) on a stand."""
    h, w = shape
    cam, fr = _camera(shape)
    radius = 0.38 * h
    hub = (0.55 * w, 0.5 * h)

    def moving_at(t: int) -> Mesh:
        ang = (tip0 * t + 0.5 * acc * t * t) / radius
        parts = [ellipsoid(fr.point(*hub, z), [fr.size(2.0, z)] * 2 + [0.04])]
        for k in (0, 1):
            a = ang + math.pi * k
            tip = (hub[0] + radius * math.cos(a), hub[1] + radius * math.sin(a))
            half = fr.size(blade_px / 2, z)
            parts.append(cylinder(fr.point(*hub, z), fr.point(*tip, z), half, n=8))
        return merge(parts)

    # a static stand (a thin pole) under the hub
    stand = cylinder(
        fr.point(hub[0], hub[1], z + 60), fr.point(hub[0], h + 2, z + 60), fr.size(1.0, z)
    )
    return _render_static_camera("propeller", cam, r, n_frames, stand, moving_at, wall)


def toward_slanted_wall(
    shape: Shape = (56, 64),
    r: int = 4,
    n_frames: int = 15,
    speed: float = 25.0,
    z0: float = 1500.0,
    yaw_deg: float = 25.0,
) -> RealisticVideo:
    """The camera moving ``speed`` mm/frame along its axis toward a wall yawed ``yaw_deg`` with
    a cylinder, a shelf and a ball on it."""
    h, w = shape
    cam, fr = _camera(shape)
    n, off = _yawed_plane(yaw_deg, z0)
    pole = (fr.point(0.25 * w, 0.3 * h, z0 - 250), fr.point(0.25 * w, 0.8 * h, z0 - 250))
    mesh = merge(
        [
            cylinder(*pole, 0.08),
            box(fr.point(0.7 * w, 0.35 * h, z0 - 150), [0.25, 0.02, 0.12]),  # a shelf
            ellipsoid(fr.point(0.55 * w, 0.75 * h, z0 - 200), [0.12] * 3),
        ]
    )
    poses = []
    for t in range(n_frames):
        m = np.eye(4)
        m[:3, 3] = -np.array([0, 0, speed * t / 1000.0])
        poses.append(m)

    def wall_at(t: int) -> Background:  # the wall in camera coordinates comes nearer
        return n, off - n[2] * speed * t

    return _render_moving_camera("toward_wall", cam, r, poses, mesh, wall_at)


def sphere_diag(
    shape: Shape = (56, 64),
    r: int = 4,
    n_frames: int = 15,
    z0: float = 3000.0,
    dz: float = 100.0,
    du: float = 1.5,
    dv: float = 1.0,
    wall: float = 3500.0,
) -> RealisticVideo:
    """A ball coming ``dz`` mm/frame nearer while moving diagonally (du, dv) px/frame."""
    h, w = shape
    cam, fr = _camera(shape)

    def moving_at(t: int) -> Mesh:
        c = fr.point(0.3 * w + du * t, 0.35 * h + dv * t, z0 - dz * t)
        return ellipsoid(c, [0.25] * 3, 16, 32)

    return _render_static_camera("sphere_diag", cam, r, n_frames, merge([]), moving_at, wall)


def hand(
    shape: Shape = (56, 64),
    r: int = 4,
    n_frames: int = 15,
    z: float = 550.0,
    wall: float = 1400.0,
    finger_px: float = 2.0,
    wave: float = 0.5,
    period: float = 8.0,
) -> RealisticVideo:
    """A hand close to the camera, fingers spread, waving (a rotation about the wrist)."""
    h, w = shape
    cam, fr = _camera(shape)
    wrist = (0.5 * w, 0.95 * h)
    # (angle, length / h) of the fingers; the first is the thumb
    fingers = ((-0.5, 0.25), (-0.2, 0.33), (0.0, 0.36), (0.2, 0.33), (0.4, 0.27))

    def moving_at(t: int) -> Mesh:
        a = wave * math.sin(2 * math.pi * t / period)

        def rot(dx: float, dy: float) -> tuple[float, float]:
            c, s = math.cos(a), math.sin(a)
            return wrist[0] + dx * c - dy * s, wrist[1] + dx * s + dy * c

        palm_c = rot(0, -0.22 * h)
        palm_radii = [fr.size(0.11 * w, z), fr.size(0.14 * h, z), 0.02]
        parts = [
            ellipsoid(fr.point(*palm_c, z), palm_radii),
            _capsule(fr.point(*wrist, z + 10), fr.point(*palm_c, z), fr.size(0.06 * w, z)),
        ]
        for k, (ang, ln) in enumerate(fingers):
            dx = 0.09 * w * math.sin(ang) * 1.5
            base = rot(dx, -0.33 * h)
            tip = rot(dx + ln * h * math.sin(ang), -0.33 * h - ln * h * math.cos(ang))
            if k == 0:
                base, tip = rot(-0.1 * w, -0.2 * h), rot(-0.1 * w - 0.2 * h, -0.28 * h)
            radius = fr.size(finger_px / 2, z)
            parts.append(_capsule(fr.point(*base, z - 5), fr.point(*tip, z - 10), radius))
        return merge(parts)

    return _render_static_camera("hand", cam, r, n_frames, merge([]), moving_at, wall)


def corridor(
    shape: Shape = (56, 64),
    r: int = 4,
    n_frames: int = 15,
    step_mm: float = 40.0,
    shake_mm: float = 3.0,
    seed: int = 5,
    length: float = 14.0,
) -> RealisticVideo:
    """A corridor (1.6 m wide, 2.4 m high) with door posts, boxes and a bin; the camera walks
    ``step_mm`` per frame along it with a hand-held shake."""
    cam, _ = _camera(shape)
    rng = np.random.default_rng(seed)
    parts = [box([0, 0, length / 2 - 2], [0.8, 1.2, length / 2])]  # seen from inside
    for z in [z for z in (2.0, 3.5, 5.0, 6.5) if z + 1.0 < length - 2]:
        parts.append(box([-0.78, 0.0, z], [0.04, 1.0, 0.05]))  # a door post (protruding)
        parts.append(box([0.78, 0.2, z + 0.7], [0.06, 0.2, 0.3]))  # a box on the right wall
    parts.append(box([0.3, 0.9, 3.0], [0.15, 0.3, 0.15]))  # a bin on the floor
    poses = []
    for t in range(n_frames):
        eye = np.array([0.1, -0.1, step_mm * t / 1000.0]) + rng.normal(0, shake_mm, 3) / 1000.0
        poses.append(look_at(eye, eye + np.array([0.05, 0.05, 1.0]), up=(0.0, -1.0, 0.0)))
    return _render_moving_camera("corridor", cam, r, poses, merge(parts), lambda t: None)


# --------------------------------------------------------------------------------------------
# The cases: (scene, sensors) of each finding of the audit
