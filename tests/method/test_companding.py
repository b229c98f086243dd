"""Depth quantised in disparity, companded beyond a knee (upsr.method.companding)."""

import math

import numpy as np
import pytest

import upsr
from upsr.errors import InputError
from upsr.method.companding import KNEE_STEPS, compand, expand, knee_mm, level_spacing
from upsr.method.config import UPSRConfig
from upsr.method.frontend import MotionFrontEnd
from upsr.method.statistics import (
    fix_video_statistics,
    pinned_config,
    video_knee_mm,
    video_level_spacing,
)
from upsr.research.synth.degradation import kinect
from upsr.research.synth.realistic import degrade, make_realistic

#: A Kinect's level step per mm²: 1/8 px of disparity at f·b = 580 px · 75 mm.
KINECT_ALPHA = 1.0 / (8 * 580.0 * 75.0)


def _kinect_wall(z_mm: float, shape=(9, 30, 40), seed: int = 0) -> np.ndarray:
    """A static fronto-parallel wall through the Kinect model, whole mm as the camera gives."""
    clean = np.full(shape, z_mm)
    return np.round(kinect(clean, np.random.default_rng(seed), dropout_fraction=0.0))


def _surface_rmse(est: np.ndarray, z_mm: float) -> float:
    return float(np.sqrt(np.mean((est[:, 4:-4, 4:-4] - z_mm) ** 2)))


@pytest.mark.parametrize("z_mm", [4000.0, 7000.0, 9000.0])
def test_a_kinect_frames_level_step_is_found(z_mm):
    alpha = level_spacing(_kinect_wall(z_mm)[0])
    assert alpha == pytest.approx(KINECT_ALPHA, rel=0.05)


def _stereo(z_mm, focal_px: float, baseline_mm: float, step_px: float, steps: float = 0.0):
    """A stereo camera's whole-mm depth of ``z_mm``: noise of the Kinect model (or of
    ``steps`` level steps), disparity quantised in steps of ``step_px``."""
    from upsr.research.synth.degradation import kinect_axial_sigma_mm, quantise_disparity

    level = step_px / (focal_px * baseline_mm) * z_mm**2
    sigma = steps * level if steps else kinect_axial_sigma_mm(z_mm)
    noisy = z_mm + np.random.default_rng(0).normal(0, 1, z_mm.shape) * sigma
    q = quantise_disparity(noisy, focal_px=focal_px, baseline_mm=baseline_mm, step_px=step_px)
    return np.round(q)


@pytest.mark.parametrize(
    ("camera", "near_share"),
    [
        ((385.0, 50.0, 1 / 32, 0.0), 0.3),
        ((580.0, 75.0, 1 / 8, 0.0), 0.6),
        ((440.0, 75.0, 1.0, 0.6), 0.0),
    ],
)
def test_stereo_levels_are_found_beside_near_whole_mm_depth(camera, near_share):
    """A D435 (1/32 px) and a Kinect with part of the frame at 0.6 m, where whole mm round the
    levels (1-2 mm steps), and an integer-disparity stereo camera (α = 3e-5 / mm, its noise
    0.6 level steps)."""
    f, b, step, steps = camera
    alpha = step / (f * b)
    z = np.full((60, 80), 1.3 * math.sqrt(100.0 / (KNEE_STEPS * alpha)))
    z[:, : int(near_share * 80)] = 600.0
    assert level_spacing(_stereo(z, f, b, step, steps)) == pytest.approx(alpha, rel=0.1)


