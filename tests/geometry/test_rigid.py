"""The rigid motion of a camera between two depth frames (point-to-plane ICP)."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.rigid import camera_points, rigid_motion, rotation_from_vector
from upsr.research.synth.degradation import add_depth_dependent_noise
from upsr.research.synth.realistic import make_realistic


def test_rotation_vectors_follow_rodrigues():
    np.testing.assert_array_equal(rotation_from_vector([0, 0, 0]), np.eye(3))
    r = rotation_from_vector([0.0, 0.0, np.pi / 2])  # a quarter turn about z
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-12)
    w = np.array([0.1, -0.2, 0.3])
    r = rotation_from_vector(w)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(r @ w, w)  # the axis stays


def test_points_are_the_pixels_rays_times_depth():
    cam = PinholeCamera(50.0, 50.0, 1.5, 0.5, 4, 2)
    z = np.array([[1000.0, 0.0, 2000.0, 1000.0], [1000.0, 1000.0, np.nan, 1000.0]])
    p = camera_points(z, cam)
    np.testing.assert_allclose(p[0, 0], [-0.03, -0.01, 1.0])
    np.testing.assert_allclose(p[0, 2], [0.02, -0.02, 2.0])
    assert np.isnan(p[0, 1]).all() and np.isnan(p[1, 2]).all()
    with pytest.raises(InputError, match="shape"):
        camera_points(z[:, :3], cam)


@pytest.mark.parametrize("sigma", [0.0, 10.0])
def test_a_camera_moving_along_its_axis_is_found(sigma):
    """The approaching camera (25 mm per frame toward a wall with boxes), 64×56 px: the step
    along the axis within 0.5 mm, sideways within 4 mm, the turn within 0.3°, with or without
    noise (the registration that puts the scene's edges where its true motion does,
    benchmarks/registration_oracle.py)."""
    v = make_realistic("toward_wall", (56, 64), scale=2, n_frames=2, seed=0)
    rng = np.random.default_rng(1)
    a, b = (add_depth_dependent_noise(f, sigma, rng, law="laplace") for f in v.lowres)
    est = rigid_motion(a, b, v.camera, noise_mm=max(sigma, 2.0))
    true = v.world_to_camera[1] @ np.linalg.inv(v.world_to_camera[0])
    assert abs(est[2, 3] - true[2, 3]) < 0.0005
    assert np.abs(est[:2, 3] - true[:2, 3]).max() < 0.004
    angle = np.degrees(np.arccos(np.clip((np.trace(est[:3, :3].T @ true[:3, :3]) - 1) / 2, -1, 1)))
    assert angle < 0.3
    np.testing.assert_allclose(rigid_motion(a, a, v.camera, noise_mm=2.0), np.eye(4), atol=1e-6)


def test_frames_that_share_nothing_are_refused():
    cam = PinholeCamera(50.0, 50.0, 15.5, 11.5, 32, 24)
    empty = np.zeros(cam.shape)
    with pytest.raises(InputError, match="pair up"):
        rigid_motion(np.full(cam.shape, 1000.0), empty, cam)
