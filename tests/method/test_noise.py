"""The robust noise estimates (upsr.method.noise)."""

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.method.noise import (
    PROFILE_MIN_POWER,
    choose_estimator,
    estimate_noise_mm,
    noise_at_depth,
    noise_profile,
    second_differences,
    spatial_noise_mm,
    tail_ratio,
    temporal_noise_mm,
)
from upsr.research.synth.degradation import add_depth_dependent_noise, kinect


def test_noise_estimate():
    rng = np.random.default_rng(3)
    z = 2000 + rng.normal(0, 10, (200, 200)).astype(np.float32)
    assert estimate_noise_mm(z) == pytest.approx(10, rel=0.1)


def test_noise_estimate_from_every_kth_row_is_a_sample_of_the_same_estimate():
    rng = np.random.default_rng(4)
    z = (2000 + rng.normal(0, 10, (400, 300))).astype(np.float32)
    full = estimate_noise_mm(z, 2)
    assert estimate_noise_mm(z, 2, row_step=1) == full
    assert estimate_noise_mm(z, 2, row_step=4) == pytest.approx(full, rel=0.05)
    assert estimate_noise_mm(z, 2, row_step=4) != full  # (it did use fewer rows)
    with pytest.raises(InputError):
        estimate_noise_mm(z, 2, row_step=0)