def test_continuous_clean_and_whole_mm_depth_has_no_levels():
    rng = np.random.default_rng(1)
    wall = np.full((30, 40), 3000.0)
    assert level_spacing(wall + rng.laplace(0, 10, wall.shape)) is None  # ToF-like
    # whole mm with 10 mm of noise over 2-4 m: steps of 1 mm, not α·z²
    ramp = np.linspace(2000, 4000, 40)[None, :] + rng.normal(0, 10, wall.shape)
    assert knee_mm(np.round(ramp), 100.0) == math.inf
    # a clean render of a few surfaces: no noise dithers them over levels
    planes = np.repeat([1500.0, 2500.0, 4000.0, 7000.0, 9000.0], 8)[None, :] * np.ones((30, 1))
    assert level_spacing(planes) is None
    assert level_spacing(np.zeros((30, 40))) is None
    # a clean plane slanted along the rows: its columns step by α·z² exactly (1/z affine)
    plane = np.ones((30, 1)) / np.linspace(1 / 3000, 1 / 9000, 64)[None, :]
    assert level_spacing(plane) is None and level_spacing(np.round(plane)) is None
    # a whole-mm ramp with little noise: steps alike at every depth, not growing as z²
    ramp = 2000.0 * (1 + 0.5 * np.arange(160)[None, :] / 160) + rng.normal(0, 0.3, (120, 160))
    assert level_spacing(np.round(ramp)) is None
    # whole mm of Laplacian noise on walls 1-15 m: the steps beyond 2 mm are the tails'
    for z0 in (1000.0, 2000.0, 4000.0, 15000.0):
        assert level_spacing(np.round(z0 + rng.laplace(0, 10, (120, 160)))) is None


def test_the_knee_is_where_a_level_step_reaches_the_edge_threshold():
    knee = knee_mm(_kinect_wall(7000.0)[0], 100.0)
    expected = math.sqrt(100.0 / (KNEE_STEPS * KINECT_ALPHA))  # 5.76 m
    assert knee == pytest.approx(expected, rel=0.03)
    assert 5500 < knee < 6000
    # a near wall has the same knee (a camera may turn to a far one) and nothing beyond it
    near = _kinect_wall(3000.0)
    assert knee_mm(near[0], 100.0) == pytest.approx(knee, rel=0.05)
    np.testing.assert_array_equal(
        upsr.super_resolve(near, 2, 3), upsr.super_resolve(near, 2, 3, compand_knee_mm=None)
    )


def test_compand_and_expand_are_inverse_and_keep_the_depth_below_the_knee():
    z = np.array([0.0, 500.0, 3000.0, 5000.0, 5000.5, 7000.0, 12000.0, 65535.0], np.float32)
    u = compand(z, 5000.0)
    assert u.dtype == np.float32
    np.testing.assert_array_equal(u[:5], z[:5])  # 0 stays 0, the near depth as it is
    assert np.all(np.diff(u) > 0) and u[-1] < 10000.0
    np.testing.assert_allclose(expand(u, 5000.0), z, rtol=1e-5)
    # a level step α·z² beyond the knee is one u-step everywhere
    alpha = 100.0 / (KNEE_STEPS * 5000.0**2)
    for depth in (6000.0, 9000.0, 14000.0):
        step = alpha * depth**2
        lo, hi = compand(np.array([depth, depth + step]), 5000.0)
        # α·k² to first order in the step (exactly α·k²·z / (z + step))
        assert hi - lo == pytest.approx(alpha * 5000.0**2 * depth / (depth + step), rel=1e-4)
    # beyond the companded range (a deblurring overshoot) the depth is capped, never < 0
    assert 0 < expand(np.array([9999.9, 20000.0], np.float32), 5000.0).max() <= 1e6
    assert expand(np.float32([2 * 5759.0]), 5759.0)[0] == 1e6  # (not 1e6 + float32 error)
    same = np.array([1.0, 2.0], np.float32)
    assert compand(same, math.inf) is same and expand(same, math.inf) is same


def _knee(frames, cfg):
    """The engines' knee: from the video's level spacing, then the config."""
    return video_knee_mm(frames, cfg, video_level_spacing(frames))


