"""Registration by the camera's own motion (``camera_motion="depth"``, beyond the paper).

Where the camera moves in a static scene, the motion of every pixel between two frames
follows from its depth and the camera's rigid motion. The flow (paper §4) sees that motion
only where the depth has texture, and a camera moving along its axis moves the edges of point
samples by a fraction of a pixel per frame, which a local flow all but misses
(``benchmarks/registration_oracle.py``: with the true motion the approaching camera's rmse
falls to bicubic's). Here the camera's motion between consecutive frames is estimated from
the depth itself (:func:`rigid_motion`, point-to-plane ICP with the frames' intrinsics),
chained over the window (:func:`window_poses`), and each pixel of the reference (its
prefiltered depth on the flow grid, :func:`pose_maps`) and each low-res sample of the other
frames (its own depth, :func:`pose_samples`) is carried by :func:`reproject`.

ICP can take a sideways step of the camera for a turn (an equal cost on a far scene at
64×56 px), and it registers bodies that move on their own as still; so the engine uses the
camera's motion only in windows where every step goes along the optical axis
(:func:`along_axis`), and only at the pixels whose flow agrees with it
(:data:`AGREEMENT_PX`); everywhere else the flow, and always the flow where the video's mixed
pixels are removed (a footprint sensor: its mixes move with the edges' sub-pixel motion,
which the flow sees).

Conventions (those of :mod:`upsr.geometry.rendering`): camera frame x right, y down, z
forward; pixel (i, j) centred at (u, v) = (j, i); a pixel (u, v) with depth Z (mm) is the
point Z·((u − cx)/fx, (v − cy)/fy, 1); poses are 4×4 world-to-camera transforms in metres.

References
----------
Chen, Y. & Medioni, G. (1992). Object modelling by registration of multiple range images.
*Image and Vision Computing* 10(3), 145–155 (point-to-plane ICP).
Newcombe, R. A. et al. (2011). KinectFusion: Real-time dense surface mapping and tracking.
*ISMAR 2011*, 127–136 (projective data association).
Hartley, R. & Zisserman, A. (2004). *Multiple View Geometry in Computer Vision*, 2nd ed., §6.1.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError

__all__ = [
    "AGREEMENT_PX",
    "AXIAL_RATIO",
    "ICP_POINTS",
    "MAX_TURN_DEG",
    "MIN_STEP_MM",
    "STEP_TOLERANCE",
    "Intrinsics",
    "agreeing",
    "along_axis",
    "camera_points",
    "grid_intrinsics",
    "pair_motion",
    "pose_maps",
    "pose_samples",
    "reproject",
    "rigid_motion",
    "rotation_from_vector",
    "window_poses",
]

#: (fx, fy, cx, cy) in px.
Intrinsics = tuple[float, float, float, float]
#: A pixel takes the camera's motion where the flow agrees with it within this (low-res px);
#: elsewhere (a body moving on its own) the flow.
AGREEMENT_PX = 2.0
#: :func:`along_axis`: a step moves along the optical axis when its axial part is at least
#: this many times its sideways part ...
AXIAL_RATIO = 3.0
#: ... and at least this long (mm; a still camera is registered by the flow) ...
MIN_STEP_MM = 5.0
#: ... and it turns the camera by at most this (degrees).
MAX_TURN_DEG = 0.5
#: :func:`rigid_motion` stops once a step moves the camera by less than this (m, and rad):
#: 0.1 mm. Its steps stay near 0.05–0.1 mm on noisy frames, sliding along the sideways / turn
#: ambiguity rather than converging: 20 steps and this tolerance gave the approaching camera
#: the rmse of 60 steps and 10 µm within ±0.2 % (seeds 0–3, Laplace σ = 0 / 10, Gauss 20, both
#: modes) at 15.6 instead of 52.9 ms per pair at 160×120.
STEP_TOLERANCE = 1e-4
#: :func:`rigid_motion` pairs about this many of frame A's points (a grid; all up to 64×64 px).
ICP_POINTS = 4096


def grid_intrinsics(intrinsics: Intrinsics, s: float) -> Intrinsics:
    """The intrinsics of the frames upsampled by ``s`` (``SPEC.md`` §1: f' = s·f,
    c' = s·(c + 0.5) − 0.5)."""
    fx, fy, cx, cy = intrinsics
    return fx * s, fy * s, s * (cx + 0.5) - 0.5, s * (cy + 0.5) - 0.5


def _pose(pose: npt.ArrayLike | None) -> np.ndarray:
    if pose is None:
        return np.eye(4)
    p = np.asarray(pose, dtype=np.float64)
    if p.shape not in ((4, 4), (3, 4)) or not np.isfinite(p).all():
        raise InputError(f"a pose must be a finite 4×4 or 3×4 array, got shape {p.shape}")
    return np.vstack([p[:3], [0.0, 0.0, 0.0, 1.0]])


def camera_points(depth_mm: npt.ArrayLike, intrinsics: Intrinsics) -> np.ndarray:
    """The camera-frame point (metres) of every pixel: float64 (H, W, 3), NaN without depth."""
    z = np.asarray(depth_mm, dtype=np.float64)
    if z.ndim != 2:
        raise InputError(f"depth must be (H, W), got shape {z.shape}")
    fx, fy, cx, cy = intrinsics
    zm = np.where(z > 0, z, np.nan) / 1000.0
    xs = (np.arange(z.shape[1], dtype=np.float64) - cx) / fx
    ys = (np.arange(z.shape[0], dtype=np.float64) - cy) / fy
    return np.stack([xs[None, :] * zm, ys[:, None] * zm, zm], axis=-1)


def reproject(
    depth_mm: npt.ArrayLike,
    intrinsics: Intrinsics,
    from_pose: npt.ArrayLike | None,
    to_pose: npt.ArrayLike | None,
    *,
    u: npt.ArrayLike | None = None,
    v: npt.ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image positions and depths in view B of the points seen with ``depth_mm`` in view A.

    Parameters
    ----------
    depth_mm : array_like, shape (H, W) (or the shape of ``u``)
        Depth Z (mm) along A's optical axis; 0 or NaN = no point.
    intrinsics : (fx, fy, cx, cy)
        The camera of both views (px).
    from_pose, to_pose : array_like (4, 4) or (3, 4), or None (identity)
        World-to-camera poses of A and B (metres).
    u, v : array_like, optional
        Image coordinates (px) in A of each depth; default the pixel centres (u = column).

    Returns
    -------
    (u_b, v_b, z_b) : ndarray float64, the shape of ``depth_mm``
        Position in B (px) and depth along B's optical axis (mm); NaN where there is no point
        or it lies behind B.

    Examples
    --------
    A camera 25 mm nearer a wall at 2.5 m sees it 1 % larger about its principal point:

    >>> ahead = np.eye(4); ahead[2, 3] = -0.025
    >>> ub, vb, zb = reproject(np.full((56, 64), 2500.0), (100.0, 100.0, 31.5, 27.5), None, ahead)
    >>> round(float(ub[0, 63] - 31.5) / (63 - 31.5), 4), float(zb[0, 0])
    (1.0101, 2475.0)
    """
    z = np.asarray(depth_mm, dtype=np.float64)
    fx, fy, cx, cy = intrinsics
    if u is None or v is None:
        if u is not None or v is not None:
            raise InputError("give both u and v, or neither")
        if z.ndim != 2:
            raise InputError(f"depth must be (H, W), got shape {z.shape}")
        us, vs = np.meshgrid(np.arange(z.shape[1], dtype=np.float64),
                             np.arange(z.shape[0], dtype=np.float64))  # fmt: skip
    else:
        us, vs = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
        if us.shape != z.shape or vs.shape != z.shape:
            raise InputError(f"u {us.shape} and v {vs.shape} must have the depth's shape {z.shape}")
    with np.errstate(invalid="ignore"):
        zm = np.where(z > 0, z, np.nan) / 1000.0
    rel = _pose(to_pose) @ np.linalg.inv(_pose(from_pose))  # A's camera frame to B's
    return _project((us - cx) / fx * zm, (vs - cy) / fy * zm, zm, rel, intrinsics)


def _project(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, rel: np.ndarray, intrinsics: Intrinsics
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera-frame points (metres; NaN: none) moved by ``rel`` (4, 4) and projected: (u, v,
    depth in mm), NaN where there is no point or it lies behind the camera."""
    fx, fy, cx, cy = intrinsics
    zb = rel[2, 0] * x + rel[2, 1] * y + rel[2, 2] * z + rel[2, 3]
    with np.errstate(invalid="ignore", divide="ignore"):
        zb = np.where(zb > 0, zb, np.nan)
        ub = fx * (rel[0, 0] * x + rel[0, 1] * y + rel[0, 2] * z + rel[0, 3]) / zb + cx
        vb = fy * (rel[1, 0] * x + rel[1, 1] * y + rel[1, 2] * z + rel[1, 3]) / zb + cy
    return ub, vb, 1000.0 * zb


def rotation_from_vector(omega: npt.ArrayLike) -> np.ndarray:
    """Rotation matrix (3, 3) of the rotation vector ``omega`` (axis × angle in radians;
    Rodrigues' formula)."""
    w = np.asarray(omega, dtype=np.float64).reshape(3)
    theta = float(np.linalg.norm(w))
    if theta < 1e-12:
        return np.eye(3)
    k = w / theta
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(theta) * cross + (1.0 - np.cos(theta)) * (cross @ cross)


def _normals(points: np.ndarray, edge_mm: float) -> np.ndarray:
    """Unit normals (central differences), NaN at the image border, without depth, or where a
    4-neighbour lies across a depth edge."""
    n = np.full(points.shape, np.nan)
    dx = points[1:-1, 2:] - points[1:-1, :-2]
    dy = points[2:, 1:-1] - points[:-2, 1:-1]
    c = np.cross(dx, dy)
    z = points[..., 2]
    step = edge_mm / 1000.0
    with np.errstate(invalid="ignore"):
        jump = np.zeros(c.shape[:2], bool)
        centre = z[1:-1, 1:-1]
        for sl in ((slice(1, -1), slice(2, None)), (slice(1, -1), slice(None, -2)),
                   (slice(2, None), slice(1, -1)), (slice(None, -2), slice(1, -1))):  # fmt: skip
            jump |= ~(np.abs(z[sl] - centre) <= step)
        norm = np.linalg.norm(c, axis=-1, keepdims=True)
        n[1:-1, 1:-1] = np.where(jump[..., None] | ~(norm > 0), np.nan, c / norm)
    return n


def rigid_motion(
    depth_a: npt.ArrayLike,
    depth_b: npt.ArrayLike,
    intrinsics: Intrinsics,
    *,
    noise_mm: float = 10.0,
    edge_mm: float = 100.0,
    iterations: int = 20,
    initial: npt.ArrayLike | None = None,
) -> np.ndarray:
    """The camera's motion from frame A to frame B of a static scene (point-to-plane ICP).

    Parameters
    ----------
    depth_a, depth_b : array_like (H, W)
        Depth (mm) seen by ``camera``; 0 or NaN = none.
    intrinsics : (fx, fy, cx, cy)
        Intrinsics of both frames (px).
    noise_mm : float
        Noise std of the depth (mm): the Huber scale (1.5σ, at least 2 mm) and, after the
        first ten steps, the rejection of pairs farther than max(50 mm, 4σ) apart along B's
        normal (300 mm before).
    edge_mm : float
        A 4-neighbour farther than this is across a depth edge (no normal there).
    iterations : int
        Largest number of Gauss–Newton steps (stops once a step moves by less than
        :data:`STEP_TOLERANCE`); A's points are taken on a grid of about :data:`ICP_POINTS`.
    initial : array_like (4, 4), optional
        Starting estimate (e.g. the previous pair's motion); identity by default.

    Returns
    -------
    ndarray float64 (4, 4): T with X_B = T·X_A for the camera-frame points (metres), i.e.
    world_to_camera_B = T · world_to_camera_A.

    Raises
    ------
    InputError
        The frames' shapes differ, or fewer than 6 pixels pair up.
    """
    pa = camera_points(depth_a, intrinsics)
    pb = camera_points(depth_b, intrinsics)
    if pa.shape != pb.shape:
        raise InputError(f"frames of shapes {pa.shape[:2]} and {pb.shape[:2]}")
    fx, fy, cx, cy = intrinsics
    nb = _normals(pb, float(edge_mm))
    # A's points on a grid of about ICP_POINTS (all of them up to 64×64 px)
    stride = max(1, int(math.sqrt(pa.shape[0] * pa.shape[1] / ICP_POINTS)))
    src = pa[::stride, ::stride]
    src = src[np.isfinite(src[..., 2])]
    h, w = pb.shape[:2]
    t_est = _pose(initial)
    scale = max(float(noise_mm) / 1000.0, 0.002)
    for it in range(int(iterations)):
        x = src @ t_est[:3, :3].T + t_est[:3, 3]
        with np.errstate(invalid="ignore", divide="ignore"):
            u = np.rint(fx * x[:, 0] / x[:, 2] + cx)
            v = np.rint(fy * x[:, 1] / x[:, 2] + cy)
            inside = (x[:, 2] > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
        ui, vi = u[inside].astype(np.int64), v[inside].astype(np.int64)
        x, q, n = x[inside], pb[vi, ui], nb[vi, ui]
        res = np.einsum("ij,ij->i", x - q, n)
        limit = 0.3 if it < 10 else max(0.05, 4.0 * float(noise_mm) / 1000.0)
        with np.errstate(invalid="ignore"):
            keep = np.abs(res) < limit  # (NaN: no point or no normal there)
        if keep.sum() < 6:
            raise InputError("rigid_motion: fewer than 6 pixels pair up between the frames")
        x, n, res = x[keep], n[keep], res[keep]
        wgt = np.minimum(1.0, 1.5 * scale / np.maximum(np.abs(res), 1e-12))
        jac = np.hstack([np.cross(x, n), n])
        step = -np.linalg.solve((jac * wgt[:, None]).T @ jac + 1e-12 * np.eye(6),
                                (jac * wgt[:, None]).T @ res)  # fmt: skip
        update = np.eye(4)
        update[:3, :3] = rotation_from_vector(step[:3])
        update[:3, 3] = step[3:]
        t_est = update @ t_est
        if np.abs(step).max() < STEP_TOLERANCE:
            break
    return t_est


def pair_motion(
    first: np.ndarray,
    second: np.ndarray,
    intrinsics: Intrinsics,
    *,
    noise_mm: float,
    edge_mm: float,
) -> np.ndarray | None:
    """The camera's motion from one frame to the next (:func:`rigid_motion` from the identity,
    so that a pair gives the same motion in every window and every chunk of a video), or None
    where the frames share too little to tell (fewer than 6 pixels pair up)."""
    try:
        return rigid_motion(first, second, intrinsics, noise_mm=max(noise_mm, 2.0), edge_mm=edge_mm)
    except InputError:
        return None


def along_axis(step: np.ndarray | None) -> bool:
    """Whether a step of the camera (:func:`pair_motion`) goes along its optical axis, where
    ICP is well conditioned: at least :data:`MIN_STEP_MM` long, its axial part at least
    :data:`AXIAL_RATIO` times its sideways part, a turn of at most :data:`MAX_TURN_DEG`."""
    if step is None:
        return False
    t = 1000.0 * step[:3, 3]
    turn = math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(step[:3, :3]) - 1.0) / 2.0))))
    axial, sideways = abs(float(t[2])), float(np.hypot(t[0], t[1]))
    return axial >= MIN_STEP_MM and axial >= AXIAL_RATIO * sideways and turn <= MAX_TURN_DEG


