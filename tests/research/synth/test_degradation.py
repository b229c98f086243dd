"""Sensor degradations: Laplacian noise, dropout, mixed (flying) pixels."""

from __future__ import annotations

import math

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.research.synth import add_laplacian_noise, dropout, flying_pixel_artefacts


def test_laplacian_noise_std_and_shape_of_law():
    rng = np.random.default_rng(0)
    depth = np.full((400, 500), 2000.0, np.float32)
    noisy = add_laplacian_noise(depth, 40.0, rng)
    n = noisy.astype(np.float64) - 2000.0
    assert noisy.dtype == np.float32 and noisy.shape == depth.shape
    assert n.std() == pytest.approx(40.0, rel=0.02)
    # Laplace: mean |n| = b = σ/√2 (a Gaussian would give σ·√(2/π) ≈ 0.80σ)
    assert np.abs(n).mean() == pytest.approx(40.0 / math.sqrt(2), rel=0.02)
    k = np.mean(n**4) / np.mean(n**2) ** 2
    assert k == pytest.approx(6.0, abs=0.4)


def test_noise_only_on_valid_pixels_and_never_invalidates():
    rng = np.random.default_rng(1)
    depth = np.full((50, 50), 5.0, np.float32)
    depth[:10] = 0.0
    depth[10:12] = np.nan
    noisy = add_laplacian_noise(depth, 100.0, rng)  # huge noise on a tiny depth
    assert (noisy[:12] == 0).all()
    assert (noisy[12:] >= 1.0).all()
    assert not np.array_equal(noisy[12:], depth[12:])


def test_zero_noise_is_identity_and_input_untouched():
    depth = np.array([[1000.0, 0.0], [1500.0, 2000.0]])
    before = depth.copy()
    out = add_laplacian_noise(depth, 0.0, np.random.default_rng(0))
    np.testing.assert_array_equal(out, depth)
    add_laplacian_noise(depth, 10.0, np.random.default_rng(0))
    np.testing.assert_array_equal(depth, before)


def test_dropout_fraction():
    rng = np.random.default_rng(2)
    out = dropout(np.full((200, 200), 1000.0), 0.3, rng)
    assert (out == 0).mean() == pytest.approx(0.3, abs=0.01)
    assert set(np.unique(out)) == {0.0, 1000.0}
    np.testing.assert_array_equal(dropout(np.ones((3, 3)), 0.0, rng), np.ones((3, 3)))


def test_flying_pixel_artefacts_mix_only_edge_pixels():
    rng = np.random.default_rng(3)
    depth = np.full((20, 20), 2500.0, np.float32)
    depth[:, :10] = 1000.0
    out = flying_pixel_artefacts(depth, rng, probability=1.0)
    changed = out != depth
    assert changed[:, 9:11].mean() > 0.9  # both sides of the edge
    assert not changed[:, :9].any() and not changed[:, 11:].any()
    assert ((out[changed] > 1000.0) & (out[changed] < 2500.0)).all()
    assert not (flying_pixel_artefacts(depth, rng, probability=0.0) != depth).any()


def test_bad_arguments():
    rng = np.random.default_rng(0)
    with pytest.raises(InputError, match="sigma_mm"):
        add_laplacian_noise(np.ones((2, 2)), -1.0, rng)
    with pytest.raises(InputError, match="Generator"):
        add_laplacian_noise(np.ones((2, 2)), 1.0, 0)
    with pytest.raises(InputError, match="negative"):
        dropout(-np.ones((2, 2)), 0.1, rng)
    with pytest.raises(InputError, match="fraction"):
        dropout(np.ones((2, 2)), -0.1, rng)
    with pytest.raises(InputError, match="2-D"):
        dropout(np.ones(4), 0.1, rng)