def _two_planes(sigma_at, near=1500.0, far=3000.0, t=3, shape=(60, 80), seed=0):
    """A slanted near plane on the left, a far wall on the right, noise std sigma_at(z)."""
    rng = np.random.default_rng(seed)
    _ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float64)
    z = np.where(xs < shape[1] // 2, near + 4.0 * xs, far)
    return (z + rng.normal(0.0, 1.0, (t, *shape)) * sigma_at(z)).astype(np.float32)


@pytest.mark.parametrize("shape", [(60, 80), (480, 640)])  # (every k-th row of the large one)
def test_the_profile_finds_noise_that_grows_as_the_square_of_depth(shape):
    frames = _two_planes(lambda z: 3.0 * (z / 1000.0) ** 2, shape=shape)
    sigma_1m, power = noise_profile(frames, 100.0)
    assert power == pytest.approx(2.0, abs=0.2)
    assert sigma_1m == pytest.approx(3.0, rel=0.2)
    z = np.array([0.0, 1000.0, 2000.0])
    np.testing.assert_allclose(
        noise_at_depth(z, sigma_1m, power), [0, sigma_1m, sigma_1m * 2**power], rtol=1e-6
    )


def test_noise_that_does_not_depend_on_depth_has_power_zero_and_its_level():
    sigma_1m, power = noise_profile(_two_planes(lambda z: 10.0 + 0 * z), 100.0)
    assert power == 0.0
    assert sigma_1m == pytest.approx(10.0, rel=0.1)  # (the slanted plane's slope cancels)


def test_a_power_no_sensor_has_is_no_profile():
    """Depth without noise (a clean render: what is left grows steeply with depth) fitted p =
    9.6 on a 14 m corridor (this one 4.9), and the deblurring's steps at 12 m were millions
    of times its median step (outputs of 0.001 mm): a power beyond PROFILE_MAX_POWER is no
    profile."""
    frames = _two_planes(lambda z: 1e-4 * (z / 1000.0) ** 6, near=1500.0, far=12000.0)
    sigma_1m, power = noise_profile(frames, 100.0)
    assert power == 0.0 and sigma_1m > 0


def test_a_narrow_depth_span_or_no_depth_fits_no_power():
    frames = _two_planes(lambda z: 3.0 * (z / 1000.0) ** 2, near=2800.0, far=3000.0)
    assert noise_profile(frames, 100.0)[1] == 0.0
    assert noise_profile(np.zeros((2, 10, 10), np.float32), 100.0) == (0.0, 0.0)
    with pytest.raises(InputError):
        noise_profile(np.zeros(5, np.float32), 100.0)


def test_the_kinect_model_has_a_profile_and_its_quantisation_is_counted_in_it():
    clean = np.where(np.arange(96)[None, :] < 48, 1800.0, 3000.0) * np.ones((3, 72, 1))
    frames = kinect(clean, np.random.default_rng(2), image_focal_px=580.0)
    sigma_1m, power = noise_profile(frames, 100.0)
    assert power > 1.0 > PROFILE_MIN_POWER
    # at 3 m: axial noise 14.0 mm and a disparity step of 25.9 mm (uniform: 7.5 mm)
    assert float(noise_at_depth(3000.0, sigma_1m, power)) == pytest.approx(15.9, rel=0.2)


def test_the_noise_keeps_the_tails_of_strong_laplacian_noise():
    """σ = 50 mm: the edge threshold (141 mm) cuts the triples' tails; 8σ does not."""
    rng = np.random.default_rng(7)
    frames = (2000.0 + rng.laplace(0, 50 / np.sqrt(2), (9, 60, 80))).astype(np.float32)
    assert temporal_noise_mm(frames, 141.0) == pytest.approx(50.0, rel=0.05)
    assert choose_estimator(tail_ratio(second_differences(frames, 141.0, 50.0))) == "median"
    assert tail_ratio(second_differences(frames, 141.0, 50.0)) > tail_ratio(
        second_differences(frames, 141.0, 1.0)
    )  # tails cut


@pytest.mark.parametrize("law", ["gaussian", "laplace"])
def test_the_tails_of_the_noise_are_read_in_space_not_in_time(law):
    """A floor seen by a moving camera and a box moving in front of a wall change depth
    from frame to frame: the excess kurtosis of the temporal differences (which chose the
    estimator before, the median above 0.75) reads them as heavy tails, 1.3 under Gaussian
    noise. The second differences along the rows and columns cancel the slopes and ignore
    the motion."""
    from upsr.method.noise import TAIL_RATIO_MEDIAN

    rng = np.random.default_rng(11)
    t, y, x = np.meshgrid(np.arange(9), np.arange(48), np.arange(64), indexing="ij")
    clean = np.where(x < 16, 1500.0 + 25.0 * (y + 3 * t), 2500.0)  # floor moving 3 px/frame
    box = (np.abs(x - (30 + 2 * t)) < 6) & (np.abs(y - 24) < 8)  # 150 mm off the wall
    clean = np.where(box, 2350.0, clean)
    sigma = 20.0
    frames = add_depth_dependent_noise(clean, sigma, rng, law=law)
    d = np.diff(frames, axis=0).ravel().astype(np.float64)
    d -= np.median(d)
    d = d[np.abs(d) <= 8 * 1.4826 * np.median(np.abs(d))]
    assert np.mean((d - d.mean()) ** 4) / d.var() ** 2 - 3 > 0.75  # "heavy tails" in time
    tail = tail_ratio(second_differences(frames, 100.0, sigma))
    assert (tail > TAIL_RATIO_MEDIAN) == (law == "laplace")
    assert choose_estimator(tail) == ("median" if law == "laplace" else "mean")
    assert np.isnan(
        tail_ratio(second_differences(clean, 100.0, 0.0))
    )  # no noise: no shape (the median)
    assert np.isnan(
        tail_ratio(second_differences(frames[:, :2, :2], 100.0, sigma))
    )  # too few triples


@pytest.mark.parametrize("law", ["gaussian", "laplace"])
def test_a_samples_noise_is_read_in_space_whatever_the_law_and_the_motion(law):
    """A floor seen by a camera moving 3 px per frame beside a wall: the temporal
    differences read the motion (three times the noise); the std of the second differences
    reads σ under either law. On a flat wall the robust estimate reads under 0.92σ under
    Laplacian noise, the second differences σ."""
    rng = np.random.default_rng(12)
    t, y, x = np.meshgrid(np.arange(9), np.arange(48), np.arange(64), indexing="ij")
    sigma = 10.0
    clean = np.where(x < 40, 1000.0 + 20.0 * (y + 3 * t), 2500.0 + 8.0 * (x - 3 * t))
    frames = add_depth_dependent_noise(clean, sigma, rng, law=law)
    assert temporal_noise_mm(frames, 100.0) > 2.5 * sigma
    d2 = second_differences(frames, 100.0, sigma)
    assert spatial_noise_mm(d2, 0.5 * sigma) == pytest.approx(sigma, rel=0.05)
    assert spatial_noise_mm(d2, 3 * sigma) == 3 * sigma  # at least the estimate given
    assert spatial_noise_mm(d2[:49], 0.5 * sigma) == 0.5 * sigma  # too few differences
    assert spatial_noise_mm(second_differences(clean, 100.0, 0.0), 0.0) == 0.0  # no noise
    flat = add_depth_dependent_noise(np.full((9, 48, 64), 2000.0), sigma, rng, law=law)
    robust = float(np.median([estimate_noise_mm(f) for f in flat]))
    if law == "laplace":
        assert robust < 0.92 * sigma  # (the MAD of Laplacian differences)
    else:
        assert robust == pytest.approx(sigma, rel=0.05)
    d2 = second_differences(flat, 100.0, robust)
    assert spatial_noise_mm(d2, robust) == pytest.approx(sigma, rel=0.05)


def _kinect_floor(seed: int = 0, n: int = 9) -> tuple[np.ndarray, np.ndarray]:
    """A floor from 1.2 to 3 m and a box at 1.5 m seen by a Kinect-like sensor: quantised
    disparity whose noise grows with depth (a mixture of scales: a heavy-tailed kurtosis)."""
    clean = np.broadcast_to(np.linspace(1200.0, 3000.0, 64)[:, None], (n, 64, 80)).copy()
    clean[:, 20:40, 30:50] = 1500.0
    return clean, kinect(clean, np.random.default_rng(seed), image_focal_px=580.0)


def test_quantised_depth_is_seen_in_the_steps_between_its_levels():
    from upsr.method.noise import QUANTISED_STEPS, quantisation_step

    _, frames = _kinect_floor()
    sigma_1m, power = noise_profile(frames, 100.0)
    assert quantisation_step(frames, 10.0, (sigma_1m, power)) > 2 * QUANTISED_STEPS
    assert quantisation_step(frames, 10.0) > 2 * QUANTISED_STEPS  # one σ for all depths
    rng = np.random.default_rng(1)
    floor = np.linspace(1200.0, 3000.0, 64)[:, None] * np.ones((9, 1, 80))
    noisy = floor + rng.normal(0, 10.0, floor.shape)
    assert quantisation_step(noisy, 10.0) < 0.01  # continuous: as many levels as samples
    assert quantisation_step(np.round(noisy), 10.0) <= 0.2 * QUANTISED_STEPS  # whole mm
    noisy[0, 0, :3] = [0.0, np.nan, -5.0]  # no measurement: not a level
    assert quantisation_step(noisy, 10.0) < 0.01
    assert np.isnan(quantisation_step(np.full((4, 4), 2000.0), 10.0))


def test_quantised_depth_is_fused_by_the_mean_whatever_its_tails():
    """The depth-dependent noise of a Kinect is a mixture of scales, heavy-tailed (the
    median was chosen), but the median of quantised samples is a quantisation level: two
    static walls at 1.8 and 3 m came out 2.6× worse than with the mean (measured 2.0 against
    0.8 mm; the temporal mean of the raw frames 3.9)."""
    import upsr
    from upsr.method.config import UPSRConfig
    from upsr.method.frontend import MotionFrontEnd
    from upsr.method.noise import TAIL_RATIO_MEDIAN
    from upsr.method.statistics import fix_video_statistics
    from upsr.research.peers import temporal_mean

    clean = np.where(np.arange(96)[None, :] < 48, 1800.0, 3000.0) * np.ones((9, 72, 1))
    frames = kinect(clean, np.random.default_rng(0), image_focal_px=580.0)
    assert tail_ratio(second_differences(frames, 100.0, 10.0)) > TAIL_RATIO_MEDIAN
    cfg = UPSRConfig(scale=2, n_frames=9)
    assert fix_video_statistics(MotionFrontEnd(cfg, 96), frames, cfg).estimator == "mean"
    rng = np.random.default_rng(3)
    laplace = (clean + rng.laplace(0, 10 / np.sqrt(2), clean.shape)).astype(np.float32)
    assert fix_video_statistics(MotionFrontEnd(cfg, 96), laplace, cfg).estimator == "median"
    truth = np.repeat(np.repeat(clean[4], 2, axis=0), 2, axis=1)
    inner = np.zeros(truth.shape, bool)
    inner[6:-6, 6:-6] = True
    inner[:, 80:112] = False  # away from the edge between the walls

    def rmse(out):
        assert (out[inner] > 0).all()
        return float(np.sqrt(np.mean((out - truth)[inner] ** 2)))

    auto = rmse(upsr.super_resolve(frames, 2, 9)[4])
    assert auto < 0.5 * rmse(upsr.super_resolve(frames, 2, 9, fusion_estimator="median")[4])
    assert auto < 0.5 * rmse(temporal_mean(frames, 2, 9)[4])
