"""Registration by the camera's own motion: reprojection, point-to-plane ICP, the engine."""

from __future__ import annotations

import numpy as np
import pytest

import upsr
from upsr.errors import InputError
from upsr.method.camera_motion import (
    AGREEMENT_PX,
    agreeing,
    along_axis,
    camera_points,
    grid_intrinsics,
    pair_motion,
    pose_maps,
    reproject,
    rigid_motion,
    rotation_from_vector,
    window_poses,
)
from upsr.research.synth.degradation import add_depth_dependent_noise
from upsr.research.synth.realistic import make_realistic

CAM = (50.0, 50.0, 15.5, 11.5)  # fx, fy, cx, cy of 32×24 px frames
SHAPE = (24, 32)


def _pose(tx: float = 0.0, tz: float = 0.0, yaw_deg: float = 0.0) -> np.ndarray:
    a = np.radians(yaw_deg)
    out = np.eye(4)
    out[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    out[:3, 3] = [tx, 0.0, tz]
    return out


def test_the_same_pose_keeps_every_pixel_and_no_depth_gives_nan():
    z = np.full(SHAPE, 2000.0)
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
    z = rng.uniform(800.0, 4000.0, SHAPE)
    a, b = _pose(0.02, 0.1, 3.0), _pose(-0.1, -0.05, -5.0)
    ub, vb, zb = reproject(z, CAM, a, b)
    back = reproject(zb, CAM, b, a, u=ub, v=vb)
    ys, xs = np.mgrid[0:24, 0:32]
    np.testing.assert_allclose(back[0], xs, atol=1e-9)
    np.testing.assert_allclose(back[1], ys, atol=1e-9)
    np.testing.assert_allclose(back[2], z, rtol=1e-12)
    behind = reproject(np.full(SHAPE, 500.0), CAM, None, _pose(tz=-1.0))  # 1 m ahead
    assert np.isnan(behind[0]).all() and np.isnan(behind[2]).all()


def test_bad_coordinates_are_refused():
    z = np.full(SHAPE, 1000.0)
    with pytest.raises(InputError, match="both u and v"):
        reproject(z, CAM, None, None, u=np.zeros(SHAPE))
    with pytest.raises(InputError, match="shape"):
        reproject(z[None], CAM, None, None)
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
    intr = (cam.fx, cam.fy, cam.cx, cam.cy)
    ub, vb, zb = reproject(v.truth[0], intr, v.world_to_camera[0], v.world_to_camera[2])
    xi, yi = np.rint(ub), np.rint(vb)
    inside = (xi >= 0) & (xi < cam.width) & (yi >= 0) & (yi < cam.height)
    seen = v.truth[2][yi[inside].astype(int), xi[inside].astype(int)]
    close = np.abs(seen - zb[inside]) < 0.02 * zb[inside]
    assert close.mean() > 0.9
    assert (np.abs(v.truth[2] - v.truth[0]) < 0.02 * v.truth[0]).mean() < close.mean() - 0.05
    assert make_realistic("gallop", (24, 32), scale=2, n_frames=2).world_to_camera is None


def test_rotation_vectors_follow_rodrigues():
    np.testing.assert_array_equal(rotation_from_vector([0, 0, 0]), np.eye(3))
    r = rotation_from_vector([0.0, 0.0, np.pi / 2])  # a quarter turn about z
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-12)
    w = np.array([0.1, -0.2, 0.3])
    r = rotation_from_vector(w)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(r @ w, w)  # the axis stays


def test_points_are_the_pixels_rays_times_depth():
    z = np.array([[1000.0, 0.0, 2000.0, 1000.0], [1000.0, 1000.0, np.nan, 1000.0]])
    p = camera_points(z, (50.0, 50.0, 1.5, 0.5))
    np.testing.assert_allclose(p[0, 0], [-0.03, -0.01, 1.0])
    np.testing.assert_allclose(p[0, 2], [0.02, -0.02, 2.0])
    assert np.isnan(p[0, 1]).all() and np.isnan(p[1, 2]).all()
    with pytest.raises(InputError, match="shape"):
        camera_points(z[None], (50.0, 50.0, 1.5, 0.5))
    assert grid_intrinsics((50.0, 40.0, 1.5, 0.5), 4) == (200.0, 160.0, 7.5, 3.5)