def test_a_near_scenes_knee_follows_its_scaled_edge_step():
    """62 % of the frame at 0.7 m: the edge step is scaled by the median depth (0.7), and the
    knee with it, so that a far level step is one surface for the scaled step too; the scale
    is that of all the frames given (the windowed engine's first N, as its thresholds')."""
    z = np.full((60, 80), 7500.0)
    z[:, :50] = 700.0
    frame = _stereo(z, 580.0, 75.0, 1 / 8)
    knee = _knee(frame[None], UPSRConfig(scale=2))
    assert knee == pytest.approx(math.sqrt(0.7 * 100.0 / (KNEE_STEPS * KINECT_ALPHA)), rel=0.05)
    given = _knee(frame[None], UPSRConfig(scale=2, near_depth_mm=None))  # (--edge-mm)
    assert given == pytest.approx(math.sqrt(100.0 / (KNEE_STEPS * KINECT_ALPHA)), rel=0.05)
    # a first frame all far, then the camera turns to the near scene: the frames' scale
    far = _stereo(np.full((60, 80), 7500.0), 580.0, 75.0, 1 / 8)
    turned = _knee(np.stack([far] + [frame] * 8), UPSRConfig(scale=2))
    assert turned == pytest.approx(knee, rel=0.05)


def test_the_video_knee_waits_for_depth_and_follows_the_config():
    wall = _kinect_wall(7000.0)[:3]
    cfg = UPSRConfig(scale=2)
    assert 5500 < _knee(wall, cfg) < 6000
    empty = np.zeros_like(wall)
    assert _knee(np.concatenate([empty, wall]), cfg) == _knee(wall, cfg)
    assert _knee(empty, cfg) == math.inf
    assert video_level_spacing(empty) is None
    assert video_level_spacing(np.concatenate([empty, wall])) == video_level_spacing(wall)
    assert video_level_spacing(wall).alpha > 0
    assert _knee(empty, UPSRConfig(scale=2, compand_knee_mm=4000.0)) == 4000.0
    assert _knee(wall, UPSRConfig(scale=2, compand_knee_mm=None)) == math.inf
    depth_motion = UPSRConfig(scale=2, camera_motion="depth", camera_intrinsics=(50, 50, 20, 15))
    assert _knee(wall, depth_motion) == math.inf


@pytest.mark.parametrize("bad", ["on", -5.0, 0.0, math.nan, True])
def test_a_bad_knee_is_refused(bad):
    with pytest.raises(InputError, match="compand_knee_mm"):
        UPSRConfig(scale=2, compand_knee_mm=bad)


@pytest.mark.parametrize("mode", ["windowed", "recursive"])
def test_a_far_kinect_wall_is_one_surface_not_a_staircase_of_levels(mode):
    """A static wall at 7 m, whose disparity levels lie 141 mm apart (over the 100 mm edge
    threshold): better than the temporal mean of the raw frames (31 mm), where without the
    companding its levels stayed surfaces of their own (24 mm windowed, 740 recursive, whose
    state restarts at every level change: missing depth counts here)."""
    z = 7000.0
    low = _kinect_wall(z, shape=(9, 24, 32))
    mean = low.mean(axis=0)
    reference = _surface_rmse(np.repeat(np.repeat(mean[None], 2, 1), 2, 2), z)
    est = upsr.super_resolve(low.astype(np.uint16), 2, 9, mode=mode)
    off = upsr.super_resolve(low.astype(np.uint16), 2, 9, mode=mode, compand_knee_mm=None)
    assert _surface_rmse(est, z) <= 0.5 * min(reference, _surface_rmse(off, z))
    assert np.all(est[:, 4:-4, 4:-4] > 0)


def test_continuous_depth_is_not_companded():
    video = make_realistic("room", (28, 32), scale=2, n_frames=9, seed=0)
    low = degrade(video, "laplace", np.random.default_rng(0), sigma_mm=10.0)
    for mode in ("windowed", "recursive"):
        engine = upsr.UPSR(2, 9, mode=mode)
        out = np.stack(list(engine.process(low)))
        assert engine.statistics.knee_mm == math.inf
        same = upsr.super_resolve(low, 2, 9, mode=mode, compand_knee_mm=None)
        np.testing.assert_array_equal(out, same)


