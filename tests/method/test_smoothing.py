"""The edge-preserving surface smoothing (upsr.method.smoothing)."""

import numba as nb
import numpy as np
import pytest

from upsr.errors import InputError
from upsr.method.smoothing import smooth_surfaces


def _bilateral_exact(x, sigma_mm, sigma_px):
    """The bilateral filter in float64, window by window: valid neighbours inside the frame
    only, a circular window of radius ⌈2·sigma_px⌉."""
    x = np.where(np.isfinite(x) & (x > 0), x, 0.0).astype(np.float64)
    radius = int(np.ceil(2 * sigma_px))
    h, w = x.shape
    out = np.zeros_like(x)
    for i in range(h):
        for j in range(w):
            if x[i, j] <= 0:
                continue
            num = den = 0.0
            for dy in range(-radius, radius + 1):
                for dx in range(-radius, radius + 1):
                    y, c = i + dy, j + dx
                    if dy * dy + dx * dx > radius * radius or not (0 <= y < h and 0 <= c < w):
                        continue
                    if x[y, c] <= 0:
                        continue
                    wt = np.exp(-(dy * dy + dx * dx) / (2 * sigma_px**2))
                    wt *= np.exp(-((x[y, c] - x[i, j]) ** 2) / (2 * sigma_mm**2))
                    num += wt * x[y, c]
                    den += wt
            out[i, j] = num / den
    return out


def _two_surfaces(shape=(23, 31), seed=5):
    rng = np.random.default_rng(seed)
    xs = np.mgrid[0 : shape[0], 0 : shape[1]][1]
    x = (1500.0 + 3.0 * xs + rng.normal(0.0, 20.0, shape)).astype(np.float32)
    x[:, shape[1] // 2 :] += 400.0  # a depth edge
    x[rng.random(shape) < 0.15] = 0.0  # holes
    return x


@pytest.mark.parametrize("sigma_px", [0.6, 2.0, 3.0])
def test_smooth_surfaces_matches_exact_bilateral(sigma_px):
    x = _two_surfaces()
    x[3, 4] = np.nan
    x[5, 6] = -7.0
    x[7, 8] = np.inf
    before = x.copy()
    out = smooth_surfaces(x, 30.0, sigma_px)
    expected = _bilateral_exact(x, 30.0, sigma_px)
    np.testing.assert_array_equal(x, before, strict=True)  # input untouched
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out == 0, expected == 0)  # invalid stays 0, nothing new
    np.testing.assert_allclose(out, expected, atol=0.005, rtol=0)
    # the foreground never takes depth from across the edge
    valid = expected > 0
    left = valid.copy()
    left[:, x.shape[1] // 2 :] = False
    assert out[left].max() < 1500.0 + 3.0 * x.shape[1] + 100.0


def test_smooth_surfaces_independent_of_threads():
    x = _two_surfaces((61, 47), seed=2)
    threads = nb.get_num_threads()
    try:
        nb.set_num_threads(1)
        one = smooth_surfaces(x, 30.0, 2.0)
        nb.set_num_threads(threads)
        many = smooth_surfaces(x, 30.0, 2.0)
    finally:
        nb.set_num_threads(threads)
    np.testing.assert_array_equal(one, many)


def test_smooth_surfaces_rejects_bad_input():
    with pytest.raises(InputError, match="2-D"):
        smooth_surfaces(np.ones((2, 3, 4), np.float32), 30.0, 2.0)
    with pytest.raises(InputError, match="> 0"):
        smooth_surfaces(np.ones((4, 4), np.float32), 0.0, 2.0)
    with pytest.raises(InputError, match="> 0"):
        smooth_surfaces(np.ones((4, 4), np.float32), 30.0, -1.0)
