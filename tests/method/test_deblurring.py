import numpy as np
import pytest

from upsr.method.config import DeblurConfig
from upsr.method.deblurring import (
    btv_energy,
    btv_subgradient,
    deblur,
    deblur_energy,
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


def test_deblur_checks_its_image_and_takes_a_mapping_of_options():
    """deblur(-z) returned negative depth and deblur(z, {"lam": 0.1}) an AttributeError."""
    from upsr.errors import InputError

    z = np.full((12, 14), 1500.0, np.float32)
    z[4:8, 4:8] = 1000.0
    with pytest.raises(InputError, match="negative"):
        deblur(-z)
    with pytest.raises(InputError, match="2-D depth frame"):
        deblur(z[None])
    with pytest.raises(InputError, match="lamda"):
        deblur(z, {"lamda": 0.1})
    with pytest.raises(InputError, match="DeblurConfig or a mapping"):
        deblur(z, 0.1)
    np.testing.assert_array_equal(deblur(z, {"lam": 0.1}), deblur(z, DeblurConfig(lam=0.1)))


def test_steep_noise_profiles_neither_diverge_nor_write_micrometres():
    """A noise profile (p = 4) gave a surface 12 times deeper than the rest steps 20 736
    times the typical one: the descent left it at the 1e-3 mm clamp. The steps are capped
    (16 times the typical one) and a pixel taken to 0 or below keeps the fused depth."""
    rng = np.random.default_rng(0)
    z = np.full((40, 40), 1000.0, np.float32)
    z[:, 30:] = 12000.0
    z += rng.normal(0, 1.0, z.shape).astype(np.float32)
    out = deblur(z, DeblurConfig(), noise_profile=(1.0, 4.0))
    assert (out > 0).all()
    assert np.abs(out[:, 32:] - 12000.0).max() < 100.0
    assert np.abs(out[:, :28] - 1000.0).max() < 10.0


def test_a_plane_sloping_across_the_border_is_not_pulled_inwards():
    """The staircase of a plane's r×r blocks (70 mm per block down, 5 across, r = 4): cut off
    by the border, every BTV pair of a border block pulled it towards the inside, the first
    and last rows of blocks 4.9 mm (8.0 at the corners) after the 15 steps. On the image
    extended by its odd reflection about the outermost blocks' centres, where the step
    across the border exceeds 4 β₀ (the 70 mm one, not the 5 mm one), the pairs are balanced
    there too: those rows keep their means; the columns keep the one-sided border (1.7 mm)."""
    ys, xs = np.mgrid[0:12, 0:14].astype(np.float32)
    low = 1800.0 + 70.0 * ys + 5.0 * xs
    z = np.repeat(np.repeat(low, 4, axis=0), 4, axis=1)
    x = deblur(z, DeblurConfig(smooth_sigma_mm=None, step_mm=10.0), scale=4)
    assert x.shape == z.shape
    means = x.reshape(12, 4, 14, 4).mean(axis=(1, 3))
    np.testing.assert_allclose(means[:, 1:-1], low[:, 1:-1], atol=0.6, rtol=0)
    np.testing.assert_allclose(np.abs(means - low)[:, [0, -1]], 1.69, atol=0.05)
    # an image smaller than a block and P in one direction: no margin there, still in place
    for shape in ((5, 3), (3, 9)):
        flat = np.full(shape, 1500.0, np.float32)
        np.testing.assert_allclose(deblur(flat, DeblurConfig(), scale=4), flat, atol=0.01)