def test_the_statistics_report_and_pin_the_knee_and_judge_mixes_on_measured_depth():
    low = _kinect_wall(7000.0)
    cfg = UPSRConfig(scale=2, n_frames=3)
    pinned = pinned_config(low[:3], cfg)
    knee = pinned.compand_knee_mm
    assert 5500 < knee < 6000
    front = MotionFrontEnd(cfg, low.shape[-1])
    stats = fix_video_statistics(front, low[:3], cfg, knee)
    assert stats.knee_mm == knee and not stats.remove_mixed
    # a later chunk run with the pinned config gives what the whole run gives
    whole = upsr.super_resolve(low.astype(np.uint16), 2, config=cfg)
    chunk = upsr.super_resolve(low[3:].astype(np.uint16), 2, config=pinned)
    np.testing.assert_array_equal(chunk[1:-1], whole[4:-1])
    engine = upsr.UPSR(2, 9, mode="recursive")
    list(engine.process(low))
    assert engine.statistics.knee_mm == pytest.approx(knee)
    assert pinned_config(np.full_like(low, 2000.0), cfg).compand_knee_mm is None


def test_a_clean_render_of_thin_legs_and_their_mixes_has_no_levels():
    """Legs and their ToF mixes on a wall, noise-free: five depths 150-600 mm apart that step
    like a coarse camera's levels (α = 7.9e-5 / mm, 11 % of the neighbours differ)."""
    from tests.method.test_thin import R, _gap
    from upsr.research.synth.degradation import tof_footprint

    low = tof_footprint(_gap(), R)
    assert level_spacing(low) is None and knee_mm(low, 100.0) == math.inf


def test_column_major_frames_are_companded_as_row_major_ones():
    """Frames of a column-major array (MATLAB, h5py, a transposed view) pushed one by one:
    the same output as their row-major copies (the kernels' flat views once wrote a copy)."""
    z = _kinect_wall(7000.0, shape=(9, 24, 32))
    knee = 5760.0
    np.testing.assert_array_equal(
        compand(z[0].T, knee), compand(np.ascontiguousarray(z[0].T), knee)
    )
    u = compand(z, knee)
    np.testing.assert_array_equal(expand(u[0].T, knee), expand(np.ascontiguousarray(u[0].T), knee))
    fortran = np.asfortranarray(z.transpose(0, 2, 1))
    for mode in ("windowed", "recursive"):
        out = [o for f in fortran for o in upsr.UPSR(2, 9, mode=mode).feed(f)]
        ref = [o for f in np.ascontiguousarray(fortran) for o in upsr.UPSR(2, 9, mode=mode).feed(f)]
        for a, b in zip(out, ref, strict=True):
            np.testing.assert_array_equal(a, b)


def _sparse_then_wall() -> np.ndarray:
    """A far Kinect wall whose first frame holds a few far pixels only (too little depth to fix
    the statistics or the knee on), the knee decided on the second."""
    low = _kinect_wall(7000.0, shape=(12, 24, 32)).astype(np.float32)
    low[0] = 0.0
    low[0, 5, 5:9] = 9000.0
    low[1:, 8:16, 10:20] = np.round(low[1:, 8:16, 10:20] * 0.4)  # a box 2.8 m away
    return low


@pytest.mark.parametrize("mode", ["windowed", "recursive"])
def test_frames_before_the_knee_is_decided_are_companded_as_if_it_was_given(mode):
    low = _sparse_then_wall()
    engine = upsr.UPSR(2, 9, mode=mode)
    out = np.stack(list(engine.process(low)))
    knee = engine.statistics.knee_mm
    assert 5500 < knee < 6000
    np.testing.assert_array_equal(
        out, upsr.super_resolve(low, 2, 9, mode=mode, compand_knee_mm=knee)
    )


