import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from upsr.method.fusion import temporal_median
from upsr.method.upsampling import upsample_nearest

NAN = np.nan


def px(*samples):
    """A (N, 1, 1) stack holding the samples of one pixel."""
    return np.array(samples, np.float32)[:, None, None]


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(500, 4000, width=32), min_size=1, max_size=15), st.data())
def test_all_valid_unimodal_is_plain_median(values, data):
    # samples on one surface (spread <= edge_mm): the ordinary median, average of the middle two
    values = np.array(values, np.float32)
    values = values[0] + (values - values[0]) * (50.0 / max(np.ptp(values), 1.0))
    ref = data.draw(st.integers(0, len(values) - 1))
    out = temporal_median(px(*values), ref)
    assert out[0, 0] == pytest.approx(np.median(values), rel=1e-6)


def test_invalid_samples_do_not_vote_on_depth():
    # 0 = no return, NaN = outside: the median of the valid ones only
    assert temporal_median(px(1000, 0, 1010, 1020, 0, NAN, NAN), 0)[0, 0] == 1010


def test_random_dropout_is_filled():
    assert temporal_median(px(1000, 0, 1004, 1008, 0, 1002, 1006, 0, 1001), 1)[0, 0] == 1003


def test_one_stray_sample_never_invents_depth():
    # background out of range: most samples say "no return"
    assert temporal_median(px(0, 0, 0, 0, 1500, 0, 0, 0, 0), 4)[0, 0] == 0
    assert temporal_median(px(0, 0, 0, 1500, 1500, 0, 0, 0, 0), 4)[0, 0] == 0


def test_outside_samples_abstain_and_ties_follow_reference():
    assert temporal_median(px(NAN, NAN, NAN, 1200, 0), 3)[0, 0] == 1200
    assert temporal_median(px(NAN, NAN, NAN, 1200, 0), 4)[0, 0] == 0
    assert temporal_median(px(NAN, NAN, NAN), 1)[0, 0] == 0


def test_even_count_never_averages_foreground_and_background():
    # two surfaces with equal votes: the reference's surface wins, never a depth in between
    assert temporal_median(px(1000, 1005, 3000, 3010), 0)[0, 0] == 1002.5
    assert temporal_median(px(1000, 1005, 3000, 3010), 3)[0, 0] == 3005
    assert temporal_median(px(1000, 1005, 3000, 3010, 1003, 2990), 1)[0, 0] == 1003
    assert temporal_median(px(1000, 1005, 3000, 3010, 1003, 2990), 2)[0, 0] == 3000
    # on one surface the two middle samples are averaged
    assert temporal_median(px(1000, 1004, 1008, 1012), 0)[0, 0] == 1006


def test_weights_decide_the_surface_at_an_edge():
    stack = px(1000, 1001, 1002, 3000, 3001)
    # unweighted: three foreground samples win
    assert temporal_median(stack, 0)[0, 0] == 1001
    w = px(0.1, 0.1, 0.1, 1.0, 1.0)
    assert temporal_median(stack, 0, weights=w)[0, 0] == pytest.approx(3000.5)


def test_image_stack_and_static_scene():
    rng = np.random.default_rng(0)
    frames = rng.uniform(960, 1040, (7, 20, 30)).astype(np.float32)
    np.testing.assert_allclose(temporal_median(frames), np.median(frames, axis=0), rtol=1e-6)


def test_bad_arguments():
    with pytest.raises(ValueError):
        temporal_median(np.ones((3, 3)))
    with pytest.raises(ValueError):
        temporal_median(np.ones((3, 2, 2)), ref=3)


def test_guide_decides_between_surfaces():
    stack = px(1000, 1001, 3000, 3001, 3002)
    assert temporal_median(stack, 0)[0, 0] == 3001
    # the guide's surface gets a bonus of 0.35 x the total weight: 2 + 1.75 > 3
    assert temporal_median(stack, 0, guide=np.full((1, 1), 1000.5))[0, 0] == 1000.5
    # the guide never overrides a clear majority
    stack = px(1000, 3000, 3001, 3002, 3003)
    assert temporal_median(stack, 0, guide=np.full((1, 1), 1000.0))[0, 0] == 3001.5


# -- sorting networks and the fused registration + median kernel --------------------------------
@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 9, 12, 16, 17])
def test_sorting_network_sorts_every_zero_one_input(n):
    from upsr.method.fusion import sorting_network

    net = sorting_network(n)
    assert np.all(net[:, 0] < net[:, 1]) and (net.size == 0 or net.max() < n)
    # 0-1 principle: a comparator network sorts everything iff it sorts all 0-1 inputs
    for code in range(2 ** min(n, 12)):
        a = [(code >> b) & 1 for b in range(n)]
        for i, j in net:
            if a[i] > a[j]:
                a[i], a[j] = a[j], a[i]
        assert a == sorted(a)


def _window(rng, n, h=10, w=12, s=2, r=4):
    lowres = rng.uniform(1000, 1100, (n, h, w)).astype(np.float32)
    lowres[:, 3:7, 4:9] -= 600  # a second surface
    lowres[rng.random(lowres.shape) < 0.15] = 0.0
    lowres[:, 0, :] = 0.0  # a row nobody measured
    maps = rng.normal(0, 1.5, (n, h * s, w * s, 2)).astype(np.float32)
    return lowres, maps


