import numba as nb
import numpy as np
import pytest

from upsr.errors import InputError
from upsr.method.config import DeblurConfig
from upsr.method.deblurring import (
    btv_energy,
    btv_subgradient,
    deblur,
    deblur_energy,
    estimate_noise_mm,
    smooth_surfaces,
)


@pytest.mark.parametrize("edge_mm", [None, 100.0])
def test_btv_subgradient_matches_numerical_gradient(edge_mm):
    rng = np.random.default_rng(1)
    x = rng.uniform(1000, 1050, (9, 11))
    guide = x.copy()
    guide[4, 5] = 0  # an invalid pixel takes no part
    guide[:, 8:] += 500  # a depth edge (pairs across it are cut when edge_mm is set)
    eps = 1e-3
    grad = btv_subgradient(x, guide, radius_px=2, alpha=0.7, edge_mm=edge_mm)
    for i, j in [(0, 0), (4, 4), (4, 7), (8, 10), (2, 8), (5, 5)]:
        xp, xm = x.copy(), x.copy()
        xp[i, j] += eps
        xm[i, j] -= eps
        kw = {"radius_px": 2, "alpha": 0.7, "edge_mm": edge_mm}
        num = (btv_energy(xp, guide, **kw) - btv_energy(xm, guide, **kw)) / (2 * eps)
        expected = num if guide[i, j] > 0 else 0.0
        assert grad[i, j] == pytest.approx(expected, rel=1e-4, abs=1e-4)


def test_edge_rule_cuts_pairs_across_discontinuities():
    x = np.full((6, 6), 1000.0)
    x[:, 3:] = 2000.0
    g_plain = btv_subgradient(x, x, edge_mm=None)
    g_edge = btv_subgradient(x, x, edge_mm=100.0)
    assert np.abs(g_plain[:, 2]).max() > 0
    assert np.abs(g_edge).max() == 0


def _noisy_step(seed=0, sigma=20.0):
    rng = np.random.default_rng(seed)
    truth = np.full((40, 40), 1500.0, np.float32)
    truth[:, 20:] = 2500.0
    truth[:3, :3] = 0.0
    z = truth + rng.laplace(0, sigma / np.sqrt(2), truth.shape).astype(np.float32)
    z[truth == 0] = 0
    return truth, z


def test_deblur_denoises_keeps_edges_and_invalid():
    truth, z = _noisy_step()
    cfg = DeblurConfig()
    x = deblur(z, cfg, scale=2)
    valid = truth > 0
    err_in = np.sqrt(np.mean((z - truth)[valid] ** 2))
    err_out = np.sqrt(np.mean((x - truth)[valid] ** 2))
    assert err_out < 0.6 * err_in
    assert (x[~valid] == 0).all() and (x[valid] > 0).all()
    # no depth between the two surfaces appears
    assert not ((x > 1700) & (x < 2300)).any()
    assert deblur_energy(x, z, cfg) < deblur_energy(z, z, cfg)


@pytest.mark.parametrize("blur", ["box", "gaussian"])
def test_blur_models_decrease_energy(blur):
    _, z = _noisy_step(1)
    cfg = DeblurConfig(blur=blur, iterations=20)
    x = deblur(z, cfg, scale=2)
    assert deblur_energy(x, z, cfg, scale=2) < deblur_energy(z, z, cfg, scale=2)
    assert (x[z == 0] == 0).all()


def test_disabled_or_empty_is_identity():
    _, z = _noisy_step()
    np.testing.assert_array_equal(deblur(z, DeblurConfig(enabled=False)), z)
    np.testing.assert_array_equal(deblur(np.zeros((5, 5), np.float32)), 0)


def test_noise_estimate():
    rng = np.random.default_rng(3)
    z = 2000 + rng.normal(0, 10, (200, 200)).astype(np.float32)
    assert estimate_noise_mm(z) == pytest.approx(10, rel=0.1)


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