@pytest.mark.parametrize("sigma", [0.0, 10.0])
def test_a_camera_moving_along_its_axis_is_found(sigma):
    """The approaching camera (25 mm per frame toward a wall with boxes), 64×56 px: the step
    along the axis within 0.5 mm, sideways within 4 mm, the turn within 0.3°, with or without
    noise (the registration that puts the scene's edges where its true motion does,
    benchmarks/registration_oracle.py)."""
    v = make_realistic("toward_wall", (56, 64), scale=2, n_frames=2, seed=0)
    rng = np.random.default_rng(1)
    a, b = (add_depth_dependent_noise(f, sigma, rng, law="laplace") for f in v.lowres)
    intr = (v.camera.fx, v.camera.fy, v.camera.cx, v.camera.cy)
    est = rigid_motion(a, b, intr, noise_mm=max(sigma, 2.0))
    true = v.world_to_camera[1] @ np.linalg.inv(v.world_to_camera[0])
    assert abs(est[2, 3] - true[2, 3]) < 0.0005
    assert np.abs(est[:2, 3] - true[:2, 3]).max() < 0.004
    angle = np.degrees(np.arccos(np.clip((np.trace(est[:3, :3].T @ true[:3, :3]) - 1) / 2, -1, 1)))
    assert angle < 0.3
    np.testing.assert_allclose(rigid_motion(a, a, intr, noise_mm=2.0), np.eye(4), atol=1e-6)


def test_frames_that_share_nothing_are_refused():
    with pytest.raises(InputError, match="pair up"):
        rigid_motion(np.full(SHAPE, 1000.0), np.zeros(SHAPE), CAM)
    with pytest.raises(InputError, match="shapes"):
        rigid_motion(np.full(SHAPE, 1000.0), np.full((24, 30), 1000.0), CAM)


def _step(tx_mm: float = 0.0, tz_mm: float = 0.0, yaw_deg: float = 0.0) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = rotation_from_vector([0.0, np.radians(yaw_deg), 0.0])
    out[:3, 3] = [tx_mm / 1000.0, 0.0, tz_mm / 1000.0]
    return out


def test_only_a_step_along_the_axis_counts():
    """ICP is trusted where the camera moves along its axis (the approaching camera), not
    where it stands still, steps sideways or turns (the room), nor without an estimate."""
    assert along_axis(_step(tz_mm=-25.0))
    assert along_axis(_step(tx_mm=3.0, tz_mm=-25.0, yaw_deg=0.2))
    assert not along_axis(np.eye(4))  # a still camera: the flow
    assert not along_axis(_step(tx_mm=30.0, tz_mm=-10.0))  # the room's sideways step
    assert not along_axis(_step(tz_mm=-25.0, yaw_deg=1.0))  # a turn
    assert not along_axis(None)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_camera_motion_is_taken_only_where_the_flow_agrees(dtype):
    """Within AGREEMENT_PX low-res px of the flow (times the grid's scale) the camera's
    motion, beyond it or where either is NaN the flow; into ``out`` (the flow itself) too."""
    s = 3.0
    flow = np.zeros((2, 3, 2), dtype)
    pose = np.zeros((2, 3, 2), dtype)
    pose[0, 0] = (AGREEMENT_PX * s - 0.01, 0.0)  # just within
    pose[0, 1] = (0.0, AGREEMENT_PX * s + 0.01)  # just beyond
    pose[0, 2] = (np.nan, 0.0)
    pose[1] = (1.0, 1.0)
    flow[1, 2] = (np.nan, 0.0)
    want = flow.copy()
    want[0, 0], want[1, :2] = pose[0, 0], pose[1, :2]
    np.testing.assert_array_equal(agreeing(flow, pose, s), want)
    assert agreeing(flow, pose, s).dtype == dtype
    assert agreeing(flow, pose, s, out=flow) is flow
    np.testing.assert_array_equal(flow, want)
    with pytest.raises(ValueError, match="C-contiguous"):
        agreeing(flow, pose, s, out=np.empty((3, 2, 2), dtype).transpose(1, 0, 2))


def _approaching(seed: int = 0, sigma: float = 10.0):
    v = make_realistic("toward_wall", (56, 64), scale=4, n_frames=9, seed=seed)
    rng = np.random.default_rng(seed)
    low = np.stack([add_depth_dependent_noise(f, sigma, rng, law="laplace") for f in v.lowres])
    return v, low, (v.camera.fx, v.camera.fy, v.camera.cx, v.camera.cy)


def test_the_camera_motion_from_depth_puts_an_approaching_cameras_edges_in_place():
    """A camera moving 25 mm per frame toward a wall with boxes: the flow sees almost none of
    the quarter-pixel zoom per frame, the depth's rigid motion sees it (the true motion's
    figures, benchmarks/registration_oracle.py): edge accuracy up by more than a point, rmse
    down by more than 5 %. The same output with windows finished on two threads."""
    from upsr.research.metrics import evaluate

    v, low, intr = _approaching()
    flow = evaluate(upsr.super_resolve(low, 4, 9), v.truth, 4)
    engine = upsr.UPSR(4, 9, workers=0, camera_motion="depth", camera_intrinsics=intr)
    out = np.stack(list(engine.process(low)))
    depth = evaluate(out, v.truth, 4)
    assert depth["edge_accuracy"] > flow["edge_accuracy"] + 0.01
    assert depth["rmse"] < 0.95 * flow["rmse"]
    assert depth["flying_pixels"] <= flow["flying_pixels"] + 1e-4
    assert depth["missing"] <= flow["missing"] + 1e-4
    threads = upsr.super_resolve(low, 4, 9, workers=2, camera_motion="depth",
                                 camera_intrinsics=intr)  # fmt: skip
    np.testing.assert_array_equal(threads, out)


