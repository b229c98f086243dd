"""Simple peers: masked bilateral filter and temporal mean."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.research.peers import bilateral_nearest, masked_bilateral, temporal_mean


def test_masked_bilateral_smooths_noise_keeps_edges_and_holes():
    rng = np.random.default_rng(0)
    clean = np.full((40, 40), 2000.0, np.float32)
    clean[:, 20:] = 1000.0
    noisy = clean + rng.normal(0, 10, clean.shape).astype(np.float32)
    noisy[5, 5] = 0.0
    out = masked_bilateral(noisy, 2.0, 30.0)
    assert out[5, 5] == 0
    inner = np.ones(clean.shape, bool)
    inner[5, 5] = False
    assert np.std((out - clean)[inner]) < 0.5 * np.std((noisy - clean)[inner])
    assert np.abs(out[:, 18:22] - clean[:, 18:22]).max() < 40  # no mixing across the edge
    np.testing.assert_array_equal(masked_bilateral(noisy, 2.0, 0.0), noisy)


def test_bilateral_nearest_shape_and_depth_dependent_sigma():
    low = np.full((2, 6, 8), 1500.0, np.float32)
    out = bilateral_nearest(low, 3, np.full((2, 6, 8), 5.0))
    assert out.shape == (2, 18, 24)
    np.testing.assert_allclose(out, 1500.0, rtol=1e-5)


def test_temporal_mean_windows_and_invalid_samples():
    video = np.stack([np.full((2, 2), v, np.float32) for v in (100, 200, 300, 400, 500)])
    video[2, 0, 0] = 0.0
    out = temporal_mean(video, 2, n_frames=3)
    assert out.shape == (5, 4, 4)
    assert out[0, 3, 3] == pytest.approx(200.0)  # window 0..2, shifted inwards
    assert out[2, 3, 3] == pytest.approx(300.0)
    assert out[2, 0, 0] == pytest.approx(300.0)  # mean of 200 and 400
    assert out[4, 3, 3] == pytest.approx(400.0)


@pytest.mark.parametrize("r", [1, 2, 3])
def test_blockwise_bilateral_equals_the_filter_of_the_nearest_upsampling(r):
    from upsr.method.upsampling import upsample_nearest

    rng = np.random.default_rng(r)
    low = rng.uniform(1000, 1100, (2, 7, 9)).astype(np.float32)
    low[:, :, 5:] += 800.0
    low[0, 3, 3] = 0.0
    sigma = rng.uniform(5, 30, low.shape).astype(np.float32)
    fast = bilateral_nearest(low, r, sigma)
    slow = masked_bilateral(upsample_nearest(low, r), float(r), 3.0 * upsample_nearest(sigma, r))
    np.testing.assert_allclose(fast, slow, rtol=1e-5, atol=1e-3)


def test_masked_bilateral_equals_its_definition():
    """A direct NumPy sum of the definition (valid neighbours only, square window)."""
    rng = np.random.default_rng(3)
    z = (1500 + rng.normal(0, 20, (9, 11))).astype(np.float32)
    z[2, 3] = 0
    z[:, 7:] += 500
    ss, sr, rad = 1.3, 40.0, 2
    out = masked_bilateral(z, ss, sr, radius_px=rad)
    ref = np.zeros_like(z)
    for i, j in zip(*np.nonzero(z), strict=True):
        num = den = 0.0
        for ii in range(max(i - rad, 0), min(i + rad + 1, z.shape[0])):
            for jj in range(max(j - rad, 0), min(j + rad + 1, z.shape[1])):
                if z[ii, jj] > 0:
                    w = np.exp(-((ii - i) ** 2 + (jj - j) ** 2) / (2 * ss**2))
                    w *= np.exp(-((z[ii, jj] - z[i, j]) ** 2) / (2 * sr**2))
                    num, den = num + w * z[ii, jj], den + w
        ref[i, j] = num / den
    np.testing.assert_allclose(out, ref, rtol=1e-6, atol=1e-3)
