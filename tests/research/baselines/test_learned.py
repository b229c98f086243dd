"""Patch-based single-image SR after Mac Aodha et al. 2012 (upsr.research.baselines.learned)."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.rendering import render_depth
from upsr.research import metrics
from upsr.research.baselines import (
    PatchSISR,
    nearest,
    patch_sisr,
    train_patch_sisr,
)
from upsr.research.synth import dynamic_scene
from upsr.research.synth.degradation import add_laplacian_noise


def _box(centre, size, angle):
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    ca, sa = np.cos(angle), np.sin(angle)
    rot = np.array([[ca, 0, sa], [0, 1, 0], [-sa, 0, ca]])
    faces = np.array(
        "0 1 3 0 3 2 4 6 7 4 7 5 0 4 5 0 5 1 2 3 7 2 7 6 0 2 6 0 6 4 1 5 7 1 7 3".split(), int
    ).reshape(-1, 3)
    return (corners * 0.5 * np.asarray(size)) @ rot.T + np.asarray(centre), faces


def _planar_scene(r: int):
    """A held-out piecewise-planar scene (three boxes before a slanted wall): (low-res, truth)."""
    cam = PinholeCamera.from_fov(40, 32, 55.0)
    parts = [
        _box((-0.35, 0.1, 1.8), (0.5, 0.7, 0.4), 0.5),
        _box((0.4, -0.15, 2.3), (0.6, 0.4, 0.5), -0.3),
        _box((0.05, 0.35, 1.4), (0.3, 0.2, 0.3), 0.9),
    ]
    verts = np.concatenate([p[0] for p in parts])
    faces = np.concatenate([p[1] + 8 * i for i, p in enumerate(parts)])
    wall = (np.array([0.2, -0.1, 1.0]), 3000.0)
    lr = render_depth(verts, faces, cam, background_mm=wall)
    hr = render_depth(verts, faces, cam.scaled(r), background_mm=wall)
    return lr, hr


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


# ----------------------------------------------------------------------------------- patch SISR
@pytest.fixture(scope="module")
def model():
    return train_patch_sisr(4, n_examples=30000, seed=0)


def test_patch_sisr_shape_and_determinism(model):
    assert isinstance(model, PatchSISR) and model.scale == 4 and model.n_examples == 30000
    again = train_patch_sisr(4, n_examples=30000, seed=0)
    np.testing.assert_array_equal(again.lowres_patches, model.lowres_patches)
    np.testing.assert_array_equal(again.highres_patches, model.highres_patches)
    other = train_patch_sisr(4, n_examples=30000, seed=1)
    assert not np.array_equal(other.lowres_patches, model.lowres_patches)
    v = dynamic_scene(n_frames=2, lowres_shape=(12, 16), scale=4, noise_sigma_mm=10, seed=0)
    out = patch_sisr(v.lowres, 4, model=model)
    assert out.shape == (2, 48, 64) and out.dtype == np.float32
    np.testing.assert_array_equal(out, patch_sisr(v.lowres, 4, model=again))
    np.testing.assert_array_equal(out[1], model(v.lowres[1]))
    with pytest.raises(InputError, match="r = 4"):
        patch_sisr(v.lowres, 2, model=model)


def test_patch_sisr_beats_nearest_on_a_held_out_planar_scene(model):
    lr, truth = _planar_scene(4)
    for sigma in (0.0, 20.0):
        x = add_laplacian_noise(lr, sigma, np.random.default_rng(1))
        m_ps = metrics.evaluate(patch_sisr(x, 4, model=model), truth, 4)
        m_nn = metrics.evaluate(nearest(x, 4), truth, 4)
        assert m_ps["surface_rmse"] < 0.7 * m_nn["surface_rmse"]
        assert m_ps["rmse"] < m_nn["rmse"]
        assert m_ps["flying_pixels"] < 0.02 and m_ps["missing"] == 0.0


def test_patch_sisr_keeps_holes():
    lr, _ = _planar_scene(2)
    lr = lr.copy()
    lr[10:14, 5:9] = 0.0
    out = patch_sisr(lr, 2, model=train_patch_sisr(2, n_examples=5000, seed=0))
    assert (out[20:28, 10:18] == 0).all()
    assert ((out > 0) == (nearest(lr, 2) > 0)).all()


def test_train_patch_sisr_bad_input():
    with pytest.raises(InputError, match="n_examples"):
        train_patch_sisr(2, n_examples=0)