def test_the_recursive_state_follows_an_approaching_camera():
    """The recursive mode registers its state by the camera's motion frame by frame: on the
    approaching camera at Gauss σ = 20 mm (16 frames, the last 8 scored) its rmse and edge
    accuracy are no worse than the flow's, its surface rmse within 0.5 % (8.546 against 8.543
    mm since the final smoothing follows each surface's plane; 9.49 against 9.51; 9.59 against
    10.09 before the flows were estimated on frames brought back by the scene's depth drift,
    MotionFrontEnd.depth_drift_mm, which the flow had taken in part for motion along the
    floor's slope; 9.88 against 10.78 before the flow path's innovation caps took slopes from
    1σ)."""
    from upsr.research.metrics import evaluate
    from upsr.research.synth.realistic import degrade

    v = make_realistic("toward_wall", (56, 64), scale=4, n_frames=16, seed=0)
    intr = (v.camera.fx, v.camera.fy, v.camera.cx, v.camera.cy)
    low = degrade(v, "gaussian", np.random.default_rng(0), sigma_mm=20.0)
    flow = evaluate(upsr.super_resolve(low, 4, 9, mode="recursive")[8:], v.truth[8:], 4)
    depth = evaluate(
        upsr.super_resolve(low, 4, 9, mode="recursive", camera_motion="depth",
                           camera_intrinsics=intr)[8:], v.truth[8:], 4,
    )  # fmt: skip
    assert depth["surface_rmse"] <= 1.005 * flow["surface_rmse"]
    assert depth["rmse"] <= flow["rmse"]
    assert depth["edge_accuracy"] >= flow["edge_accuracy"]
    assert depth["flying_pixels"] <= flow["flying_pixels"] + 1e-4


@pytest.mark.parametrize("mode", ["windowed", "recursive"])
def test_a_still_camera_or_a_sideways_one_keeps_the_flow(mode):
    """Bodies moving before a still camera, and a room seen by a camera stepping sideways and
    turning: the camera's motion is not along its axis; a ToF camera approaching the wall:
    its mixed pixels move with the edges' sub-pixel motion. The output is the flow's exactly,
    in both modes."""
    from upsr.research.synth.realistic import degrade

    for scene, sensor in (("gallop", "laplace"), ("room", "laplace"), ("toward_wall", "tof")):
        v = make_realistic(scene, (56, 64), scale=4, n_frames=9, seed=0)
        intr = (v.camera.fx, v.camera.fy, v.camera.cx, v.camera.cy)
        low = degrade(v, sensor, np.random.default_rng(0), sigma_mm=10.0)
        np.testing.assert_array_equal(
            upsr.super_resolve(low, 4, 9, mode=mode, camera_motion="depth",
                               camera_intrinsics=intr),
            upsr.super_resolve(low, 4, 9, mode=mode),
        )  # fmt: skip


def test_a_static_camera_is_registered_as_still():
    """Two identical frames: the camera did not move, every map is zero; frames that share
    nothing give no motion at all."""
    z = np.full(SHAPE, 2000.0)
    z[8:16, 10:20] = 1500.0
    step = pair_motion(z, z, CAM, noise_mm=5.0, edge_mm=100.0)
    np.testing.assert_allclose(step, np.eye(4), atol=1e-9)
    poses = window_poses(range(3), lambda k: step)
    maps = pose_maps(z, CAM, poses, 1, np.empty((3, *SHAPE, 2), np.float32))
    np.testing.assert_allclose(maps, 0.0, atol=1e-6)
    assert pair_motion(z, np.zeros(SHAPE), CAM, noise_mm=5.0, edge_mm=100.0) is None


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"camera_motion": "depth"}, "needs camera_intrinsics"),
        ({"camera_motion": "imu"}, "'flow' or 'depth'"),
        ({"camera_intrinsics": (50.0, 50.0)}, r"\(fx, fy, cx, cy\)"),
        ({"camera_intrinsics": (0.0, 50.0, 1.0, 1.0)}, "fx, fy > 0"),
        ({"camera_intrinsics": (50.0, np.nan, 1.0, 1.0)}, "finite"),
    ],
)
def test_bad_camera_motion_options_are_refused(options, match):
    with pytest.raises(InputError, match=match):
        upsr.UPSRConfig.from_options(2, 3, **options)
