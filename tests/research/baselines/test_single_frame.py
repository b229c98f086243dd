"""Single-frame baselines of paper §7 (upsr.research.baselines.single_frame): nearest, naive
bicubic, bicubic without flying pixels and joint bilateral upsampling (Kopf et al. 2007)."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.method.upsampling import upsample_nearest
from upsr.research import metrics
from upsr.research.baselines import (
    bicubic,
    bicubic_noflying,
    joint_bilateral_upsampling,
    nearest,
)
from upsr.research.synth import dynamic_scene

FG, BG = 1000.0, 2500.0


def step_video(t: int = 2, h: int = 8, w: int = 10) -> np.ndarray:
    v = np.full((t, h, w), BG, np.float32)
    v[:, :, : w // 2] = FG
    return v


@pytest.mark.parametrize("method", [nearest, bicubic])
def test_shapes_and_dtype(method):
    v = step_video()
    out = method(v, 3)
    assert out.shape == (2, 24, 30) and out.dtype == np.float32
    single = method(v[0].astype(np.float64), 3)
    assert single.shape == (24, 30) and single.dtype == np.float32
    np.testing.assert_allclose(single, out[0])
    np.testing.assert_array_equal(method(v, 1), v)


@pytest.mark.parametrize("method", [nearest, bicubic])
def test_constant_image_preserved(method):
    v = np.full((2, 7, 9), 1234.5, np.float32)
    np.testing.assert_allclose(method(v, 4), 1234.5, rtol=1e-6)


def test_nearest_is_dense_upsampling():
    rng = np.random.default_rng(0)
    v = rng.uniform(500, 3000, (3, 5, 6)).astype(np.float32)
    v[0, 1, 1] = 0.0
    np.testing.assert_array_equal(nearest(v, 4), upsample_nearest(v, 4))


def test_bicubic_creates_flying_pixels_nearest_does_not():
    v = step_video()

    def between(a):
        return (a > FG + 150) & (a < BG - 150)

    assert between(bicubic(v, 4)).any()
    assert not between(nearest(v, 4)).any()
    # nearest creates no new values at all
    assert set(np.unique(nearest(v, 4))) == {FG, BG}


def test_bicubic_uses_half_pixel_geometry():
    # SPEC §1: low-res pixel j sits at high-res coordinate (j + 0.5)·r − 0.5.
    row = np.full((5, 12), 1000.0, np.float32)
    row[:, 5] = 2000.0
    out4 = bicubic(row, 4)[8]  # an impulse at j = 5 is centred at 21.5 for r = 4
    np.testing.assert_allclose(out4[21 - np.arange(8)], out4[22 + np.arange(8)], rtol=1e-6)
    out3 = bicubic(row, 3)[7]  # ... and exactly on high-res pixel 16 for r = 3
    assert out3.argmax() == 16 and out3[16] == pytest.approx(2000.0)
    np.testing.assert_allclose(out3[16 - np.arange(6)], out3[16 + np.arange(6)], rtol=1e-6)


def test_bicubic_interpolates_holes_as_zero_and_clips_negative():
    v = np.full((1, 9, 9), 2000.0, np.float32)
    v[0, 4, 4] = 0.0  # a hole
    v[0, 0, :3] = np.nan  # NaN is a hole too
    out = bicubic(v, 4)
    assert (out >= 0).all()
    # the naive interpolation pulls the neighbourhood of the hole towards 0 ...
    assert out[0, 17:19, 17:19].max() < 500.0
    assert ((out > 100) & (out < 1800)).any()
    # ... while nearest keeps the hole exactly the size of one low-res pixel
    n = nearest(v, 4)
    assert (n[0, 16:20, 16:20] == 0).all() and (n == 0).sum() == 16 * 4


@pytest.mark.parametrize("method", [nearest, bicubic])
def test_bad_input_raises(method):
    with pytest.raises(InputError, match="scale"):
        method(step_video(), 0)
    with pytest.raises(InputError, match="scale"):
        method(step_video(), 2.0)
    with pytest.raises(InputError, match="shape"):
        method(np.ones((2, 2, 2, 2)), 2)
    with pytest.raises(InputError, match="negative"):
        method(-step_video(), 2)


# ------------------------------------------------------------------------ bicubic, no flying
def test_noflying_removes_the_flying_pixels_of_bicubic():
    clean = dynamic_scene(n_frames=2, lowres_shape=(24, 32), scale=4, noise_sigma_mm=0, seed=1)
    assert metrics.flying_pixels(bicubic(clean.lowres, 4), clean.truth, 4) > 0.05
    out = bicubic_noflying(clean.lowres, 4)
    assert out.shape == clean.truth.shape and out.dtype == np.float32
    assert metrics.flying_pixels(out, clean.truth, 4) == 0.0
    # only edge pixels go: the surfaces keep their bicubic values
    assert metrics.missing(out, clean.truth) < 0.08
    kept = out > 0
    np.testing.assert_array_equal(out[kept], bicubic(clean.lowres, 4)[kept])
    noisy = dynamic_scene(n_frames=2, lowres_shape=(24, 32), scale=4, noise_sigma_mm=30, seed=1)
    fly_bicubic = metrics.flying_pixels(bicubic(noisy.lowres, 4), noisy.truth, 4)
    assert metrics.flying_pixels(bicubic_noflying(noisy.lowres, 4), noisy.truth, 4) < (
        0.1 * fly_bicubic
    )


def test_noflying_threshold_rule():
    step = np.full((6, 8), 2500.0, np.float32)
    step[:, :4] = 1000.0
    b = bicubic(step, 4)
    out = bicubic_noflying(step, 4, threshold_mm=100.0)
    between = (b > 1100) & (b < 2400)
    assert between.any() and (out[between] == 0).all()
    kept = out[out > 0]
    assert (np.minimum(np.abs(kept - 1000.0), np.abs(kept - 2500.0)) <= 100.0).all()
    # a larger threshold keeps more, a constant image is kept whole
    assert (bicubic_noflying(step, 4, threshold_mm=1000.0) > 0).sum() > (out > 0).sum()
    const = np.full((5, 5), 1500.0, np.float32)
    np.testing.assert_allclose(bicubic_noflying(const, 3), 1500.0, rtol=1e-6)
    with pytest.raises(InputError, match="threshold"):
        bicubic_noflying(step, 4, threshold_mm=0.0)


# ------------------------------------------------------------------------------------------ JBU
@pytest.mark.parametrize("edge", [18, 21, 22, 23])
def test_jbu_snaps_edges_to_the_guide(edge):
    r, fg, bg = 4, 1000.0, 2500.0
    cols = np.arange(12 * r)
    lowres = np.where((np.arange(12) + 0.5) * r - 0.5 < edge, fg, bg)
    lowres = np.repeat(lowres[None, :], 8, axis=0).astype(np.float32)
    guide = np.where(cols < edge, 50, 200).astype(np.uint8)
    guide = np.repeat(guide[None, :], 8 * r, axis=0)
    out = joint_bilateral_upsampling(lowres, r, guide, sigma_spatial_px=4.0, sigma_range=10.0)
    assert out.shape == (8 * r, 12 * r) and out.dtype == np.float32
    np.testing.assert_allclose(out[:, :edge], fg, atol=1.0)
    np.testing.assert_allclose(out[:, edge:], bg, atol=1.0)
    # nearest upsampling puts the edge on the low-res block border instead
    if edge % r:
        assert np.abs(nearest(lowres, r) - np.where(cols < edge, fg, bg)).max() > 1000
    # without a guide edge, the depth edge is blurred (weighted average across it)
    flat = joint_bilateral_upsampling(lowres, r, np.zeros_like(guide), sigma_spatial_px=4.0)
    assert ((flat > fg + 150) & (flat < bg - 150)).any()


def test_jbu_invalid_samples_have_no_weight_and_video_works():
    lowres = np.full((2, 6, 6), 2000.0, np.float32)
    lowres[0, 3, 3] = 0.0
    lowres[1] = 0.0
    guide = np.random.default_rng(0).uniform(0, 1, (2, 18, 18, 3))
    out = joint_bilateral_upsampling(lowres, 3, guide)
    assert out.shape == (2, 18, 18)
    np.testing.assert_allclose(out[0], 2000.0, rtol=1e-6)  # the hole is not pulled to 0
    assert (out[1] == 0).all()  # nothing valid: unknown
    with pytest.raises(InputError, match="guide"):
        joint_bilateral_upsampling(lowres[0], 3, guide[0, :17])
    with pytest.raises(InputError, match="2 guide images"):
        joint_bilateral_upsampling(lowres, 3, guide[0, ..., 0])
