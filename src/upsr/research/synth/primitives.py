"""Triangle-mesh primitives for the evaluation scenes: boxes, capped cylinders, ellipsoids.

Metres, in the camera frame of the scene's first frame (x right, y down, z forward). A mesh is
a pair ``(vertices (V, 3) float, faces (F, 3) int64)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

__all__ = ["Mesh", "box", "cylinder", "ellipsoid", "merge"]

Mesh = tuple[np.ndarray, np.ndarray]


def merge(parts: Sequence[Mesh]) -> Mesh:
    verts, faces, base = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces.append(f + base)
        base += len(v)
    if not verts:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    return np.concatenate(verts), np.concatenate(faces)


def box(centre: npt.ArrayLike, half: npt.ArrayLike) -> Mesh:
    """Axis-aligned box (12 triangles)."""
    c, hs = np.asarray(centre, float), np.asarray(half, float)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = [(a, b, c_) for a, b, c_, _ in quads] + [(a, c_, d) for a, _, c_, d in quads]
    return c + corners * hs, np.array(faces, np.int64)


def cylinder(p0: npt.ArrayLike, p1: npt.ArrayLike, radius: float, n: int = 10) -> Mesh:
    """Capped cylinder (an n-gon prism) from p0 to p1."""
    a, b = np.asarray(p0, float), np.asarray(p1, float)
    axis = b - a
    length = np.linalg.norm(axis)
    axis = axis / length if length > 0 else np.array([0.0, 1.0, 0.0])
    helper = np.array([0.0, 0.0, 1.0]) if abs(axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    ang = 2 * np.pi * np.arange(n) / n
    ring = radius * (np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * v)
    verts = np.concatenate([a + ring, b + ring, [a, b]])
    k = np.arange(n)
    k1 = (k + 1) % n
    faces = np.concatenate(
        [
            np.stack([k, k1, n + k], 1),
            np.stack([k1, n + k1, n + k], 1),
            np.stack([np.full(n, 2 * n), k1, k], 1),
            np.stack([np.full(n, 2 * n + 1), n + k, n + k1], 1),
        ]
    )
    return verts, faces.astype(np.int64)


def ellipsoid(
    centre: npt.ArrayLike, radii: npt.ArrayLike, n_lat: int = 12, n_lon: int = 24
) -> Mesh:
    """UV ellipsoid."""
    c, rad = np.asarray(centre, float), np.asarray(radii, float)
    th = np.linspace(0, np.pi, n_lat + 1)[1:-1]
    ph = 2 * np.pi * np.arange(n_lon) / n_lon
    ring = np.stack(
        [
            np.sin(th)[:, None] * np.cos(ph)[None, :],
            -np.cos(th)[:, None] * np.ones_like(ph)[None, :],
            np.sin(th)[:, None] * np.sin(ph)[None, :],
        ],
        -1,
    ).reshape(-1, 3)
    verts = np.concatenate([ring, [[0, -1, 0], [0, 1, 0]]]) * rad + c
    top, bottom = len(ring), len(ring) + 1
    faces = []
    for i in range(n_lat - 2):
        for j in range(n_lon):
            a, b = i * n_lon + j, i * n_lon + (j + 1) % n_lon
            faces += [(a, b, a + n_lon), (b, b + n_lon, a + n_lon)]
    for j in range(n_lon):
        j1 = (j + 1) % n_lon
        last = (n_lat - 2) * n_lon
        faces += [(top, j1, j), (bottom, last + j, last + j1)]
    return verts, np.array(faces, np.int64)
