"""The motion front-end's per-video statistics (upsr.method.frontend): the scale of the depth
thresholds for a camera at close range, the final smoothing at high noise."""

import dataclasses

import numpy as np
import pytest

import upsr
from upsr.method.config import UPSRConfig
from upsr.method.frontend import MotionFrontEnd, depth_scale
from upsr.method.statistics import first_frame_noise_mm, fix_video_statistics, pinned_config


def _box_video(near_mm: float, far_mm: float, n: int = 8, seed: int = 0) -> np.ndarray:
    """A box ``near_mm`` away moving 1 px per frame across a wall ``far_mm`` away (0.5 mm
    noise), 24×28."""
    video = np.full((n, 24, 28), far_mm, np.float32)
    for t in range(n):
        video[t, 7:16, 6 + t : 15 + t] = near_mm
    noise = np.random.default_rng(seed).normal(0.0, 0.5, video.shape)
    return (video + noise).astype(np.float32)


def _flying(out: np.ndarray, near_mm: float, far_mm: float, tol_mm: float = 5.0) -> int:
    """Output pixels with depth within neither surface's ``tol_mm``."""
    d = out[out > 0]
    return int(((np.abs(d - near_mm) > tol_mm) & (np.abs(d - far_mm) > tol_mm)).sum())


def test_depth_scale_is_the_median_depth_over_the_near_depth_at_most_one():
    frames = np.full((3, 8, 8), 400.0, np.float32)
    frames[:, :2] = 0.0  # no measurement: not counted
    frames[:, 2, :] = 5000.0  # a far row moves the median nowhere
    assert depth_scale(frames, 1000.0) == pytest.approx(0.4)
    assert depth_scale(frames * 10, 1000.0) == 1.0  # 4 m: the thresholds as given
    assert depth_scale(frames, None) == 1.0
    assert depth_scale(np.zeros((2, 4, 4)), 1000.0) == 1.0  # nothing measured: as given
    # a few stray values (an otherwise empty first window) scale nothing; a frame with
    # enough neighbouring measurements does, on its own
    strays = np.zeros((3, 40, 48), np.float32)
    strays[:, ::7, ::9] = 5.0
    assert depth_scale(strays, 1000.0) == 1.0
    strays[2] = 400.0
    assert depth_scale(strays, 1000.0) == pytest.approx(0.4)


def test_the_front_end_scales_the_thresholds_once_per_video():
    cfg = UPSRConfig(scale=2, n_frames=3)
    near = _box_video(220.0, 250.0, n=3)
    front = MotionFrontEnd(cfg, near.shape[-1])
    assert front.depth_scale == 1.0 and front.edge_mm == 100.0 and front.fixed_config is cfg
    front.fix_statistics(near)
    k = float(np.median(near)) / 1000.0
    assert front.depth_scale == pytest.approx(k)
    assert front.edge_mm == pytest.approx(max(100.0 * k, 4.0 * front.noise_mm))
    fixed = front.fixed_config
    assert fixed.near_depth_mm is None
    assert fixed.edge_mm == pytest.approx(100.0 * k)
    assert fixed.deblur.edge_mm == pytest.approx(100.0 * k)
    assert fixed.deblur.smooth_sigma_mm == pytest.approx(30.0 * k)
    # a chunk of the video runs with them as fixed (upsr batch)
    pinned = pinned_config(near, cfg)
    assert (pinned.edge_mm, pinned.deblur, pinned.near_depth_mm) == (
        fixed.edge_mm,
        fixed.deblur,
        None,
    )
    # a scene a metre away or farther: nothing changes
    far = MotionFrontEnd(cfg, near.shape[-1])
    far.fix_statistics(near * 10)
    assert far.depth_scale == 1.0 and far.fixed_config.edge_mm == 100.0
    assert far.fixed_config.deblur == cfg.deblur


@pytest.mark.parametrize("mode", ["windowed", "recursive"])
def test_a_camera_at_close_range_keeps_its_surfaces_apart(mode):
    """A box 3 cm in front of a wall 25 cm away: with the thresholds made for metres (one
    surface at 100 mm, smoothed with a 30 mm range std) thousands of output pixels lie
    between box and wall; scaled to the scene, none."""
    video = _box_video(220.0, 250.0)
    out = upsr.super_resolve(video, 2, 5, mode=mode)
    assert _flying(out, 220.0, 250.0) == 0
    unscaled = upsr.super_resolve(video, 2, 5, mode=mode, near_depth_mm=None)
    assert _flying(unscaled, 220.0, 250.0) > 500
    # the same scene 2.2 m away: the defaults as they were
    far = _box_video(2200.0, 2500.0)
    np.testing.assert_array_equal(
        upsr.super_resolve(far, 2, 5, mode=mode),
        upsr.super_resolve(far, 2, 5, mode=mode, near_depth_mm=None),
    )


def _noisy_planes(sigma_mm: float, n: int = 3) -> np.ndarray:
    """A slanted plane 2–3 m away with a box, Laplacian noise of std ``sigma_mm``, 40×48."""
    rng = np.random.default_rng(1)
    clean = 2000.0 + 20.0 * np.mgrid[0:40, 0:48][1]
    clean[10:25, 12:30] = 1500.0
    noise = rng.laplace(0.0, sigma_mm / np.sqrt(2.0), (n, 40, 48))
    return (clean + noise).astype(np.float32)


