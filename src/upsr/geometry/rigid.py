"""The rigid motion of a camera between two depth frames of a static scene.

Point-to-plane ICP (Chen & Medioni 1992) with projective data association (the points of
frame A, moved by the current estimate, are projected into frame B and paired with B's point
at that pixel, as in KinectFusion, Newcombe et al. 2011), Huber weights and Gauss–Newton
steps on the six parameters of a small motion. A research tool
(``benchmarks/registration_oracle.py``): on a camera moving along its axis it registers the
frames as well as the true motion; a sideways step and a turn of the camera can cost the
same (a far scene seen at 64×56 px), which it cannot tell apart.

References
----------
Chen, Y. & Medioni, G. (1992). Object modelling by registration of multiple range images.
*Image and Vision Computing* 10(3), 145–155.
Newcombe, R. A. et al. (2011). KinectFusion: Real-time dense surface mapping and tracking.
*ISMAR 2011*, 127–136.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera

__all__ = ["camera_points", "rigid_motion", "rotation_from_vector"]


def camera_points(depth_mm: npt.ArrayLike, camera: PinholeCamera) -> np.ndarray:
    """The camera-frame point (metres) of every pixel: float64 (H, W, 3), NaN without depth."""
    z = np.asarray(depth_mm, dtype=np.float64)
    if z.shape != camera.shape:
        raise InputError(f"depth of shape {z.shape} for a camera of shape {camera.shape}")
    zm = np.where(z > 0, z, np.nan) / 1000.0
    xs, ys = camera.rays()
    return np.stack([xs * zm, ys * zm, zm], axis=-1)


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
    camera: PinholeCamera,
    *,
    noise_mm: float = 10.0,
    edge_mm: float = 100.0,
    iterations: int = 60,
    initial: npt.ArrayLike | None = None,
) -> np.ndarray:
    """The camera's motion from frame A to frame B of a static scene (point-to-plane ICP).

    Parameters
    ----------
    depth_a, depth_b : array_like (H, W)
        Depth (mm) seen by ``camera``; 0 or NaN = none.
    camera : PinholeCamera
        Intrinsics of both frames (px).
    noise_mm : float
        Noise std of the depth (mm): the Huber scale (1.5σ, at least 2 mm) and, after the
        first ten steps, the rejection of pairs farther than max(50 mm, 4σ) apart along B's
        normal (300 mm before).
    edge_mm : float
        A 4-neighbour farther than this is across a depth edge (no normal there).
    iterations : int
        Largest number of Gauss–Newton steps (stops once a step is below 1e-7).
    initial : array_like (4, 4), optional
        Starting estimate (e.g. the previous pair's motion); identity by default.

    Returns
    -------
    ndarray float64 (4, 4): T with X_B = T·X_A for the camera-frame points (metres), i.e.
    world_to_camera_B = T · world_to_camera_A.

    Raises
    ------
    InputError
        Shapes differ from the camera's, or fewer than 6 pixels pair up.
    """
    pa = camera_points(depth_a, camera)
    pb = camera_points(depth_b, camera)
    nb = _normals(pb, float(edge_mm))
    src = pa[np.isfinite(pa[..., 2])]
    h, w = camera.height, camera.width
    t_est = np.eye(4) if initial is None else np.array(initial, dtype=np.float64).reshape(4, 4)
    scale = max(float(noise_mm) / 1000.0, 0.002)
    for it in range(int(iterations)):
        x = src @ t_est[:3, :3].T + t_est[:3, 3]
        with np.errstate(invalid="ignore", divide="ignore"):
            u = np.rint(camera.fx * x[:, 0] / x[:, 2] + camera.cx)
            v = np.rint(camera.fy * x[:, 1] / x[:, 2] + camera.cy)
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
        if np.abs(step).max() < 1e-7:
            break
    return t_est