def window_poses(frames: Sequence[int], step: Callable[[int], np.ndarray]) -> np.ndarray:
    """(N, 4, 4) poses of a window's frames relative to its first, chained from ``step(k)``,
    the motion from frame k − 1 to frame k."""
    poses = [np.eye(4)]
    for k in list(frames)[1:]:
        poses.append(step(k) @ poses[-1])
    return np.stack(poses)


def pose_maps(
    depth: np.ndarray, intrinsics: Intrinsics, poses: np.ndarray, ref: int, out: np.ndarray
) -> np.ndarray:
    """Where each pixel of the reference lies in each frame of a window, as displacements:
    ``out`` (N, fh, fw, 2) float32 (the maps of
    :func:`upsr.method.registration.cumulative_flows`), from the reference's ``depth`` (mm;
    0: none, displacement 0) on a grid of ``intrinsics`` and the frames' ``poses`` (N, 4, 4)."""
    pts = camera_points(depth, intrinsics)  # the reference's points, once
    xs = np.arange(depth.shape[1], dtype=np.float64)[None, :]
    ys = np.arange(depth.shape[0], dtype=np.float64)[:, None]
    inv_ref = np.linalg.inv(_pose(poses[ref]))
    for i, pose in enumerate(poses):
        if i == ref:
            out[i] = 0.0
            continue
        rel = _pose(pose) @ inv_ref  # the reference's camera frame to frame i's
        ub, vb, _ = _project(pts[..., 0], pts[..., 1], pts[..., 2], rel, intrinsics)
        out[i, ..., 0] = np.nan_to_num(ub - xs)
        out[i, ..., 1] = np.nan_to_num(vb - ys)
    return out