def test_a_pinned_chunk_equals_the_whole_run_with_the_flow_images_ready_from_the_start():
    """The depth range and noise given: the first frame's flow image is made at once, before
    the knee; it is made again with the frames companded (a pinned chunk, as ``upsr batch``
    runs, differed by up to 7 m)."""
    low = _sparse_then_wall()
    cfg = UPSRConfig(scale=2, n_frames=3, depth_range_mm=(500.0, 12000.0), noise_mm=30.0)
    whole = upsr.super_resolve(low, 2, config=cfg)
    np.testing.assert_array_equal(
        whole, upsr.super_resolve(low, 2, config=pinned_config(low[:3], cfg))
    )


def test_a_camera_turning_from_a_near_wall_to_a_far_one_is_companded():
    z = np.full((16, 24, 32), 7500.0)
    z[:4] = 3000.0
    low = np.round(kinect(z, np.random.default_rng(0), dropout_fraction=0.0))
    for mode in ("windowed", "recursive"):
        auto = upsr.super_resolve(low, 2, 9, mode=mode)
        off = upsr.super_resolve(low, 2, 9, mode=mode, compand_knee_mm=None)
        err = [np.sqrt(np.mean((o[10:, 4:-4, 4:-4] - 7500.0) ** 2)) for o in (auto, off)]
        assert err[0] < 0.5 * err[1], (mode, err)


def test_mixed_pixels_are_judged_on_the_depth_as_measured(monkeypatch):
    """Whether the sensor mixes depths at edges is the sensor's: the footprint test reads the
    frames as measured, never companded (a knee given for depth not quantised in disparity);
    a sensor whose depth is quantised in disparity samples points: no footprint test."""
    from upsr.method import recursive, statistics

    seen = []
    share, counts = statistics.footprint_share, recursive.footprint_counts
    monkeypatch.setattr(
        statistics, "footprint_share", lambda f, e: seen.append(f.max()) or share(f, e)
    )
    monkeypatch.setattr(
        recursive, "footprint_counts", lambda f, e: seen.append(f.max()) or counts(f, e)
    )
    low = 7000.0 + np.random.default_rng(0).normal(0.0, 20.0, (9, 24, 32)).astype(np.float32)
    for mode in ("windowed", "recursive"):
        list(upsr.UPSR(2, 9, mode=mode, compand_knee_mm=4000.0).process(low))
    assert len(seen) == 1 + 9 and min(seen) > 7000.0  # (companded at 4 m: 5.7 m)
    seen.clear()
    clean = np.full((9, 24, 32), 7000.0)
    clean[:, 8:16, 8:16] = 3000.0  # (a box: levels from 3 to 7 m, steps seen to grow as z²)
    kinect_box = np.round(kinect(clean, np.random.default_rng(0), dropout_fraction=0.0))
    for mode in ("windowed", "recursive"):
        list(upsr.UPSR(2, 9, mode=mode).process(kinect_box))
    assert seen == []


def test_depth_in_equal_units_over_a_narrow_range_is_no_triangulating_sensor():
    """A ToF camera's depth in 4 mm units over 2.0–2.45 m fits a level step α too, but the
    steps are not seen to grow as z² (a span under POWER_SPAN): its mixes are still judged
    (the removal had been turned off at a footprint share of 0.98)."""
    from upsr.method.statistics import sensor_mixes
    from upsr.research.synth.degradation import tof_footprint

    r = 4
    hr = np.full((9, 24 * r, 32 * r), 2450.0, np.float32)
    for k in range(9):
        hr[k, :, : 12 * r + k] = 2000.0
        hr[k, 10 * r + k : 14 * r + k, 20 * r :] = 2000.0
    tof = tof_footprint(hr, r) + np.random.default_rng(0).normal(0, 6, (9, 24, 32))
    units = (4 * np.round(tof / 4)).astype(np.float32)
    spacing = video_level_spacing(units)
    assert spacing is not None and not spacing.confirmed
    assert sensor_mixes(units, 100.0, spacing)
    cfg = UPSRConfig(scale=r, n_frames=9)
    assert pinned_config(units, cfg).remove_mixed
    engine = upsr.UPSR(r, 9, mode="recursive")
    for frame in units:
        engine.push(frame)
    assert engine.statistics.remove_mixed
