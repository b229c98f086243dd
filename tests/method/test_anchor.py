"""The reference frame's anchors and the noise outliers of a frame."""

import numpy as np
import pytest

from upsr.method.anchor import OUTLIER_MAX_SIGMAS, OWN_SURFACE_SIGMAS, noise_outliers


def _plane(sigma, *, seed=0, shape=(24, 32), slope=(2.0, 1.0)):
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float32)
    clean = 5000 + slope[0] * xs + slope[1] * ys
    return clean, (clean + rng.normal(0, sigma, shape)).astype(np.float32)


def test_a_pair_of_noise_outliers_is_an_outlier_a_thin_part_and_a_far_object_are_not():
    sigma = 10.0
    clean, frame = _plane(sigma, seed=1)
    frame = np.clip(frame, clean - 2 * sigma, clean + 2 * sigma)  # no other outliers
    frame[5, 5] = clean[5, 5] + 55.0  # a lone outlier, 5.5 σ
    frame[10, 10], frame[11, 11] = clean[10, 10] - 50.0, clean[11, 11] - 60.0  # a pair
    frame[3:20, 25] = clean[3:20, 25] - 50.0  # a thin part one pixel wide, as far off
    frame[16, 8], frame[16, 9] = clean[16, 8] - 400.0, clean[16, 9] - 400.0  # an object
    around, limit = noise_outliers(frame, sigma)
    flagged = set(zip(*np.nonzero(around), strict=True))
    assert flagged == {(5, 5), (10, 10), (11, 11)}
    assert set(zip(*np.nonzero(limit), strict=True)) == flagged
    # the surface around: the median of the 3×3 samples, within 3σ + their spread of it
    np.testing.assert_allclose(around[5, 5], np.median(frame[4:7, 4:7]))
    spread = np.median(np.abs(frame[4:7, 4:7] - around[5, 5]))
    np.testing.assert_allclose(limit[5, 5], OWN_SURFACE_SIGMAS * sigma + spread, rtol=1e-5)
    assert OUTLIER_MAX_SIGMAS * sigma < 400.0


@pytest.mark.parametrize("slope", [(0.0, 0.0), (40.0, 25.0), (-90.0, 60.0)])
def test_without_noise_nothing_is_an_outlier_on_any_slope(slope):
    _clean, frame = _plane(0.0, slope=slope)
    frame[4, 4] += 30.0  # a small bump, real at σ = 0
    assert not noise_outliers(frame, 0.0)[0].any()
    # with noise of the slope's size, a steep plane's pixels are not outliers either
    _clean, noisy = _plane(3.0, slope=slope, seed=2)
    assert (noise_outliers(noisy, 3.0)[0] > 0).mean() < 0.01


def test_the_noise_follows_the_profile_and_holes_are_never_outliers():
    clean, frame = _plane(0.0)
    frame[6, 6] = clean[6, 6] + 60.0
    frame[12:, :] = 0.0
    frame[11, 20] = clean[11, 20] + 60.0  # beside the hole: not judged
    assert noise_outliers(frame, 10.0)[0][6, 6] > 0
    # σ₁ = 0.5 mm at 1 m, growing as z²: 12.5 mm at 5 m (60 mm = 4.8 σ: an outlier)
    assert noise_outliers(frame, 1.0, noise_profile=(0.5, 2.0))[0][6, 6] > 0
    # σ₁ = 0.1 mm: 2.5 mm at 5 m (60 mm = 24 σ: a small object)
    assert not noise_outliers(frame, 10.0, noise_profile=(0.1, 2.0))[0].any()
    assert not noise_outliers(frame, 10.0)[0][12:].any()