def test_the_final_smoothing_is_at_least_a_samples_noise():
    cfg = UPSRConfig(scale=2, n_frames=3)
    front = MotionFrontEnd(cfg, 48)
    front.fix_statistics(_noisy_planes(10.0))
    front.smooth_at_least(12.0)  # below the configured 30 mm: as configured
    assert front.fixed_config.deblur == cfg.deblur
    front.smooth_at_least(49.0)
    assert front.fixed_config.deblur.smooth_sigma_mm == 49.0
    assert front.fixed_config.deblur.edge_mm == cfg.deblur.edge_mm
    # with the video's statistics, from its own noise: both modes, and a chunk (upsr batch)
    for sigma, want in ((10.0, 30.0), (50.0, 50.0)):
        frames = _noisy_planes(sigma)
        front = MotionFrontEnd(cfg, 48)
        fix_video_statistics(front, frames, cfg)
        assert front.fixed_config.deblur.smooth_sigma_mm == pytest.approx(want, rel=0.15)
        pinned = pinned_config(frames, cfg)
        assert pinned.deblur == front.fixed_config.deblur
        engine = upsr.UPSR(2, 3, mode="recursive")
        engine.push(frames[0])
        assert engine._front.fixed_config.deblur.smooth_sigma_mm == pytest.approx(want, rel=0.15)
    assert first_frame_noise_mm(frames[0], front, dataclasses.replace(cfg, noise_mm=7.0)) == 7.0


def _slanted_approach(n: int = 10, step_mm: float = 25.0, sigma_mm: float = 10.0, seed=0):
    """A wall slanted along the rows (40 mm per px) coming ``step_mm`` nearer per frame,
    seen without lateral motion, with Gaussian noise; 24×32."""
    x = np.arange(32, dtype=np.float32)
    wall = 1500.0 + 40.0 * x[None, :] + np.zeros((24, 1), np.float32)
    video = np.stack([wall - step_mm * t for t in range(n)])
    return (video + np.random.default_rng(seed).normal(0, sigma_mm, video.shape)).astype(np.float32)


def test_the_depth_drift_is_the_scenes_common_change():
    video = _slanted_approach()
    cfg = UPSRConfig(scale=2, n_frames=5)
    front = MotionFrontEnd(cfg, 32)
    front.fix_statistics(video[:5])
    pre = [front.prefilter(f) for f in video[:2]]
    drift = front.depth_drift_mm(pre[0], pre[1])
    assert drift == pytest.approx(-25.0, abs=2.0)
    assert front.depth_drift_mm(pre[0], pre[0]) == 0.0  # a static scene: none
    # below half a level of the guide: none (the flows as they were)
    near, far = front.depth_range_mm
    assert front.depth_drift_mm(pre[0], pre[0] + 0.4 * (far - near) / 254.0) == 0.0
    # pixels changing each their own way, by more than their common change (a camera moving
    # sideways and turning in a room): none
    ragged = pre[0] - 20.0 + np.random.default_rng(1).uniform(-60.0, 60.0, pre[0].shape)
    assert front.depth_drift_mm(pre[0], ragged.astype(np.float32)) == 0.0
    # a part of the scene changing alone (a box coming nearer over a third of it): none
    part = pre[0].copy()
    part[:, : part.shape[1] // 3] -= 60.0
    assert front.depth_drift_mm(pre[0], part) == 0.0
    # a change beyond the edge threshold is no drift (a cut, a pan to another scene)
    assert front.depth_drift_mm(pre[0], pre[0] + 3 * front.edge_mm) == 0.0
    # the guide of a frame brought back: its depth minus the drift where measured
    holes = pre[1].copy()
    holes[0, :4] = 0.0
    back, guide = front.shifted(holes, drift)
    assert np.all(back[0, :4] == 0) and np.allclose(back[1:], pre[1][1:] - drift)
    assert np.array_equal(guide, front.guide(back))
    assert front.shifted(np.array([[5.0, 2000.0]], np.float32), 10.0)[0].tolist() == [[0, 1990]]
    # integer frames as floats; a frame of a few pixels tells no drift
    ints = [np.round(p).astype(np.uint16) for p in pre]
    assert front.depth_drift_mm(*ints) == pytest.approx(drift, abs=1.0)
    assert front.depth_drift_mm(pre[0][:12, :12], pre[1][:12, :12]) == 0.0  # 9 samples


def test_a_depth_drift_is_not_taken_for_motion_along_a_slope():
    """Nothing moves sideways: the flow between two frames of a slanted wall coming nearer
    is near zero once the second is brought back by the drift, and along the slope without
    (the 8-bit depth reads as brightness); the recursive output, whose flow is so estimated,
    follows the wall without lag (surface bias +4.0 mm over the last five frames without the
    drift, monkeypatched away)."""
    video = _slanted_approach()
    cfg = UPSRConfig(scale=2, n_frames=5)
    front = MotionFrontEnd(cfg, 32)
    front.fix_statistics(video[:5])
    pre = [front.prefilter(f) for f in video[:2]]
    guides = [front.guide(p) for p in pre]
    drift = front.depth_drift_mm(*pre)
    inner = (slice(4, -4), slice(8, -8))
    back, back_guide = front.shifted(pre[1], drift)
    with_drift = front.consecutive_flow(back, pre[0], back_guide, guides[0])[inner]
    without = front.consecutive_flow(pre[1], pre[0], guides[1], guides[0])[inner]
    assert np.abs(with_drift[..., 0]).mean() < 0.2 < np.abs(without[..., 0]).mean()

    truth = _slanted_approach(sigma_mm=0.0)
    out = upsr.super_resolve(video, 2, 5, mode="recursive")
    bias = np.mean(out[5:, 4:-4, 8:-8] - np.repeat(np.repeat(truth[5:], 2, 1), 2, 2)[:, 4:-4, 8:-8])
    assert abs(bias) < 1.5, bias
