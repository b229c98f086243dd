"""Synthetic dynamic scenes: shapes, determinism, noise law, pixel geometry (SPEC §1)."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.research.synth import DynamicScene, SyntheticVideo, dynamic_scene, make_scene


def excess_kurtosis(x: np.ndarray) -> float:
    x = x - x.mean()
    return float(np.mean(x**4) / np.mean(x**2) ** 2 - 3.0)


def test_shapes_and_dtypes():
    v = dynamic_scene(n_frames=5, lowres_shape=(24, 32), scale=4, noise_sigma_mm=10.0)
    assert isinstance(v, SyntheticVideo) and isinstance(v.scene, DynamicScene)
    assert v.lowres.shape == v.lowres_clean.shape == (5, 24, 32)
    assert v.truth.shape == (5, 96, 128)
    assert v.lowres.dtype == v.lowres_clean.dtype == v.truth.dtype == np.float32
    assert v.scale == 4 and v.noise_sigma_mm == 10.0 and v.n_frames == 5


def test_depth_ranges_wall_and_object():
    v = dynamic_scene(n_frames=4, noise_sigma_mm=0.0)
    t = v.truth
    assert (t > 0).all()  # the wall is everywhere behind the object
    wall = t[t > 2200]
    obj = t[t < 2200]
    assert 2500 <= wall.min() and wall.max() <= 3000
    assert 1200 <= obj.min() and obj.max() <= 1800
    # the object covers a sizeable but partial part of the image
    assert 0.05 < (t < 2200).mean() < 0.5


def test_deterministic_with_seed():
    a = dynamic_scene(n_frames=3, lowres_shape=(16, 20), seed=7, dropout=0.1)
    b = dynamic_scene(n_frames=3, lowres_shape=(16, 20), seed=7, dropout=0.1)
    c = dynamic_scene(n_frames=3, lowres_shape=(16, 20), seed=8, dropout=0.1)
    np.testing.assert_array_equal(a.lowres, b.lowres)
    np.testing.assert_array_equal(a.truth, b.truth)
    assert not np.array_equal(a.lowres, c.lowres)


def test_noise_is_laplacian_with_requested_std():
    sigma = 25.0
    v = dynamic_scene(n_frames=12, lowres_shape=(96, 128), scale=1, noise_sigma_mm=sigma)
    noise = (v.lowres - v.lowres_clean).astype(np.float64).ravel()
    assert noise.size > 100_000
    assert abs(noise.mean()) < 0.5
    assert noise.std() == pytest.approx(sigma, rel=0.03)
    assert excess_kurtosis(noise) == pytest.approx(3.0, abs=0.5)  # Gaussian would give 0
    # the truth is noise-free
    np.testing.assert_array_equal(v.truth, v.lowres_clean)


def test_no_noise_means_clean_input():
    v = dynamic_scene(n_frames=2, lowres_shape=(16, 16), noise_sigma_mm=0.0)
    np.testing.assert_array_equal(v.lowres, v.lowres_clean)


def test_background_none_gives_no_return():
    v = dynamic_scene(n_frames=3, lowres_shape=(24, 32), background="none", noise_sigma_mm=30.0)
    for arr in (v.truth, v.lowres_clean):
        assert (arr == 0).mean() > 0.5  # most of the view is empty
        assert arr[arr > 0].max() <= 1800  # only the object remains
    # noise is added to valid pixels only: empty stays empty, valid stays valid
    np.testing.assert_array_equal(v.lowres == 0, v.lowres_clean == 0)
    w = dynamic_scene(n_frames=3, lowres_shape=(24, 32), background="wall", noise_sigma_mm=30.0)
    np.testing.assert_array_equal(v.truth[v.truth > 0], w.truth[v.truth > 0])


def test_scale_one_samples_like_the_truth():
    v = dynamic_scene(n_frames=3, lowres_shape=(20, 24), scale=1)
    np.testing.assert_array_equal(v.truth, v.lowres_clean)


def test_odd_scale_lowres_centre_is_a_highres_pixel_centre():
    # SPEC §1: low-res pixel i sits at high-res coordinate (i + 0.5)·r − 0.5 = 3i + 1 for r = 3
    v = dynamic_scene(n_frames=3, lowres_shape=(20, 24), scale=3)
    np.testing.assert_array_equal(v.truth[:, 1::3, 1::3], v.lowres_clean)


def test_even_scale_lowres_centre_between_highres_centres():
    # r = 4: the low-res centre is at 4i + 1.5, the mean of high-res rows/cols 4i+1, 4i+2.
    # On the (planar) wall the low-res depth is the mean of those four high-res pixels.
    r = 4
    v = dynamic_scene(n_frames=2, lowres_shape=(24, 32), scale=r, noise_sigma_mm=0.0)
    t = v.truth.astype(np.float64)
    quad = (t[:, 1::r, 1::r] + t[:, 1::r, 2::r] + t[:, 2::r, 1::r] + t[:, 2::r, 2::r]) / 4
    wall = np.ones(v.lowres_clean.shape, bool)
    for dy in range(r):
        for dx in range(r):
            wall &= t[:, dy::r, dx::r] > 2400
    assert wall.mean() > 0.4
    np.testing.assert_allclose(v.lowres_clean[wall], quad[wall], atol=0.01)
    # a half-pixel shift would be off by about half a high-res pixel of wall slope
    off = (t[:, 2::r, 2::r])[wall]
    assert np.abs(off - v.lowres_clean[wall]).mean() > 0.5


def test_lowres_pixel_equals_scene_at_its_centre():
    v = dynamic_scene(n_frames=4, lowres_shape=(24, 32), scale=4)
    h, w = 24, 32
    yy, xx = np.mgrid[0:h, 0:w]
    for t in range(4):
        expected = v.scene.depth_at(t, yy + 0.5, xx + 0.5).astype(np.float32)
        np.testing.assert_array_equal(v.lowres_clean[t], expected)
        k = np.arange(4 * h)
        hr = v.scene.depth_at(t, (k[:, None] + 0.5) / 4, (np.arange(4 * w)[None] + 0.5) / 4)
        np.testing.assert_array_equal(v.truth[t], hr.astype(np.float32))


def test_motion_is_subpixel_and_nonrigid():
    scene = make_scene((48, 64), n_frames=9, motion_px=1.5, seed=0)
    states = np.array([scene.blob_state(t) for t in range(9)])
    steps = np.hypot(np.diff(states[:, 0]), np.diff(states[:, 1]))
    np.testing.assert_allclose(steps, 1.5, rtol=1e-9)  # constant speed, no bounce here
    assert not np.allclose(states[:, 1], np.round(states[:, 1]))  # non-integer positions
    assert np.ptp(states[:, 2]) > 1.0  # the radii breathe
    v = dynamic_scene(n_frames=9, noise_sigma_mm=0.0, seed=0)
    # the object's shape changes: its pixel count is not constant
    counts = (v.truth < 2200).sum(axis=(1, 2))
    assert np.ptp(counts) > 0.02 * counts.mean()


def test_dropout_and_flying_pixels_options():
    v = dynamic_scene(n_frames=4, lowres_shape=(32, 32), dropout=0.2, noise_sigma_mm=0.0)
    assert (v.lowres == 0).mean() == pytest.approx(0.2, abs=0.03)
    assert (v.lowres_clean > 0).all()
    f = dynamic_scene(n_frames=4, lowres_shape=(32, 32), flying_pixels=1.0, noise_sigma_mm=0.0)
    mixed = f.lowres != f.lowres_clean
    assert mixed.any()
    # mixed pixels take depths between foreground and background
    assert ((f.lowres[mixed] > 1850) & (f.lowres[mixed] < 2450)).any()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"background": "sky"}, "background"),
        ({"scale": 0}, "scale"),
        ({"scale": 2.5}, "scale"),
        ({"n_frames": 0}, "n_frames"),
        ({"noise_sigma_mm": -1.0}, "noise_sigma_mm"),
        ({"dropout": 1.5}, "fraction"),
        ({"lowres_shape": (4, 4)}, "lowres_shape"),
        ({"lowres_shape": 32}, "lowres_shape"),
        ({"motion_px": float("nan")}, "motion_px"),
        ({"seed": -1}, "seed"),
    ],
)
def test_bad_parameters_raise_input_error(kwargs, match):
    with pytest.raises(InputError, match=match):
        dynamic_scene(**kwargs)