def pose_samples(
    lowres: np.ndarray, intrinsics: Intrinsics, s: float, pose: np.ndarray, to_pose: np.ndarray
) -> np.ndarray:
    """(h, w, 2) float64: a frame's low-res sample centres (its ``intrinsics``, its depth) in
    another frame, on the grid upsampled by ``s`` (px); a sample without depth stays put."""
    h, w = lowres.shape
    ii, jj = np.mgrid[0:h, 0:w].astype(np.float64)
    ub, vb, _ = reproject(lowres, intrinsics, pose, to_pose)
    ub = np.where(np.isnan(ub), jj, ub)
    vb = np.where(np.isnan(vb), ii, vb)
    return np.stack([(ub + 0.5) * s - 0.5, (vb + 0.5) * s - 0.5], axis=-1)


@nb.njit(cache=True, nogil=True)
def _agreeing_kernel(by_flow, by_pose, limit, out):  # pragma: no cover - numba
    for i in range(by_flow.shape[0]):
        dx = by_pose[i, 0] - by_flow[i, 0]
        dy = by_pose[i, 1] - by_flow[i, 1]
        src = by_pose if math.hypot(dx, dy) <= limit else by_flow  # (NaN: the flow)
        out[i, 0] = src[i, 0]
        out[i, 1] = src[i, 1]


def agreeing(
    by_flow: np.ndarray, by_pose: np.ndarray, grid_scale: float, *, out: np.ndarray | None = None
) -> np.ndarray:
    """The camera's motion ``by_pose`` where the flow ``by_flow`` agrees with it within
    :data:`AGREEMENT_PX` low-res px, the flow elsewhere (a body moving on its own): maps of
    one shape (…, 2) and dtype on a flow grid ``grid_scale`` times the frames', written to
    ``out`` (which may be ``by_flow``; default a new array). One compiled pass."""
    if out is None:
        out = np.empty(by_flow.shape, by_flow.dtype)
    if not out.flags.c_contiguous or out.dtype != by_flow.dtype:
        raise ValueError("out must be C-contiguous, of by_flow's dtype")
    flow = np.ascontiguousarray(by_flow).reshape(-1, 2)
    pose = np.ascontiguousarray(by_pose, by_flow.dtype).reshape(-1, 2)
    _agreeing_kernel(flow, pose, float(AGREEMENT_PX * grid_scale), out.reshape(-1, 2))
    return out
