"""Reprojection of depth between two views of a rigid scene."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.reprojection import reproject
from upsr.research.synth.realistic import make_realistic

CAM = PinholeCamera(50.0, 50.0, 15.5, 11.5, 32, 24)


def _pose(tx: float = 0.0, tz: float = 0.0, yaw_deg: float = 0.0) -> np.ndarray:
    a = np.radians(yaw_deg)
    out = np.eye(4)
    out[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    out[:3, 3] = [tx, 0.0, tz]
    return out


def test_the_same_pose_keeps_every_pixel_and_no_depth_gives_nan():
    z = np.full(CAM.shape, 2000.0)
    z[0, 0], z[0, 1] = 0.0, np.nan
    ub, vb, zb = reproject(z, CAM, _pose(0.1), _pose(0.1))
    ys, xs = np.mgrid[0:24, 0:32]
    ok = z > 0
    np.testing.assert_allclose(ub[ok], xs[ok], atol=1e-9)
    np.testing.assert_allclose(vb[ok], ys[ok], atol=1e-9)
    np.testing.assert_allclose(zb[ok], 2000.0)
    assert np.isnan(ub[0, :2]).all() and np.isnan(zb[0, :2]).all()


def test_a_sideways_step_moves_near_points_more_than_far_ones():
    """Camera 50 mm to the right (world x −50 mm in its frame): a point at Z moves by
    fx·0.05 m / Z to the left, 2.5 px at 1 m and 1 px at 2.5 m."""
    z = np.where(np.arange(32)[None, :] < 16, 1000.0, 2500.0) * np.ones((24, 1))
    ub, vb, zb = reproject(z, CAM, None, _pose(tx=-0.05))
    xs = np.arange(32)[None, :] * np.ones((24, 1))
    np.testing.assert_allclose((ub - xs)[:, :16], -2.5)
    np.testing.assert_allclose((ub - xs)[:, 16:], -1.0)
    np.testing.assert_allclose(vb, np.mgrid[0:24, 0:32][0], atol=1e-9)
    np.testing.assert_allclose(zb, z)


def test_there_and_back_again_and_points_behind_the_camera():
    rng = np.random.default_rng(0)
    z = rng.uniform(800.0, 4000.0, CAM.shape)
    a, b = _pose(0.02, 0.1, 3.0), _pose(-0.1, -0.05, -5.0)
    ub, vb, zb = reproject(z, CAM, a, b)
    back = reproject(zb, CAM, b, a, u=ub, v=vb)
    ys, xs = np.mgrid[0:24, 0:32]
    np.testing.assert_allclose(back[0], xs, atol=1e-9)
    np.testing.assert_allclose(back[1], ys, atol=1e-9)
    np.testing.assert_allclose(back[2], z, rtol=1e-12)
    behind = reproject(np.full(CAM.shape, 500.0), CAM, None, _pose(tz=-1.0))  # 1 m ahead
    assert np.isnan(behind[0]).all() and np.isnan(behind[2]).all()


def test_bad_coordinates_are_refused():
    z = np.full(CAM.shape, 1000.0)
    with pytest.raises(InputError, match="both u and v"):
        reproject(z, CAM, None, None, u=np.zeros(CAM.shape))
    with pytest.raises(InputError, match="shape"):
        reproject(z[:-1], CAM, None, None)
    with pytest.raises(InputError, match="shape"):
        reproject(z, CAM, None, None, u=np.zeros((2, 2)), v=np.zeros((2, 2)))


@pytest.mark.parametrize("scene", ["room", "toward_wall"])
def test_a_moving_cameras_poses_carry_one_frames_truth_onto_the_next(scene):
    """The scenes' poses are the true motion: frame 0's truth carried into frame 2 lands on
    frame 2's truth (the pixels not hidden there and inside it), which a static camera's
    would not."""
    v = make_realistic(scene, (24, 32), scale=2, n_frames=3, seed=1)
    assert v.world_to_camera is not None and v.world_to_camera.shape == (3, 4, 4)
    cam = v.camera.scaled(2)
    ub, vb, zb = reproject(v.truth[0], cam, v.world_to_camera[0], v.world_to_camera[2])
    xi, yi = np.rint(ub), np.rint(vb)
    inside = (xi >= 0) & (xi < cam.width) & (yi >= 0) & (yi < cam.height)
    seen = v.truth[2][yi[inside].astype(int), xi[inside].astype(int)]
    close = np.abs(seen - zb[inside]) < 0.02 * zb[inside]
    assert close.mean() > 0.9
    assert (np.abs(v.truth[2] - v.truth[0]) < 0.02 * v.truth[0]).mean() < close.mean() - 0.05
    assert make_realistic("gallop", (24, 32), scale=2, n_frames=2).world_to_camera is None
