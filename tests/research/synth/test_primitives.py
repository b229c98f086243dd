"""Triangle-mesh primitives of the evaluation scenes (upsr.research.synth.primitives)."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.geometry.camera import PinholeCamera
from upsr.geometry.rendering import render_depth
from upsr.research.synth.primitives import box, cylinder, ellipsoid, merge


def _closed(faces: np.ndarray) -> bool:
    """Every edge of a closed triangle mesh belongs to exactly two faces."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool((counts == 2).all())


@pytest.mark.parametrize(
    "mesh",
    [
        box((0, 0, 2), (0.1, 0.2, 0.3)),
        cylinder((0, 0, 2), (0, 0.5, 2), 0.05, n=8),
        ellipsoid((0, 0, 2), (0.2, 0.1, 0.3)),
    ],
)
def test_primitives_are_closed_meshes(mesh):
    verts, faces = mesh
    assert verts.shape[1] == 3 and faces.dtype == np.int64
    assert faces.min() >= 0 and faces.max() < len(verts)
    assert _closed(faces)


def test_a_box_renders_at_its_front_face_and_merge_keeps_every_part():
    cam = PinholeCamera.from_fov(32, 24, 60.0)
    a = box((0.0, 0.0, 2.0), (0.2, 0.2, 0.1))
    b = ellipsoid((0.0, 0.0, 3.0), (0.3, 0.3, 0.3))
    verts, faces = merge([a, b])
    assert len(verts) == len(a[0]) + len(b[0]) and len(faces) == len(a[1]) + len(b[1])
    depth = render_depth(verts, faces, cam)
    assert depth[12, 16] == pytest.approx(1900.0, abs=1.0)  # the box's front, in mm
    assert merge([])[0].shape == (0, 3)
