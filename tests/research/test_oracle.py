"""The plain NumPy references (upsr.research.oracle) compute what the compiled kernels compute."""

import dataclasses

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.method.config import DeblurConfig
from upsr.method.deblurring import btv_subgradient, deblur
from upsr.method.fusion import temporal_median
from upsr.method.noise import estimate_noise_mm
from upsr.research.oracle import (
    btv_subgradient_numpy,
    deblur_numpy,
    estimate_noise_mm_numpy,
    temporal_median_numpy,
)


def _random_stack(rng: np.random.Generator, n: int, h: int = 24, w: int = 20) -> np.ndarray:
    """Two surfaces 500 mm apart (noisy, some pixels mixing both), no-returns and outsides."""
    base = np.where(rng.random((h, w)) < 0.5, 1000.0, 1500.0)
    stack = base + rng.normal(0.0, 5.0, (n, h, w))
    flip = rng.random((n, h, w)) < 0.3  # samples from the other surface
    stack[flip] = (2500.0 - base + rng.normal(0.0, 5.0, (n, h, w)))[flip]
    stack[rng.random((n, h, w)) < 0.15] = 0.0
    stack[rng.random((n, h, w)) < 0.15] = np.nan
    stack[:, :2, :2] = np.nan  # all outside
    stack[:, -2:, -2:] = 0.0  # all no return
    return stack.astype(np.float32)


def _assert_same_fusion(expected: np.ndarray, actual: np.ndarray) -> None:
    np.testing.assert_array_equal(expected == 0, actual == 0)
    np.testing.assert_allclose(actual, expected, atol=1e-3, rtol=0)


@pytest.mark.parametrize("n", range(1, 11))
def test_temporal_median_matches_kernel(n):
    rng = np.random.default_rng(100 + n)
    stack = _random_stack(rng, n)
    weights = rng.uniform(0.2, 2.0, stack.shape).astype(np.float32)
    guide = np.where(rng.random(stack.shape[1:]) < 0.5, 1000.0, 1500.0).astype(np.float32)
    guide[rng.random(guide.shape) < 0.2] = 0.0
    cases = [
        {},
        {"weights": weights},
        {"weights": weights, "guide": guide},
        {"guide": guide, "guide_bonus": 0.6, "min_valid_fraction": 0.3, "ref": 0},
        {"weights": weights, "edge_mm": 3.0, "ref": n - 1},
    ]
    for kw in cases:
        _assert_same_fusion(temporal_median(stack, **kw), temporal_median_numpy(stack, **kw))


def test_temporal_median_ties_follow_the_reference():
    # validity: 2 valid of 4 in-frame samples, the reference decides
    s = np.array([1000.0, 1002.0, 0.0, 0.0, np.nan], np.float32)
    assert temporal_median_numpy(s[:, None, None], ref=0)[0, 0] == 1001.0
    assert temporal_median_numpy(s[:, None, None], ref=2)[0, 0] == 0.0
    # surfaces: two votes against two, the reference's surface wins, either side
    s = np.array([1000.0, 1002.0, 2000.0, 2004.0], np.float32)[:, None, None]
    assert temporal_median_numpy(s, ref=0)[0, 0] == 1001.0
    assert temporal_median_numpy(s, ref=3)[0, 0] == 2002.0
    for ref in (0, 3):
        assert temporal_median(s, ref=ref)[0, 0] == temporal_median_numpy(s, ref=ref)[0, 0]


def test_temporal_median_guide_bonus_decides_the_surface():
    s = np.array([1000.0, 1001.0, 1002.0, 2000.0, 2004.0], np.float32)[:, None, None]
    assert temporal_median_numpy(s, ref=3)[0, 0] == 1001.0  # 3 votes against 2
    guide = np.full((1, 1), 2010.0, np.float32)  # within edge_mm of the far surface
    kw = {"ref": 0, "guide": guide, "guide_bonus": 0.35}  # 2 + 0.35 * 5 > 3
    assert temporal_median_numpy(s, **kw)[0, 0] == 2002.0
    assert temporal_median(s, **kw)[0, 0] == 2002.0
    kw["guide_bonus"] = 0.1  # 2 + 0.5 < 3
    assert temporal_median_numpy(s, **kw)[0, 0] == 1001.0


