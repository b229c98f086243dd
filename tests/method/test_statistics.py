"""The choices UP-SR makes once per video (upsr.method.statistics)."""

import numpy as np
import pytest

from upsr.method.config import UPSRConfig
from upsr.method.frontend import MotionFrontEnd
from upsr.method.statistics import fix_video_statistics, pinned_config, trust_profile
from upsr.research.synth.degradation import add_depth_dependent_noise, kinect


def test_the_trust_profile_is_estimated_once_per_video_given_or_switched_off():
    clean = np.where(np.arange(96)[None, :] < 48, 1800.0, 3000.0) * np.ones((5, 72, 1))
    frames = kinect(clean, np.random.default_rng(2), image_focal_px=580.0)
    cfg = UPSRConfig(scale=2, n_frames=5)
    stats = fix_video_statistics(MotionFrontEnd(cfg, 96), frames, cfg)
    sigma_1m, power = stats.trust_noise_profile
    assert power > 1.0 and sigma_1m > 0
    pinned = pinned_config(frames, cfg)
    assert pinned.trust_noise_profile == (sigma_1m, power)
    assert trust_profile(frames, pinned, 100.0) == (sigma_1m, power)  # a chunk: the same
    for off in (
        dict(trust_noise_profile="constant"),
        dict(trust_noise_mm=10.0),  # a given noise is the noise
        dict(noise_mm=10.0),
        dict(trust_noise_profile=(2.0, 0.0)),
    ):
        assert trust_profile(frames, UPSRConfig(scale=2, **off), 100.0) is None
    # time-of-flight or Laplacian noise: one σ per video
    flat = (clean + np.random.default_rng(3).laplace(0, 7, clean.shape)).astype(np.float32)
    assert fix_video_statistics(MotionFrontEnd(cfg, 96), flat, cfg).trust_noise_profile is None
    assert pinned_config(flat, cfg).trust_noise_profile == "constant"


@pytest.mark.parametrize("law", ["gaussian", "laplace"])
def test_the_estimator_follows_the_noise_not_the_motion_of_the_camera(law):
    """A camera moving over a floor and a wall changes every pixel's depth from frame to
    frame (the temporal differences read 3× the noise): the estimator still follows the
    shape of the noise, and the noise of a sample (the reach, the radial offsets) is the
    noise; a given noise is the trust's and the reach's noise."""
    from upsr.method.noise import temporal_noise_mm

    rng = np.random.default_rng(4)
    t, y, x = np.meshgrid(np.arange(9), np.arange(48), np.arange(64), indexing="ij")
    # slopes of 8 mm per pixel, the camera moving 6 px per frame
    clean = np.where(x < 32, 1500.0 + 8.0 * (y + 6 * t), 2500.0 + 8.0 * (x - 6 * t))
    sigma = 10.0
    frames = add_depth_dependent_noise(clean, sigma, rng, law=law)
    cfg = UPSRConfig(scale=2, n_frames=9)
    assert temporal_noise_mm(frames, 100.0) > 3 * sigma  # the motion, read as noise
    stats = fix_video_statistics(MotionFrontEnd(cfg, 64), frames, cfg)
    assert stats.estimator == ("median" if law == "laplace" else "mean")
    # the trust's σ reads the motion; a sample's own noise (the reach, the radial offsets'
    # test) is read in space
    assert stats.trust_noise_mm > 3 * sigma
    assert 0.95 * sigma < stats.reach_noise_mm < 1.3 * sigma
    assert pinned_config(frames, cfg).reach_noise_mm == stats.reach_noise_mm  # a chunk: the same
    given = UPSRConfig(scale=2, n_frames=9, noise_mm=25.0)
    given_stats = fix_video_statistics(MotionFrontEnd(given, 64), frames, given)
    assert given_stats.trust_noise_mm == given_stats.reach_noise_mm == 25.0
    reach = UPSRConfig(scale=2, n_frames=9, reach_noise_mm=7.0)
    assert fix_video_statistics(MotionFrontEnd(reach, 64), frames, reach).reach_noise_mm == 7.0


def test_enough_for_statistics():
    """Neighbouring measurements to estimate a frame's noise from: not an empty frame, not a
    few scattered pixels; a small frame needs half its pairs."""
    from upsr.method.frontend import enough_for_statistics

    full = np.full((20, 24), 1500.0)
    assert enough_for_statistics(full)
    assert not enough_for_statistics(np.zeros_like(full))
    scattered = np.zeros_like(full)
    scattered[::2, ::2] = 1500.0  # (no two neighbours)
    assert not enough_for_statistics(scattered)
    patch = np.zeros_like(full)
    patch[:8, :8] = 1500.0  # 112 pairs
    assert enough_for_statistics(patch)
    assert enough_for_statistics(np.full((3, 3), 1500.0))  # (12 pairs, all a 3×3 has)
    assert not enough_for_statistics(np.array([[1500.0, 0.0], [0.0, 0.0]]))
