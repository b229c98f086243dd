"""The edge-preserving surface smoothing along each surface's plane (upsr.method.smoothing)."""

import numba as nb
import numpy as np
import pytest

from upsr.errors import InputError
from upsr.method.smoothing import SAME_SURFACE_SIGMAS, smooth_surfaces


def _slope_exact(a, p, m, s, b, tol):
    dp, dm = (p - a) * s, (a - m) * s
    if p > 0 and m > 0 and abs(dp - dm) < tol:
        return (p - m) / (2 * b)
    if p > 0 and m <= 0 and abs(dp) < tol:
        return (p - a) / b
    if m > 0 and p <= 0 and abs(dm) < tol:
        return (a - m) / b
    return 0.0


def _plane_bilateral_exact(x, sigma_mm, sigma_px, b, edge_mm=None):
    """The filter in float64, pixel by pixel, as its docstring states it: inverse depth
    w = 10⁶/z, each neighbour carried along the gradient of w, exact exponentials."""
    x = np.where(np.isfinite(x) & (x > 0), x, 0.0).astype(np.float64)
    w = np.where(x > 0, 1e6 / np.where(x > 0, x, 1.0), 0.0)
    radius = int(np.ceil(2 * sigma_px))
    h, wd = x.shape
    tol = SAME_SURFACE_SIGMAS * sigma_mm if edge_mm is None else edge_mm

    def at(i, j):
        return w[i, j] if 0 <= i < h and 0 <= j < wd else 0.0

    out = np.zeros_like(x)
    for i in range(h):
        for j in range(wd):
            if x[i, j] <= 0:
                continue
            s = x[i, j] ** 2 / 1e6
            gy = _slope_exact(w[i, j], at(i + b, j), at(i - b, j), s, b, tol)
            gx = _slope_exact(w[i, j], at(i, j + b), at(i, j - b), s, b, tol)
            num = den = 0.0
            for dy in range(-radius, radius + 1):
                for dx in range(-radius, radius + 1):
                    if dy * dy + dx * dx > radius * radius or at(i + dy, j + dx) <= 0:
                        continue
                    pred = at(i + dy, j + dx) - gy * dy - gx * dx
                    e = (pred - w[i, j]) * s
                    wt = np.exp(-(dy * dy + dx * dx) / (2 * sigma_px**2))
                    wt *= np.exp(-(e**2) / (2 * sigma_mm**2))
                    num += wt * pred
                    den += wt
            out[i, j] = 1e6 / (num / den)
    return out


def _pinhole_plane(shape, z0_mm, per_row, per_col):
    """Depth (mm) of a plane seen by a pinhole camera: 1/z affine in the pixel."""
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float64)
    return 1.0 / (1.0 / z0_mm + per_row * ys + per_col * xs)


