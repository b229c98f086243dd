"""Single-frame baselines of paper §7: nearest and naive bicubic upsampling."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.baselines import bicubic, nearest
from upsr.errors import InputError
from upsr.upsampling import upsample_nearest

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