def _registered(lowres, maps, r, sigma_px=None, floor=0.25):
    """The two-step reference: warp the upsampled frames, weights from sample_offsets."""
    from upsr.method.registration import sample_offsets, warp_nearest

    stack = np.stack(
        [warp_nearest(upsample_nearest(f, r), m) for f, m in zip(lowres, maps, strict=True)]
    )
    if sigma_px is None:
        return stack, None
    d = np.stack([sample_offsets(m, r) for m in maps])
    return stack, floor + (1 - floor) * np.exp(-(d**2) / (2 * sigma_px**2))


def test_register_and_fuse_of_one_frame_is_its_nearest_neighbour_warp():
    import cv2

    from upsr.method.fusion import register_and_fuse

    rng = np.random.default_rng(2)
    lowres, maps = _window(rng, 1, s=4)
    lowres[0, 0, :] = 1000.0
    fused = register_and_fuse(lowres, maps, 4, 0, measured_only=False)
    stack, _ = _registered(lowres, maps, 4)
    np.testing.assert_array_equal(fused, np.nan_to_num(stack[0], nan=0.0))
    # a coarser flow grid is interpolated like cv2.resize (positions that round differently
    # by float error of the interpolation are rare)
    _, coarse = _window(rng, 1, s=2)
    fused = register_and_fuse(lowres, coarse, 4, 0, measured_only=False)
    fine = cv2.resize(coarse[0], (48, 40), interpolation=cv2.INTER_LINEAR) * 2.0
    stack, _ = _registered(lowres, fine[None], 4)
    assert (fused == np.nan_to_num(stack[0], nan=0.0)).mean() > 0.995


@pytest.mark.parametrize("n", [1, 4, 9, 11, 17])
@pytest.mark.parametrize("still_reference", [False, True])
def test_register_and_fuse_equals_registration_then_median(n, still_reference):
    from upsr.method.fusion import register_and_fuse

    rng = np.random.default_rng(n)
    lowres, maps = _window(rng, n, s=4)
    ref = n // 2
    if still_reference:  # as in the engine: the kernel's shortcut for a frame that stays
        maps[ref] = 0.0
    guide = np.where(rng.random((40, 48)) < 0.5, np.float32(500), np.float32(np.nan))
    opts = dict(guide=guide, min_valid_fraction=0.5, edge_mm=100.0)
    fused = register_and_fuse(
        lowres, maps, 4, ref, weight_sigma_px=1.4, measured_only=False, **opts
    )
    stack, weights = _registered(lowres, maps, 4, sigma_px=1.4)
    expected = temporal_median(stack, ref, weights=weights, **opts)
    # the tabulated Gaussian may tip an exact tie of votes: allow a handful of pixels
    same = np.isclose(fused, expected, atol=1e-3)
    assert same.mean() > 0.995
    unweighted = register_and_fuse(lowres, maps, 4, ref, measured_only=False, **opts)
    np.testing.assert_allclose(unweighted, temporal_median(stack, ref, **opts), atol=1e-3)
    # measured_only: 0 wherever no frame measured the low-res pixel
    only = register_and_fuse(lowres, maps, 4, ref, weight_sigma_px=1.4, **opts)
    measured = upsample_nearest((lowres > 0).any(axis=0), 4)
    np.testing.assert_array_equal(only[~measured], 0.0)
    np.testing.assert_array_equal(only[measured], fused[measured])


def test_an_untrusted_reference_sample_abstains_whether_or_not_the_reference_moves():
    """The kernel's shortcut for a reference whose map is zero skipped ``untrusted[ref]``:
    the untrusted reference sample won (1500) where a map 1e-6 px off gave the other frame's
    1000 mm."""
    from upsr.method.fusion import register_and_fuse

    lowres = np.full((2, 6, 6), 1000.0, np.float32)
    lowres[0] = 1500.0
    maps = np.zeros((2, 12, 12, 2), np.float32)
    untrusted = np.zeros((2, 6, 6), bool)
    untrusted[0, 2, 2] = True
    still = register_and_fuse(lowres, maps, 2, 0, untrusted=untrusted)
    maps[0, -1, -1, 0] = 1e-6
    moved = register_and_fuse(lowres, maps, 2, 0, untrusted=untrusted)
    np.testing.assert_array_equal(still, moved)
    np.testing.assert_array_equal(still[4:6, 4:6], 1000.0)
    assert (still[untrusted[0].repeat(2, 0).repeat(2, 1) == 0] == 1500.0).all()


def test_temporal_median_refuses_what_is_not_a_registered_stack():
    """±inf and negative samples gave ±inf and negative depth; a wrong shape, ref or weights
    gave plain ValueErrors or NumPy's broadcast error: one InputError each (a ValueError)."""
    from upsr.errors import InputError

    z = np.full((6, 8), 1500.0, np.float32)
    z[2, 2] = 0.0
    stack = np.stack([z, z + (z > 0), z - (z > 0)])
    bad = (
        ({"stack": np.where(stack > 0, np.inf, 0.0)}, "±inf"),
        ({"stack": -stack}, "negative"),
        ({"stack": z}, r"\(N, H, W\)"),
        ({"stack": stack.astype(complex)}, "numeric"),
        ({"stack": stack, "ref": 5}, "ref must be"),
        ({"stack": stack, "weights": np.ones((2, 2))}, "weights must broadcast"),
        ({"stack": stack, "guide": z[:3]}, "guide must be one frame"),
    )
    for kwargs, match in bad:
        with pytest.raises(InputError, match=match):
            temporal_median(**kwargs)
    nan_outside = stack.copy()
    nan_outside[2, :, :4] = np.nan  # (outside the frame: allowed)
    assert temporal_median(nan_outside)[0, 0] == 1500.5  # (the median of the two in frame)