def _two_surfaces(shape=(23, 31), seed=5):
    rng = np.random.default_rng(seed)
    xs = np.mgrid[0 : shape[0], 0 : shape[1]][1]
    x = (1500.0 + 3.0 * xs + rng.normal(0.0, 20.0, shape)).astype(np.float32)
    x[:, shape[1] // 2 :] += 400.0  # a depth edge
    x[rng.random(shape) < 0.15] = 0.0  # holes
    return x


@pytest.mark.parametrize(
    ("sigma_px", "baseline_px", "edge_mm"), [(0.6, 1, None), (2.0, 4, None), (3.0, 2, 100.0)]
)
def test_smooth_surfaces_matches_its_definition(sigma_px, baseline_px, edge_mm):
    x = _two_surfaces()
    x[:, :6] = _pinhole_plane((x.shape[0], 6), 1200.0, 2e-6, -3e-5)  # a steep plane
    x[3, 4] = np.nan
    x[5, 6] = -7.0
    x[7, 8] = np.inf
    before = x.copy()
    out = smooth_surfaces(x, 30.0, sigma_px, baseline_px=baseline_px, edge_mm=edge_mm)
    expected = _plane_bilateral_exact(x, 30.0, sigma_px, baseline_px, edge_mm)
    np.testing.assert_array_equal(x, before, strict=True)  # input untouched
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out == 0, expected == 0)  # invalid stays 0, nothing new
    np.testing.assert_allclose(out, expected, atol=0.01, rtol=0)
    # the foreground never takes depth from across the edge
    left = expected > 0
    left[:, x.shape[1] // 2 :] = False
    assert out[left].max() < 1500.0 + 3.0 * x.shape[1] + 100.0


def test_a_steep_plane_keeps_its_depth_and_loses_its_noise():
    # a floor seen at a grazing angle: 1.9 → 4.3 m over 40 rows, 27–133 mm per pixel
    truth = _pinhole_plane((40, 48), 1900.0, -7.5e-6, 1e-7)
    assert 25 < np.diff(truth, axis=0).min() and np.diff(truth, axis=0).max() < 135
    inner = (slice(4, -4), slice(4, -4))
    exact = smooth_surfaces(truth, 30.0, 2.0, baseline_px=4)
    np.testing.assert_allclose(exact[inner], truth[inner], atol=0.05)  # a plane stays a plane
    noisy = truth + np.random.default_rng(3).normal(0.0, 10.0, truth.shape)
    out = smooth_surfaces(noisy, 30.0, 2.0, baseline_px=4)
    rms_in = np.sqrt(np.mean((noisy - truth)[inner] ** 2))
    rms_out = np.sqrt(np.mean((out - truth)[inner] ** 2))
    # about the 12 neighbours' worth of a window of σ = 2 px: the plain bilateral filter of
    # the depth gives a neighbour 30–170 mm off almost no weight (rms_out ≈ 0.9 rms_in)
    assert rms_out < 0.4 * rms_in


def test_a_crease_is_not_rounded():
    # two planes meeting at a ridge (1/z piecewise affine, about ±25 mm per pixel): the
    # pixels beside it keep their own plane's depth
    xs = np.arange(40, dtype=np.float64)
    inverse = np.where(xs < 20, 1 / 2000.0 - 5e-6 * xs, 1 / 2000.0 - 5e-6 * (40 - xs))
    x = np.repeat(1.0 / inverse[None], 12, axis=0)
    out = smooth_surfaces(x, 10.0, 2.0, baseline_px=4)
    np.testing.assert_allclose(out[:, 4:16], x[:, 4:16], atol=0.05)
    np.testing.assert_allclose(out[:, 24:36], x[:, 24:36], atol=0.05)
    assert np.abs(out[:, 20] - x[:, 20]).max() < 10.0  # the ridge itself: a few mm at most


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
    with pytest.raises(InputError, match="baseline_px"):
        smooth_surfaces(np.ones((4, 4), np.float32), 30.0, 2.0, baseline_px=0)
    with pytest.raises(InputError, match="baseline_px"):
        smooth_surfaces(np.ones((4, 4), np.float32), 30.0, 2.0, baseline_px=1.5)
    with pytest.raises(InputError, match="edge_mm"):
        smooth_surfaces(np.ones((4, 4), np.float32), 30.0, 2.0, edge_mm=0.0)


def test_a_pixel_beside_an_edge_takes_no_slope_towards_it():
    # a row between a near surface (above) and a far one (below), 150 mm from the far one:
    # its step towards the far side is no slope of a surface (it may be a mix of the two);
    # smoothed as a plain bilateral filter it keeps its depth
    x = np.full((15, 20), 4500.0, np.float32)
    x[:7] = 3900.0
    x[7] = 4350.0
    out = smooth_surfaces(x, 30.0, 2.0, baseline_px=4, edge_mm=350.0)
    np.testing.assert_allclose(out[7], 4350.0, atol=0.01)
    # at the frame's border (no depth beyond it) the one side's slope is used
    ramp = (2000.0 + 20.0 * np.arange(20, dtype=np.float32))[None].repeat(9, axis=0)
    noisy = ramp + np.random.default_rng(1).normal(0.0, 5.0, ramp.shape).astype(np.float32)
    out = smooth_surfaces(noisy, 30.0, 2.0, baseline_px=4, edge_mm=350.0)
    assert np.abs(out[:, :2] - ramp[:, :2]).mean() < np.abs(noisy[:, :2] - ramp[:, :2]).mean()


def test_smooth_output_follows_the_deblurring_settings():
    from upsr.method.config import DeblurConfig
    from upsr.method.smoothing import smooth_output

    x = _two_surfaces((20, 24), seed=3)
    cfg = DeblurConfig()
    np.testing.assert_array_equal(
        smooth_output(x, cfg, 4),
        smooth_surfaces(x, cfg.smooth_sigma_mm, 2.0, baseline_px=4, edge_mm=cfg.edge_mm),
    )
    np.testing.assert_array_equal(
        smooth_output(x, cfg, 2, edge_mm=50.0),
        smooth_surfaces(x, cfg.smooth_sigma_mm, 1.0, baseline_px=2, edge_mm=50.0),
    )
    for off in (DeblurConfig(smooth_sigma_mm=None), DeblurConfig(enabled=False)):
        assert smooth_output(x, off, 4) is x
