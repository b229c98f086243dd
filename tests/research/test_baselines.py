"""Single-frame baselines of paper §7: nearest, naive bicubic and patch-based SISR."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.method.upsampling import upsample_nearest
from upsr.research.baselines import PatchSISR, bicubic, nearest, patch_sisr, train_patch_sisr

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


# ----------------------------------------------------------------------------------- patch SISR
@pytest.fixture(scope="module")
def small_model():
    return train_patch_sisr(4, n_examples=3000, seed=0, lowres_shape=(12, 16))


def diagonal_step(near: float, far: float, h: int = 10, w: int = 12) -> np.ndarray:
    lr = np.full((h, w), near, np.float32)
    for i in range(h):
        lr[i, 5 + i // 3 :] = far
    return lr


def step_dictionary(height: float, r: int = 4, **kw) -> PatchSISR:
    """A dictionary of vertical steps of one height (every edge position, both directions)."""
    side = 3 * r
    lo, hi = [], []
    for cut in range(1, side):  # the edge between high-res columns cut − 1 and cut
        for sign in (1.0, -1.0):
            h_patch = np.where(np.arange(side) < cut, 0.0, sign * height)
            h_patch = np.broadcast_to(h_patch, (side, side))
            l_patch = h_patch[r // 2 :: r, r // 2 :: r]  # point samples at the low-res centres
            mean = l_patch.mean()
            lo.append((l_patch - mean).ravel())
            hi.append((h_patch - mean).ravel())
    return PatchSISR(r, np.array(lo), np.array(hi), k=2, **kw)


def test_patch_sisr_step_of_unseen_height_lands_on_the_two_surfaces():
    # The dictionary only knows 300 mm steps; shifted by the query's mean, a 300 mm step
    # put on a 1200 mm step lands between its surfaces unless the guard moves it back.
    near, far = 1500.0, 2700.0
    lr = diagonal_step(near, far)
    plain = step_dictionary(300.0, guard_connect_mm=None)(lr)
    assert ((plain > near + 200) & (plain < far - 200)).any()  # the cause: flying pixels
    out = step_dictionary(300.0, guard_margin_mm=0.0)(lr)
    assert set(np.unique(out)) <= {near, far}
    assert (out == near).any() and (out == far).any()


@pytest.mark.parametrize(("near", "far"), [(1000.0, 1150.0), (2000.0, 2450.0), (800.0, 5000.0)])
def test_patch_sisr_no_value_between_the_surfaces_of_a_step(small_model, near, far):
    out = small_model(diagonal_step(near, far))
    margin = small_model.guard_margin_mm
    assert not ((out > near + margin) & (out < far - margin)).any()
    assert out.min() >= near - margin and out.max() <= far + margin
    # the plain composition (no guard) does fly on these steps
    plain = PatchSISR(
        4, small_model.lowres_patches, small_model.highres_patches, guard_connect_mm=None
    )(diagonal_step(near, far))
    assert ((plain > near + margin) & (plain < far - margin)).any()


def test_patch_sisr_values_stay_on_the_surfaces_of_a_piecewise_constant_scene(small_model):
    rng = np.random.default_rng(3)
    levels = np.array([1000.0, 1700.0, 2900.0], np.float32)
    lr = levels[rng.integers(0, 3, (6, 8))].repeat(2, axis=0).repeat(2, axis=1)
    lr[0:3, 10:13] = 0.0  # a hole
    out = patch_sisr(lr, 4, model=small_model)
    valid = out > 0
    np.testing.assert_array_equal(valid, nearest(lr, 4) > 0)  # invalid stays invalid
    dist = np.abs(out[valid][:, None] - levels[None]).min(axis=1)
    assert dist.max() <= small_model.guard_margin_mm


def test_patch_sisr_removes_an_isolated_outlier(small_model):
    i, j = np.mgrid[0:10, 0:12]
    plane = (2000.0 + 20.0 * i + 12.0 * j).astype(np.float32)
    lr = plane.copy()
    lr[5, 6] += 400.0  # one noise outlier, 400 mm off its surface
    out = small_model(lr)
    y, x = np.mgrid[0:40, 0:48]
    truth = 2000.0 + 20.0 * ((y + 0.5) / 4 - 0.5) + 12.0 * ((x + 0.5) / 4 - 0.5)
    assert np.abs(out - truth).max() < 60.0
    # no guard: the outlier is reproduced
    plain = PatchSISR(
        4, small_model.lowres_patches, small_model.highres_patches, guard_connect_mm=None
    )(lr)
    assert np.abs(plain - truth).max() > 100.0


def test_patch_sisr_guard_keeps_slopes(small_model):
    # neighbouring samples 60 mm apart are one surface: values between them are allowed
    i, j = np.mgrid[0:10, 0:12]
    ramp = (2000.0 + 60.0 * j + 0.0 * i).astype(np.float32)
    out = small_model(ramp)
    x = np.arange(48)
    truth = 2000.0 + 60.0 * ((x + 0.5) / 4 - 0.5)
    inner = slice(4, 44)  # away from the clamped border
    assert np.abs(out[:, inner] - truth[inner]).max() < 30.0
    assert len(np.unique(np.round(out[20, inner]))) > 20  # not staircased to the samples


def test_patch_sisr_bad_guard_parameters(small_model):
    lo, hi = small_model.lowres_patches, small_model.highres_patches
    with pytest.raises(InputError, match="guard_margin_mm"):
        PatchSISR(4, lo, hi, guard_margin_mm=-1.0)
    with pytest.raises(InputError, match="guard_connect_mm"):
        PatchSISR(4, lo, hi, guard_connect_mm=float("nan"))
    with pytest.raises(InputError, match="guard_margin_mm"):
        train_patch_sisr(4, n_examples=10, guard_margin_mm=float("inf"))
