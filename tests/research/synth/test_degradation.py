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


# --------------------------------------------------------------------------------------------
# Sensor models: ToF footprint, depth-dependent noise, Kinect v1
# --------------------------------------------------------------------------------------------

from upsr.research.synth import degradation as deg  # noqa: E402


def test_tof_footprint_means_blocks_and_mixes_at_an_edge():
    r = 4
    truth = np.full((8, 16), 3000.0, np.float32)
    truth[:, :6] = 1000.0  # edge inside the second block column (cols 4..7)
    low = deg.tof_footprint(truth, r)
    assert low.shape == (2, 4) and low.dtype == np.float32
    np.testing.assert_allclose(low[:, 0], 1000.0)
    np.testing.assert_allclose(low[:, 2:], 3000.0)
    # the mixed (flying) pixel: 2 of 4 columns foreground
    np.testing.assert_allclose(low[:, 1], 0.5 * 1000.0 + 0.5 * 3000.0)
    # video input and exact block means
    rng = np.random.default_rng(0)
    video = rng.uniform(500, 4000, (3, 8, 12)).astype(np.float32)
    expect = video.reshape(3, 2, 4, 3, 4).mean(axis=(2, 4))
    np.testing.assert_allclose(deg.tof_footprint(video, 4), expect, rtol=1e-6)


def test_tof_footprint_no_return_when_most_of_the_block_is_empty():
    truth = np.zeros((4, 12), np.float32)
    truth[:, 0:4] = 2000.0  # full block
    truth[:2, 4:8] = 1500.0  # half the block: kept (not "most" empty), mean of valid only
    truth[0, 8:11] = 1200.0  # 3 of 16 valid: no return
    low = deg.tof_footprint(truth, 4)
    np.testing.assert_allclose(low[0], [2000.0, 1500.0, 0.0])
    assert deg.tof_footprint(truth, 4, min_valid_fraction=0.1)[0, 2] == pytest.approx(1200.0)
    with pytest.raises(InputError):
        deg.tof_footprint(np.ones((5, 8)), 4)


@pytest.mark.parametrize("law, kurtosis", [("gaussian", 3.0), ("laplace", 6.0)])
def test_depth_dependent_noise_statistics(law, kurtosis):
    rng = np.random.default_rng(4)
    depth = np.empty((400, 400), np.float32)
    depth[:200] = 1000.0
    depth[200:] = 3000.0
    coeffs = (2.0, 0.0, 3.0)  # σ = 2 + 3·z_m² mm: 5 mm at 1 m, 29 mm at 3 m
    noisy = deg.add_depth_dependent_noise(depth, coeffs, rng, law=law).astype(np.float64)
    for rows, z, s in ((slice(0, 200), 1000.0, 5.0), (slice(200, 400), 3000.0, 29.0)):
        n = noisy[rows] - z
        assert abs(n.mean()) < 0.05 * s
        assert n.std() == pytest.approx(s, rel=0.02)
        assert np.mean(n**4) / np.mean(n**2) ** 2 == pytest.approx(kurtosis, abs=0.4)
    # a callable gives the same law as the coefficients
    again = deg.add_depth_dependent_noise(
        depth, lambda z: 2.0 + 3.0 * (z / 1000.0) ** 2, np.random.default_rng(4), law=law
    )
    np.testing.assert_allclose(again, noisy, rtol=1e-6)


def test_kinect_axial_sigma_follows_nguyen_2012():
    np.testing.assert_allclose(
        deg.kinect_axial_sigma_mm([400.0, 1000.0, 2000.0, 3000.0]),
        [1.2, 1.2 + 1.9 * 0.36, 1.2 + 1.9 * 2.56, 1.2 + 1.9 * 6.76],
    )


def test_disparity_quantisation_steps():
    fb = 580.0 * 75.0
    z = np.linspace(800.0, 3500.0, 5000, dtype=np.float32)[None, :]
    q = deg.quantise_disparity(z).astype(np.float64)
    d = fb / q
    # every output disparity is a multiple of 1/8 px, and within half a step of the input's
    np.testing.assert_allclose(d * 8, np.round(d * 8), atol=1e-3)
    assert np.abs(d - fb / z).max() <= 1 / 16 + 1e-4
    # the depth step at 2 m is z²·(1/8)/(f·b) ≈ 11.5 mm: neighbouring levels differ by that
    levels = np.unique(np.round(q[(q > 1900) & (q < 2100)], 2))
    assert np.diff(levels).mean() == pytest.approx(2000.0**2 / fb / 8, rel=0.1)
    assert deg.quantise_disparity(np.zeros((2, 2))).sum() == 0


def test_projector_shadows_on_the_far_side_of_the_jump():
    f, b = 145.0, 75.0  # Kinect at 160×120
    depth = np.full((4, 60), 2000.0, np.float32)
    depth[:, 30:45] = 1000.0  # foreground block
    width = f * b * (1 / 1000.0 - 1 / 2000.0)  # ≈ 5.4 px
    out = deg.projector_shadows(depth, focal_px=f, baseline_mm=b, projector_side="right")
    shadow = (out == 0)[0]
    cols = np.flatnonzero(shadow)
    # projector on the right: the band lies left of the foreground, on the background
    assert cols.max() == 29 and len(cols) in (int(width), int(width) + 1)
    assert (out[:, 30:45] == 1000.0).all() and (out[:, 45:] == 2000.0).all()
    left = deg.projector_shadows(depth, focal_px=f, baseline_mm=b, projector_side="left")
    cols = np.flatnonzero((left == 0)[0])
    assert cols.min() == 45 and len(cols) in (int(width), int(width) + 1)
    # a slanted plane casts no shadow on itself
    ramp = np.tile(np.linspace(1500.0, 2500.0, 60, dtype=np.float32), (3, 1))
    assert (deg.projector_shadows(ramp, focal_px=f) > 0).all()


def test_kinect_model_rate_of_dropouts_noise_and_shadows():
    rng = np.random.default_rng(5)
    depth = np.full((2, 120, 160), 2000.0, np.float32)
    depth[:, 40:80, 60:100] = 1200.0
    out = deg.kinect(depth, rng)
    assert out.shape == depth.shape and out.dtype == np.float32
    # shadow band left of the box, about f·b·(1/1.2 m − 1/2 m) = 145·75·(1/1200 − 1/2000) px
    band = 145.0 * 75.0 * (1 / 1200.0 - 1 / 2000.0)
    row = out[0, 60]
    assert (row[60 - int(band) + 1 : 60] == 0).all()
    lost = out[:, :, 120:] == 0  # far from any edge: dropouts only
    assert lost.mean() == pytest.approx(0.01, abs=0.004)
    wall = out[:, :, 120:][~lost].astype(np.float64)
    # σ_z(2 m) ≈ 6.1 mm of noise plus the ≈ 11.5 mm quantisation (uniform: step/√12 ≈ 3.3 mm)
    assert wall.std() == pytest.approx(math.hypot(6.06, 11.46 / math.sqrt(12)), rel=0.15)
    assert abs(wall.mean() - 2000.0) < 1.0