def test_temporal_median_nothing_known_is_zero():
    stack = np.full((3, 2, 2), np.nan, np.float32)
    stack[:, 1, 1] = 0.0  # no return everywhere
    stack[1, 0, 1] = 1234.0  # one valid in-frame sample among outsides
    out = temporal_median_numpy(stack)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, [[0.0, 1234.0], [0.0, 0.0]])
    np.testing.assert_array_equal(out, temporal_median(stack))


def _random_image(rng: np.random.Generator, h: int = 17, w: int = 19):
    x = rng.uniform(1000.0, 1050.0, (h, w)).astype(np.float32)
    guide = x + rng.normal(0.0, 2.0, (h, w)).astype(np.float32)
    guide[:, w // 2 :] += 500.0  # a depth edge
    guide[rng.random((h, w)) < 0.15] = 0.0  # invalid pixels
    x[rng.random((h, w)) < 0.1] = 1025.0  # some ties
    return x, guide


@pytest.mark.parametrize("radius", [1, 2, 3])
@pytest.mark.parametrize("edge_mm", [None, 100.0])
def test_btv_subgradient_matches_kernel(radius, edge_mm):
    rng = np.random.default_rng(7 * radius)
    x, guide = _random_image(rng)
    kw = {"radius_px": radius, "alpha": 0.7, "edge_mm": edge_mm}
    ref = btv_subgradient_numpy(x, guide, **kw)
    assert ref.dtype == np.float32
    assert np.all(ref[guide <= 0] == 0)
    np.testing.assert_allclose(ref, btv_subgradient(x, guide, **kw), atol=1e-4, rtol=0)


@pytest.mark.parametrize("scale", [1, 2, 4])
def test_deblur_matches_kernel_on_a_surface_sloping_across_the_border(scale):
    """The descent on the image extended by its odd reflection (a floor stepping 60 mm per
    row, beyond 4 β₀): the reference and the kernel extend it alike."""
    rng = np.random.default_rng(scale)
    ys, xs = np.mgrid[0:24, 0:28].astype(np.float32)
    z = 1500.0 + 60.0 * ys + 2.0 * xs + rng.normal(0.0, 3.0, ys.shape).astype(np.float32)
    z[rng.random(z.shape) < 0.05] = 0.0
    cfg = DeblurConfig(iterations=10, smooth_sigma_mm=None)
    expected = deblur(z, cfg, scale=scale)
    actual = deblur_numpy(z, cfg, scale=scale)
    np.testing.assert_array_equal(actual == 0, z == 0)
    err = np.abs(actual - expected)
    assert np.mean(err > 0.05) < 0.03 and err.max() < 1.0
    if scale > 1:  # (at r = 1 the noise estimate of this image is 23 mm: a step of 4 β₀)
        # the border rows moved as the inside ones (no inward pull of the slope)
        assert abs(float(np.median((actual - z)[[0, -1]][z[[0, -1]] > 0]))) < 1.0


@pytest.mark.parametrize(
    ("smooth", "profile"), [(None, None), (30.0, None), (None, (2.0, 2.0)), (30.0, (2.0, 1.5))]
)
def test_deblur_matches_kernel(smooth, profile):
    rng = np.random.default_rng(3)
    z = np.full((24, 28), 1000.0, np.float32)
    z[:, 14:] = 1600.0
    z += rng.normal(0.0, 4.0, z.shape).astype(np.float32)
    z[rng.random(z.shape) < 0.1] = 0.0
    cfg = DeblurConfig(iterations=10, smooth_sigma_mm=smooth)
    expected = deblur(z, cfg, noise_profile=profile)
    actual = deblur_numpy(z, cfg, noise_profile=profile)
    assert actual.dtype == np.float32
    np.testing.assert_array_equal(actual == 0, z == 0)
    # the same up to sign ties (a difference of exactly 0 in float32 rounding, which the
    # compiled kernel's fused multiply-adds round otherwise): a few pixels, within a step
    err = np.abs(actual - expected)
    assert np.mean(err > 0.05) < 0.03 and err.max() < 1.0
    if profile is None:
        np.testing.assert_allclose(actual, expected, atol=0.05, rtol=0)
    else:  # the profile's steps are not the plain steps
        assert np.abs(actual - deblur(z, cfg)).max() > 0.5


@pytest.mark.parametrize("lag", [1, 2, 4])
@pytest.mark.parametrize("case", ["noisy", "steps", "noiseless", "sparse", "invalid", "even"])
def test_estimate_noise_matches_numpy_exactly(case, lag):
    rng = np.random.default_rng(lag)
    z = (2000.0 + rng.laplace(0.0, 15.0, (37, 53))).astype(np.float32)
    if case == "steps":  # two surfaces and holes: the edge pairs must not count
        z[:, 20:] += 600.0
        z[rng.random(z.shape) < 0.2] = 0.0
    elif case == "noiseless":  # every difference is 0: one histogram bin holds them all
        z[:] = 1500.0
    elif case == "sparse":
        z[rng.random(z.shape) < 0.9] = 0.0
    elif case == "invalid":
        z[:] = 0.0
    elif case == "even":  # an even number of differences: mean of the two middle ones
        z = z[:2, :3].copy()
    assert estimate_noise_mm(z, lag) == estimate_noise_mm_numpy(z, lag)


def test_estimate_noise_rejects_a_video():
    with pytest.raises(InputError, match="2-D"):
        estimate_noise_mm(np.ones((2, 4, 4), np.float32))


def test_deblur_numpy_rejects_a_blur_model():
    with pytest.raises(NotImplementedError, match="blur"):
        deblur_numpy(np.ones((4, 4), np.float32), DeblurConfig(blur="gaussian"))


@pytest.mark.parametrize(
    ("sigma_mm", "depth_factor"),
    [(10.0, 1.0), (50.0, 1.0), (10.0, 0.2)],
    ids=["paper", "smoothing-at-the-noise", "near-scene"],
)
def test_straightforward_path_agrees_with_the_engine_at_the_paper_settings(sigma_mm, depth_factor):
    """Also where the video's statistics change the thresholds after the fusion: a noise
    above the smoothing's 30 mm, a scene nearer than 1 m."""
    from upsr.method.config import UPSRConfig
    from upsr.method.windowed import super_resolve
    from upsr.research.metrics import evaluate
    from upsr.research.oracle import super_resolve_straightforward
    from upsr.research.synth import dynamic_scene

    scene = dynamic_scene(
        n_frames=6, lowres_shape=(14, 18), scale=2, noise_sigma_mm=sigma_mm, seed=4
    )
    scene = dataclasses.replace(
        scene, lowres=scene.lowres * depth_factor, truth=scene.truth * depth_factor
    )
    # the engine with the flow grid at r and DIS medium everywhere is the same algorithm
    # (without the speckle removal: a close vote at an edge can make an island in one only)
    cfg = UPSRConfig(scale=2, n_frames=5, flow_scale=2, refine_preset="medium", speckle_px=0)
    slow = super_resolve_straightforward(scene.lowres, cfg)
    fast = super_resolve(scene.lowres, 2, config=cfg)
    assert slow.shape == fast.shape == scene.truth.shape
    np.testing.assert_array_equal(slow == 0, fast == 0)
    a, b = evaluate(slow, scene.truth, 2), evaluate(fast, scene.truth, 2)
    for key in ("surface_rmse", "rmse", "edge_accuracy"):
        assert abs(a[key] - b[key]) < 0.02 * b[key]
    both = (slow > 0) & (fast > 0)  # the same thresholds after the fusion: the same surfaces
    assert (np.abs(slow - fast)[both] < 0.5).mean() > 0.95
    # the fused images agree but for a few edge pixels: the engine traces the splat samples
    # through the flows and tabulates the vote weights (the straightforward path composes
    # dense fields and evaluates exp), which can tip a close vote between two surfaces
    nodeb = dataclasses.replace(cfg, deblur=dataclasses.replace(cfg.deblur, enabled=False))
    same = super_resolve_straightforward(scene.lowres, nodeb) == super_resolve(
        scene.lowres, 2, config=nodeb
    )
    assert same.mean() > 0.98
