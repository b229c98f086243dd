"""Evaluation scenes of real cameras: shapes, determinism, moving masks, motion sizes."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.research.synth import realistic
from upsr.research.synth.realistic import degrade, make_realistic

SMALL = (24, 32)


@pytest.mark.parametrize("name", [*realistic.SCENES, "gallop_none"])
def test_scenes_render_with_consistent_shapes_and_seeds(name):
    v = make_realistic(name, SMALL, scale=2, n_frames=4, seed=3)
    assert v.lowres.shape == (4, *SMALL) and v.lowres.dtype == np.float32
    assert v.truth.shape == (4, 48, 64) and v.moving.shape == v.truth.shape
    assert v.moving.dtype == bool and not (v.moving & (v.truth == 0)).any()
    assert v.camera.shape == SMALL
    again = make_realistic(name, SMALL, scale=2, n_frames=4, seed=3)
    np.testing.assert_array_equal(v.truth, again.truth)
    # low-res frames are point samples of the same scene: they match the truth at the
    # high-res pixels nearest to the low-res centres on flat parts (most pixels)
    assert (
        np.mean(np.abs(v.lowres - v.truth[:, 1::2, 1::2]) < 0.03 * v.truth[:, 1::2, 1::2] + 20)
        > 0.8
    )


def test_static_camera_masks_are_the_moving_bodies():
    v = make_realistic("gallop", SMALL, scale=2, n_frames=3)
    wall = 3000.0
    assert v.static_camera
    np.testing.assert_allclose(v.truth[~v.moving], wall)  # everything else is the wall
    assert (v.truth[v.moving] < wall - 500).all()
    assert 0.03 < v.moving.mean() < 0.4
    none = make_realistic("gallop_none", SMALL, scale=2, n_frames=3)
    np.testing.assert_array_equal(none.moving, none.truth > 0)  # no wall: body only
    d = make_realistic("deforming", SMALL, scale=2, n_frames=3)
    np.testing.assert_allclose(d.truth[~d.moving], 2800.0)
    assert not np.array_equal(d.moving[0], d.moving[1])


def test_moving_camera_masks_cover_everything_and_room_is_dense():
    room = make_realistic("room", SMALL, scale=2, n_frames=3)
    assert not room.static_camera
    assert (room.truth > 0).all() and room.moving.all()
    assert room.truth.max() - room.truth.min() > 1000  # several planes at different depths


def test_camera_toward_wall_moves_25mm_per_frame():
    v = make_realistic("toward_wall", SMALL, scale=2, n_frames=4)
    for t in range(4):
        vals, counts = np.unique(v.truth[t], return_counts=True)
        assert vals[np.argmax(counts)] == pytest.approx(2500.0 - 25.0 * t)  # the bare wall
    assert (v.truth < 2500.0 - 60).any()  # boxes stand out of the wall


def test_thin_legs_and_fast_feet():
    v = realistic.galloping_animal((56, 64), scale=1, n_frames=7, background="none")
    # a row through the legs (below the body): foreground runs 1–2 low-res px wide
    row = v.truth[0, 38] > 0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], row.astype(int), [0]])))
    widths = edges[1::2] - edges[::2]
    assert len(widths) >= 2 and widths.max() <= 3
    # the feet move by up to 5 px between frames (the body by 1 px)
    assert 4.0 <= v.max_motion_px <= 5.5


def test_deforming_head_moves_20_to_30_px_per_frame():
    v = realistic.deforming_body((56, 64), scale=1, n_frames=6, head_speed_px=25.0)
    assert 20.0 <= v.max_motion_px <= 30.0
    # the head's top rows move by about as much in the image
    tops = []
    for t in range(6):
        rows = np.flatnonzero((v.truth[t] < 2000).any(1))
        tops.append(np.flatnonzero((v.truth[t, rows[0] : rows[0] + 3] < 2000).any(0)).mean())
    assert 15 <= np.abs(np.diff(tops)).max() <= 30


def test_fan_blades_are_thin_and_fast_and_the_ball_comes_nearer():
    v = realistic.spinning_fan((56, 64), scale=1, n_frames=5, tip_speed_px=6.0, seed=2)
    assert v.static_camera and v.name == "fan"
    assert 5.0 <= v.max_motion_px <= 7.0  # the blade tips (the ball drifts 1.5 px at most)
    # the ball: the nearest surface in the right part of the image, 50 mm nearer per frame
    ball = v.truth[:, 25:40, 40:]  # (the box stands below it)
    nearest = np.array([f[f > 0].min() for f in ball])
    np.testing.assert_allclose(np.diff(nearest), -50.0, atol=3.0)
    # three blades 1-3 px wide: about 3 × 18.5 px long, a few dozen pixels in all
    fan = v.moving[0] & (v.truth[0] < 1800.0)
    assert 40 <= fan.sum() <= 3 * 18.5 * 3
    # the box: its top meets its front at a crease, with no depth edge between them
    col = v.truth[0, 40:, 32]  # the lower part of the middle column: wall, then the box
    steps = np.abs(np.diff(col[col < 2600.0]))
    assert steps.max() < 200.0 and len(steps) >= 3


def test_camera_motion_sizes():
    wall = make_realistic("toward_wall", (56, 64), scale=1, n_frames=3)
    # an image corner ≈ 40 px from the centre moves outwards by ≈ 40·25/2450 ≈ 0.4 px
    assert 0.2 < wall.max_motion_px < 1.0
    assert make_realistic("room", (56, 64), scale=1, n_frames=3).max_motion_px > 0.5


@pytest.mark.parametrize("sensor", realistic.SENSORS)
def test_degrade_every_sensor(sensor):
    v = make_realistic("gallop", SMALL, scale=2, n_frames=2)
    low = degrade(v, sensor, np.random.default_rng(0), sigma_mm=10.0)
    assert low.shape == v.lowres.shape and low.dtype == np.float32
    if sensor == "clean":
        np.testing.assert_array_equal(low, v.lowres)
    if sensor == "tof":  # the footprint mean of the truth at the body's edges: mixed pixels
        block = v.truth.reshape(2, 24, 2, 32, 2).mean(axis=(2, 4))
        assert np.abs(low - block).mean() < 15
    if sensor == "kinect":
        assert 0.005 < (low == 0).mean() < 0.2


@pytest.mark.parametrize("sensor", ["laplace", "gaussian", "tof"])
def test_degrade_drops_the_share_of_pixels_asked_for(sensor):
    v = make_realistic("room", SMALL, scale=2, n_frames=4)
    kept = degrade(v, sensor, np.random.default_rng(0), sigma_mm=10.0)
    low = degrade(v, sensor, np.random.default_rng(0), sigma_mm=10.0, dropout_fraction=0.05)
    lost = (kept > 0) & (low == 0)
    assert 0.03 < lost.mean() < 0.07
    np.testing.assert_array_equal(low[~lost], kept[~lost])  # the same noise, then the losses
    with pytest.raises(InputError):
        degrade(v, sensor, np.random.default_rng(0), dropout_fraction=1.5)


def test_unknown_scene_and_sensor():
    with pytest.raises(InputError):
        make_realistic("castle", SMALL)
    with pytest.raises(InputError):
        degrade(
            make_realistic("room", SMALL, n_frames=1, scale=1), "lidar", np.random.default_rng(0)
        )


def test_the_gaussian_tof_sensor_mixes_like_the_tof_sensor_with_gaussian_noise():
    from upsr.research.synth.degradation import tof_footprint
    from upsr.research.synth.realistic import degrade, make_realistic

    video = make_realistic("room", (28, 32), scale=4, n_frames=3)
    rng = np.random.default_rng(0)
    low = degrade(video, "tof_gaussian", rng, sigma_mm=10.0)
    clean = tof_footprint(video.truth, 4)
    np.testing.assert_array_equal(low > 0, clean > 0)
    noise = (low - clean)[clean > 0]
    assert abs(noise.std() - 10.0) < 1.0
    # Gaussian, not Laplacian: excess kurtosis near 0 (Laplace: 3)
    assert abs(np.mean(noise**4) / noise.var() ** 2 - 3.0) < 0.5
