"""Trust of the registered samples: reference anchor, mixed pixels, radial motion, estimator,
hole filling (upsr.method.trust and the trust path of fusion.register_and_fuse)."""

import numpy as np
import pytest

import upsr
from upsr.errors import InputError
from upsr.method.config import UPSRConfig
from upsr.method.frontend import MotionFrontEnd
from upsr.method.fusion import register_and_fuse
from upsr.method.statistics import fix_video_statistics
from upsr.method.trust import (
    fill_holes,
    radial_offsets,
    reference_anchor,
)
from upsr.method.upsampling import upsample_nearest

R = 2
WALL = 3000.0
BAR = 1500.0


def _bar_video(n=9, h=12, w=40, width=1, speed=5, background=WALL, noise=0.0, seed=0):
    """A thin vertical bar (``width`` low-res px) moving ``speed`` px/frame in front of a wall
    (or of nothing: background 0); the reference (middle frame) has it at column 18."""
    rng = np.random.default_rng(seed)
    ref = (n - 1) // 2
    frames = np.full((n, h, w), background, np.float32)
    for k in range(n):
        c = 18 + speed * (k - ref)
        if 0 <= c < w:
            frames[k, :, c : c + width] = BAR
    if noise:
        frames = np.where(frames > 0, frames + rng.normal(0, noise, frames.shape), 0)
    return frames.astype(np.float32), ref


def _fuse_trusted(frames, ref, maps=None, *, sigma=3.0, edge=100.0, **kw):
    n, h, w = frames.shape
    if maps is None:  # the flow did not follow the bar: zero motion everywhere
        maps = np.zeros((n, h * R, w * R, 2), np.float32)
    anchor, tol = reference_anchor(frames[ref], sigma, 3.0, edge)
    return register_and_fuse(
        frames, maps, R, ref, anchor=anchor, tolerance=tol, edge_mm=edge, min_trusted=3, **kw
    )


@pytest.mark.parametrize("background", [WALL, 0.0])
@pytest.mark.parametrize("width", [1, 2])
def test_thin_fast_bar_survives_at_its_reference_position(background, width):
    frames, ref = _bar_video(width=width, background=background)
    maps = np.zeros((frames.shape[0], 12 * R, 40 * R, 2), np.float32)
    old = register_and_fuse(frames, maps, R, ref, edge_mm=100.0)
    new = _fuse_trusted(frames, ref)
    cols = slice(18 * R, (18 + width) * R)
    # the other frames' samples there show the wall (or nothing) and used to erase the bar
    assert not np.any(old[:, cols] == BAR)
    np.testing.assert_array_equal(new[:, cols], BAR)
    # not shifted: everywhere else the reference's own background
    rest = np.ones(new.shape[1], bool)
    rest[cols] = False
    np.testing.assert_array_equal(new[:, rest], background)


def test_an_untrusted_sample_cannot_change_the_output():
    rng = np.random.default_rng(1)
    frames = (WALL + rng.normal(0, 3, (7, 6, 6))).astype(np.float32)
    ref = 3
    outs = []
    for value in (WALL + 60, WALL - 80, 500.0, 0.0, 9000.0):
        changed = frames.copy()
        changed[1, 2, 3] = value
        changed[5, 2, 3] = value
        outs.append(_fuse_trusted(changed, ref))
    for out in outs[1:]:  # whatever the untrusted value (or none): the same output
        np.testing.assert_array_equal(out, outs[0])
    # which is the estimate of the trusted samples alone
    trusted = np.delete(frames[:, 2, 3], [1, 5])
    np.testing.assert_allclose(outs[0][2 * R, 3 * R], np.median(trusted), rtol=1e-6)
    # without the trust test the outliers move it
    maps = np.zeros((7, 12, 12, 2), np.float32)
    changed = frames.copy()
    changed[[1, 5, 6], 2, 3] = WALL + 60
    assert register_and_fuse(changed, maps, R, ref)[2 * R, 3 * R] != outs[0][2 * R, 3 * R]


def test_with_too_few_trusted_samples_the_output_is_the_anchor_never_zero():
    frames = np.zeros((9, 5, 5), np.float32)
    frames[4] = 2000.0
    frames[4, 2, 2] = 2004.0
    out = _fuse_trusted(frames, 4)
    anchor, _ = reference_anchor(frames[4], 3.0, 3.0, 100.0)
    np.testing.assert_array_equal(out, upsample_nearest(anchor, R))
    assert anchor[2, 2] == 2000.0  # the 3x3 median on its surface
    # without trust the other frames' "no return" erase the reference's depth
    maps = np.zeros((9, 10, 10, 2), np.float32)
    assert not register_and_fuse(frames, maps, R, 4).any()


def test_a_dropout_in_the_reference_is_still_filled():
    rng = np.random.default_rng(2)
    frames = (WALL + rng.normal(0, 3, (7, 6, 6))).astype(np.float32)
    frames[3, 2, 3] = 0.0
    out = _fuse_trusted(frames, 3)
    block = out[2 * R : 3 * R, 3 * R : 4 * R]
    expected = np.median(np.delete(frames[:, 2, 3], 3))
    np.testing.assert_allclose(block, expected, rtol=1e-6)


def test_anchor_follows_its_surface_and_tolerance_its_relief():
    z = np.tile(2000.0 + 10.0 * np.arange(8, dtype=np.float32), (6, 1))
    z[:, 6:] = 1000.0  # a foreground edge
    anchor, tol = reference_anchor(z, 2.0, 3.0, 100.0)
    np.testing.assert_array_equal(anchor[1:-1, 1:5], z[1:-1, 1:5])  # a plane: its own depth
    np.testing.assert_array_equal(anchor[:, 6:], 1000.0)  # never across the edge
    assert tol[2, 3] == pytest.approx(3.0 * 2.0 + 10.0)  # k·σ + relief of one pixel
    assert tol[2, 7] == pytest.approx(6.0)
    z[1, 1] = 0.0
    anchor, tol = reference_anchor(z, 2.0, 3.0, 100.0)
    assert anchor[1, 1] == 0.0 and tol[1, 1] == 0.0


def test_with_a_noise_profile_the_tolerance_follows_the_depth_of_the_anchor():
    z = np.full((6, 12), 1000.0, np.float32)
    z[:, 6:] = 3000.0
    profile = (2.0, 2.0)  # σ(z) = 2 mm · (z / 1 m)²
    _, tol = reference_anchor(z, 50.0, 3.0, 100.0, noise_profile=profile)
    assert tol[2, 2] == pytest.approx(3.0 * 2.0)
    assert tol[2, 9] == pytest.approx(3.0 * 2.0 * 9.0)
    # a power of 0 is one σ: the video's
    _, flat = reference_anchor(z, 50.0, 3.0, 100.0, noise_profile=(2.0, 0.0))
    assert flat[2, 2] == flat[2, 9] == pytest.approx(150.0)


def test_with_a_noise_profile_a_small_offset_of_a_near_surface_is_significant():
    """A near surface (1 m, σ 2 mm) moved 6 mm toward the camera while the far wall (3 m,
    σ 18 mm) sets the video's one σ: with one σ the offset is not significant there (4 standard
    errors of the median of 25 differences of σ = 18 mm: 25 mm), with the profile it is."""
    rng = np.random.default_rng(6)
    ref = np.full((20, 40), 1000.0, np.float32)
    ref[:, 20:] = 3000.0
    sigma = np.where(ref < 2000.0, 2.0, 18.0)
    frames = (ref + rng.normal(0.0, 1.0, (3, 20, 40)) * sigma).astype(np.float32)
    frames[0, :, :20] -= 6.0
    maps = np.zeros((3, 20, 40, 2), np.float32)
    kw = dict(sigma_mm=18.0, edge_mm=150.0)
    near = (slice(2, -2), slice(2, 18))
    assert not radial_offsets(frames, maps, 1, 1, **kw)[0][near].any()
    got = radial_offsets(frames, maps, 1, 1, noise_profile=(2.0, 2.0), **kw)
    assert np.median(got[0][near]) == pytest.approx(-6.0, abs=1.5)
    assert not got[1].any()  # the reference
    assert not got[2][near].any()  # noise alone is not an offset, with the profile either


def _approach_video(t=12, h=16, w=20, speed=25.0, noise=3.0, seed=3):
    """A camera moving ``speed`` mm/frame toward a slanted wall (no lateral motion)."""
    rng = np.random.default_rng(seed)
    _ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    walls = np.stack([2500.0 + 15.0 * xs - speed * k for k in range(t)])
    return (walls + rng.normal(0, noise, walls.shape)).astype(np.float32), walls


def test_radial_motion_is_compensated():
    video, truth = _approach_video(h=24, w=30)
    kw = dict(deblur=False, noise_mm=3.0, edge_weight_px=None, speckle_px=0)
    out = upsr.super_resolve(video, 2, 9, **kw)
    truth_up = upsample_nearest(truth, 2)
    assert abs(float(np.mean(out - truth_up))) < 1.0
    # per output frame (the windows of the first and last frames are not centred on them):
    # what is left is the noise of the offset estimates, no bias
    bias = np.mean(out - truth_up, axis=(1, 2))
    assert np.abs(bias).max() < 2.0
    # without it, the worst frame's bias is several times larger (the blocks of this slope,
    # steep for σ = 3, take part of their level from the reference: memory.level_to_reference)
    trust_only = upsr.super_resolve(video, 2, 9, radial_compensation=False, **kw)
    assert np.abs(np.mean(trust_only - truth_up, axis=(1, 2))).max() > 3.0 * np.abs(bias).max()
    plain = upsr.super_resolve(video, 2, 9, radial_compensation=False, trust_k=None, **kw)
    assert np.abs(np.mean(plain - truth_up, axis=(1, 2))).max() > 20.0


def test_a_static_scene_gets_no_radial_offset():
    rng = np.random.default_rng(4)
    frames = (2000.0 + rng.laplace(0, 10 / np.sqrt(2), (9, 16, 20))).astype(np.float32)
    maps = np.zeros((9, 32, 40, 2), np.float32)
    off = radial_offsets(frames, maps, 2, 4, sigma_mm=10.0, edge_mm=100.0)
    assert not off.any()
    # a real offset of one frame is found
    frames[2] += 40.0
    off = radial_offsets(frames, maps, 2, 4, sigma_mm=10.0, edge_mm=100.0)
    assert np.median(off[2]) == pytest.approx(40.0, abs=5.0)
    assert not off[4].any()


@pytest.mark.parametrize("m_side", [5, 4])  # 25 and 16 differences: odd and even medians
def test_the_offset_is_the_significant_median_of_the_differences(m_side):
    """The kernel decides most pixels by counting the differences beyond the threshold (no
    selection); the result must be exactly the significant median: offsets near the
    threshold, with odd and even numbers of differences; and the second result, from a
    lower significance (the recursive state's confirmed offsets), the same from there."""
    import math

    from upsr.method.trust import _offset_at

    rng = np.random.default_rng(m_side)
    sigma, signif = 10.0, 2.0
    m = m_side * m_side
    thr = signif * 1.2533 * math.sqrt(2.0) * sigma / math.sqrt(m)
    ref = np.full((m_side, m_side), 2000.0, np.float32)
    anc = np.zeros_like(ref)  # no surface test
    sig = np.full((1, m_side, m_side), signif, np.float32)
    buf, us = np.empty(m, np.float32), np.empty(m, np.float32)  # (m samples in the image)
    rows, cols = np.empty(m, np.int64), np.empty(m, np.int64)
    scratch = (buf, rows, cols, us)
    found = weak_only = 0
    for _ in range(400):
        shift = rng.uniform(-2.0 * thr, 2.0 * thr)
        diff = (shift + rng.normal(0, 0.5 * thr, (m_side, m_side))).astype(np.float32)
        reg = (ref + diff)[None]
        med = float(np.median((reg[0] - ref).astype(np.float64)))
        want = med if abs(med) > thr else 0.0
        weak = med if abs(med) > thr / 2 else 0.0  # from min(signif, low) = 1 standard error
        got = _offset_at(
            reg, ref, anc, 0, 0, 0, 100.0, sigma, 0.0, 2 * m_side, 1, *scratch, sig, 1.0
        )
        assert got[0] == pytest.approx(want, abs=1e-3)
        assert got[1] == pytest.approx(weak, abs=1e-3)
        only = _offset_at(
            reg, ref, anc, 0, 0, 0, 100.0, sigma, 0.0, 2 * m_side, 1, *scratch, sig, 9.0
        )
        assert only == got[:1] * 2  # low above signif: the one test
        found += want != 0.0
        weak_only += weak != 0.0 and want == 0.0
    assert 50 < found < 350  # both outcomes, many of them near the threshold
    assert weak_only > 20


def test_a_frame_that_moved_has_its_offsets_measured_at_a_lower_significance():
    """Where the frame moved (a camera along a slanted wall), an offset of 3 standard errors
    of the 5×5 median is kept there; where it did not, it needs 4 and the frame falls back on
    the wide neighbourhood, whose median is the offset of the rest of the frame."""
    from upsr.method.trust import OFFSET_SIGNIFICANCE, OFFSET_SIGNIFICANCE_MOVED, significance

    sigma = 30.0
    se = 1.2533 * np.sqrt(2.0) * sigma / 5.0  # of the median of 25 differences
    ref = np.full((40, 48), 2000.0, np.float32)
    frames = np.repeat(ref[None], 3, axis=0)
    frames[0] += 8.0 * se
    frames[0, :, 20:28] = ref[:, 20:28] + 3.0 * se  # a stripe 8 px wide
    still = np.zeros((3, 40, 48, 2), np.float32)
    moved = still.copy()
    moved[0] = 0.01  # moves, but every sample still lands on its own pixel
    sig = significance(moved, (40, 48))
    assert (sig[0] == OFFSET_SIGNIFICANCE_MOVED).all() and (sig[1:] == OFFSET_SIGNIFICANCE).all()
    kw = dict(sigma_mm=sigma, edge_mm=500.0)
    stripe = (slice(None), slice(22, 26))
    got = radial_offsets(frames, moved, 1, 1, **kw)[0]
    np.testing.assert_allclose(got[stripe], 3.0 * se, rtol=1e-5)
    np.testing.assert_allclose(got[:, :18], 8.0 * se, rtol=1e-5)
    static = radial_offsets(frames, still, 1, 1, **kw)[0]
    np.testing.assert_allclose(static[stripe], 8.0 * se, rtol=1e-5)
    # the motion at the pixel centres, when the caller has it, is read instead of the maps
    from upsr.method.consistency import maps_at_centres

    at = maps_at_centres(moved, (40, 48))
    np.testing.assert_array_equal(significance(moved, (40, 48), centres=at), sig)
    np.testing.assert_array_equal(radial_offsets(frames, moved, 1, 1, **kw, centres=at)[0], got)
    at_still = maps_at_centres(still, (40, 48))
    np.testing.assert_array_equal(
        radial_offsets(frames, moved, 1, 1, **kw, centres=at_still)[0], static
    )


def test_a_slow_radial_motion_under_strong_noise_is_found_on_a_wider_neighbourhood():
    rng = np.random.default_rng(5)
    frames = (2000.0 + rng.laplace(0, 30 / np.sqrt(2), (9, 40, 48))).astype(np.float32)
    frames -= 10.0 * (np.arange(9) - 4)[:, None, None]  # a camera 10 mm/frame closer
    maps = np.zeros((9, 40, 48, 2), np.float32)
    off = radial_offsets(frames, maps, 1, 4, sigma_mm=30.0, edge_mm=120.0)
    # 5×5 px: 4 standard errors ≈ 42 mm, frames ±1..±3 invisible; 17×17 px: ≈ 12 mm
    for k, expected in ((0, 40.0), (2, 20.0), (6, -20.0)):
        assert np.median(off[k]) == pytest.approx(expected, abs=5.0)
    assert not off[4].any()
    frames = (2000.0 + rng.laplace(0, 30 / np.sqrt(2), (9, 40, 48))).astype(np.float32)
    assert not radial_offsets(frames, maps, 1, 4, sigma_mm=30.0, edge_mm=120.0).any()


def test_the_anchor_ignores_a_lone_outlier_and_keeps_a_thin_line():
    rng = np.random.default_rng(6)
    plane = (2000.0 + rng.laplace(0, 10 / np.sqrt(2), (9, 9))).astype(np.float32)
    plane[4, 4] = 2300.0  # a lone noise outlier (> edge from all its neighbours)
    anchor, tol = reference_anchor(plane, 10.0, 3.0, 100.0)
    assert anchor[4, 4] == 0.0 and tol[4, 4] == 0.0  # no anchor: the other frames decide
    assert (np.abs(anchor[3:6, 3:6][anchor[3:6, 3:6] > 0] - 2000) < 30).all()
    plane[4, 4] = 2090.0  # an outlier within the edge threshold of a few neighbours only
    anchor, _ = reference_anchor(plane, 10.0, 3.0, 100.0)
    assert abs(anchor[4, 4] - 2000.0) < 30.0
    line = np.full((9, 9), 3000.0, np.float32)
    line[:, 4] = 1500.0  # a thin part one pixel wide
    anchor, _ = reference_anchor(line, 10.0, 3.0, 100.0)
    np.testing.assert_array_equal(anchor[:, 4], 1500.0)


def _box_side_edge_on(h: int = 16, w: int = 20) -> np.ndarray:
    """A wall (left), a box front (right) and between them the box's side seen edge-on, one
    pixel wide, 150 mm deeper per row: none of its pixels within 100 mm of another (the
    room of seed 6, point-sampled, steps of 130–160 mm down such a column)."""
    z = np.full((h, w), WALL, np.float32)
    z[:, 11:] = 1922.0
    z[3:12, 10] = WALL + 150.0 * np.arange(9, 0, -1)
    return z


def test_a_surface_one_pixel_wide_seen_edge_on_is_a_steep_run_not_an_outlier():
    from upsr.method.anchor import steep_runs

    z = _box_side_edge_on()
    steep = steep_runs(z, 100.0)
    assert steep[3:12, 10].all() and not steep[:, 11:].any() and not steep[:, :9].any()
    anchor, tol = reference_anchor(z, 10.0, 3.0, 100.0)
    np.testing.assert_array_equal(anchor[3:12, 10], z[3:12, 10])  # its own measurement
    assert (tol[3:12, 10] > 0).all()
    # where the sensor mixes, a line of mixes along a slope steps like one: no anchor
    assert not reference_anchor(z, 10.0, 3.0, 100.0, keep_steep=False)[0][3:12, 10].any()
    plane = np.full((9, 9), 2000.0, np.float32)
    plane[4, 4] = 2300.0  # a noise outlier steps out and back
    assert not steep_runs(plane, 100.0).any()
    plane[:, 4] = 2400.0
    plane[:, 5:] = 3000.0  # a column of mixes between two flat surfaces: one step each side
    assert not steep_runs(plane, 100.0).any()
    floor = np.repeat((1000.0 + 150.0 * np.arange(9.0))[:, None], 9, axis=1).astype(np.float32)
    assert steep_runs(floor, 100.0).all()  # a floor at a grazing angle


@pytest.mark.parametrize("mode", ["windowed", "recursive"])
def test_a_box_side_seen_edge_on_keeps_its_depth(mode):
    """Without a neighbour on its surface, each of its pixels was a lone outlier: blanked by
    the speckle filter in the recursive mode (108 px of holes here), given the wall's or the
    box's depth in the windowed mode."""
    z = _box_side_edge_on()
    out = upsr.super_resolve(np.repeat(z[None], 3, axis=0), 2, 3, mode=mode)
    side = out[:, 8:22, 20:22]
    assert (np.abs(side - np.repeat(z[4:11, 10], 2)[None, :, None]) < 100).all()
    assert not (out == 0).any()


def test_an_outlier_with_one_noisy_neighbour_on_its_side_gets_no_anchor():
    """Samba, r = 2, Laplacian σ = 50 mm (edge threshold 141 mm): a +5σ outlier (3111 mm on a
    surface at about 2850) had one neighbour within the edge threshold, itself a +2.7σ sample
    (2987) whose own anchor is the surface's; the pair's median (3049) became the outlier's
    anchor, rejected every other frame's sample and was the output over its whole block.
    Now an anchor that no neighbour's anchor shares is none (the other frames decide), while
    a real part of two pixels and the tip of a line one pixel wide keep theirs."""
    z = np.array(
        [[2816, 2864, 2865, 2871], [2802, 3111, 2987, 2850], [2818, 2845, 2841, 2833]],
        np.float32,
    )
    anchor, tol = reference_anchor(z, 50.0, 3.0, 141.0, own_surface="except_rims")
    assert anchor[1, 1] == 0.0 and tol[1, 1] == 0.0
    assert abs(anchor[1, 2] - 2850.0) < 30.0
    part = np.full((7, 7), 3000.0, np.float32)
    part[3, 3:5] = 1500.0  # a part two pixels wide
    part[0:3, 1] = 1200.0  # a line one pixel wide, its tip at row 2
    for mode in ("never", "always", "except_rims"):
        anchor, _ = reference_anchor(part, 10.0, 3.0, 100.0, own_surface=mode)
        np.testing.assert_array_equal(anchor[3, 3:5], 1500.0)
        np.testing.assert_array_equal(anchor[0:3, 1], 1200.0)


def test_the_anchor_stays_on_the_pixels_own_surface_where_a_wall_meets_a_slope():
    """A ToF frame of the approaching camera (Gaussian noise σ ≈ 21 mm): a box side sloping
    away from the wall begins inside the centre pixel's block. The two-step median over the
    neighbours within the edge threshold walked onto the wall (2442 mm, 93 mm from the pixel's
    2349, where the slope's pixel below it reads 2312): the recursive state restarted from the
    wall there. With ``own_surface`` (the recursive mode) the anchor stays within 3σ of the
    pixel when a neighbour on its side lies beyond 3σ of the wall; a noise outlier with no
    such neighbour keeps the surface's."""
    z = np.array(
        [
            [2469, 2442, 2439, 2461, 2440],
            [2486, 2463, 2349, 2187, 2083],
            [2472, 2456, 2312, 2165, 2085],
        ],
        np.float32,
    )
    for mode in ("always", "except_rims"):  # (the anchor lies beyond the pixel: no rim)
        anchor, _ = reference_anchor(z, 20.7, 3.0, 100.0, own_surface=mode)
        assert anchor[1, 2] == pytest.approx(0.5 * (2349 + 2312))
    assert reference_anchor(z, 20.7, 3.0, 100.0)[0][1, 2] > 2430.0
    lone = z.copy()
    lone[2, 2] = 2460.0  # no neighbour on the pixel's side: a noise outlier on the wall
    anchor, _ = reference_anchor(lone, 20.7, 3.0, 100.0, own_surface="always")
    assert anchor[1, 2] > 2430.0


def test_the_windowed_anchor_of_a_rim_stays_the_surfaces_median():
    """The synthetic wall (``benchmarks/synthetic_eval.py``, r = 2, σ = 10 mm): the centre
    pixel samples the steep far end of a blob's rim (1776 mm; the blob inside reads ~1700,
    the wall behind 2820). Its block is half wall; with the anchor at the pixel's own value
    the windowed fusion gave the wall's half the blob's depth (rmse +2.5 % there), so
    ``"except_rims"`` keeps the median where it lies nearer and a neighbour lies beyond the
    edge threshold; ``"always"`` (the recursive mode) takes the pixel's own surface."""
    z = np.array(
        [
            [1655, 1632, 1634, 1635, 1648],
            [1673, 1672, 1713, 1695, 1701],
            [1775, 1771, 1776, 2823, 2821],
            [2812, 2816, 2819, 2819, 2824],
            [2838, 2811, 2813, 2815, 2822],
        ],
        np.float32,
    )
    median = reference_anchor(z, 10.0, 3.0, 300.0)[0][2, 2]
    assert median < 1730.0
    assert reference_anchor(z, 10.0, 3.0, 300.0, own_surface="except_rims")[0][2, 2] == median
    own = reference_anchor(z, 10.0, 3.0, 300.0, own_surface="always")[0][2, 2]
    assert own == pytest.approx(0.5 * (1771 + 1776))
    ridge = z.copy()
    ridge[2, 3:] = 1700.0  # no edge beside it: a ridge on the blob, its own surface kept
    ridge[3:] = 1705.0
    anchor = reference_anchor(ridge, 10.0, 3.0, 300.0, own_surface="except_rims")[0]
    assert anchor[2, 2] == pytest.approx(0.5 * (1771 + 1776))
    assert reference_anchor(ridge, 10.0, 3.0, 300.0)[0][2, 2] == pytest.approx(1705.0)
    with pytest.raises(ValueError, match="own_surface"):
        reference_anchor(z, 10.0, 3.0, 300.0, own_surface=True)


def _kinect(z, rng, f=580.0, b=75.0, sigma_px=0.07):
    """Kinect-like structured light: disparity with noise, quantised to 1/8 px."""
    disparity = f * b / z + rng.normal(0, sigma_px, z.shape)
    return (f * b / (np.round(disparity * 8.0) / 8.0)).astype(np.float32)


@pytest.mark.parametrize("kind", ["gaussian", "kinect", "laplace"])
def test_the_estimator_follows_the_shape_of_the_noise(kind):
    rng = np.random.default_rng(5)
    n, h, w = 9, 24, 24
    truth = np.full((n, h, w), 2500.0, np.float32)
    if kind == "gaussian":
        frames = truth + rng.normal(0, 10, truth.shape)
    elif kind == "laplace":
        frames = truth + rng.laplace(0, 10 / np.sqrt(2), truth.shape)
    else:
        frames = _kinect(truth, rng)
    frames = frames.astype(np.float32)
    cfg = UPSRConfig(scale=R, n_frames=n)
    stats = fix_video_statistics(MotionFrontEnd(cfg, w), frames, cfg)
    estimator = stats.estimator
    assert estimator == ("median" if kind == "laplace" else "mean")
    sigma = stats.trust_noise_mm
    anchor, tol = reference_anchor(frames[4], sigma, 3.0, 100.0)
    maps = np.zeros((n, h * R, w * R, 2), np.float32)
    fused = register_and_fuse(
        frames, maps, R, 4, anchor=anchor, tolerance=tol, min_trusted=3, estimator=estimator
    )
    rmse = float(np.sqrt(np.mean((fused - 2500.0) ** 2)))
    mean = float(np.sqrt(np.mean((frames.mean(axis=0) - 2500.0) ** 2)))
    median = float(np.sqrt(np.mean((np.median(frames, axis=0) - 2500.0) ** 2)))
    if kind == "laplace":
        assert rmse <= median * 1.02 and median < mean
    else:
        assert rmse <= mean + 1e-3
    assert rmse < float(np.sqrt(np.mean((frames[4] - 2500.0) ** 2)))  # never worse than input


def test_fill_holes_takes_the_background_side_and_is_off_by_default():
    z = np.full((6, 8), 3000.0, np.float32)
    z[:, :3] = 1000.0
    z[2:4, 3:5] = 0.0  # a shadow between foreground and background
    filled = fill_holes(z, 1)
    assert (filled[2:4, 3:5] == 3000.0).all()
    np.testing.assert_array_equal(filled[z > 0], z[z > 0])
    assert UPSRConfig().fill_holes is False
    video = np.stack([z] * 3)
    assert (upsr.super_resolve(video, 2, 3, deblur=False) == 0).any()
    assert (upsr.super_resolve(video, 2, 3, deblur=False, fill_holes=True) > 0).all()


def test_trust_config_is_validated():
    assert UPSRConfig(n_frames=9).min_trusted_samples == 3
    assert UPSRConfig(n_frames=3).min_trusted_samples == 2
    assert UPSRConfig(n_frames=1).min_trusted_samples == 1
    assert UPSRConfig(n_frames=9, min_trusted=5).min_trusted_samples == 5
    for bad in (
        {"trust_k": 0},
        {"trust_k": float("nan")},
        {"min_trusted": 0},
        {"radial_radius_px": 0},
        {"fusion_estimator": "mode"},
        {"fill_holes": 1},
    ):
        with pytest.raises(InputError):
            UPSRConfig(**bad)
    with pytest.raises(ValueError):
        register_and_fuse(np.ones((2, 3, 3)), np.zeros((2, 3, 3, 2)), 1, estimator="mode")


def test_engine_keeps_a_thin_fast_bar():
    # 2 low-res px wide, 5 px/frame, in front of a wall, with noise: the flow cannot follow it
    frames, _ = _bar_video(n=9, h=16, w=40, width=2, noise=5.0, seed=6)
    kw = dict(noise_mm=5.0, deblur=False)
    out = upsr.super_resolve(frames, R, 9, **kw)[4]  # the reference of the middle window
    bar = out[2 * R : -2 * R, 18 * R : 20 * R]
    # its core always; at its sides the wall's samples may compete for a high-res pixel
    assert np.all(np.abs(bar[:, 1:-1] - BAR) < 30)
    assert np.mean(np.abs(bar - BAR) < 30) > 0.9
    wall = out[2 * R : -2 * R, 22 * R : 30 * R]
    assert np.all(np.abs(wall - WALL) < 30)
    old = upsr.super_resolve(frames, R, 9, trust_k=None, **kw)[4]
    assert np.mean(np.abs(old[2 * R : -2 * R, 18 * R : 20 * R] - BAR) < 30) < 0.5


def test_two_noise_outliers_side_by_side_are_outvoted_a_near_speck_is_not():
    """Samba, r = 2, Laplacian σ = 50: two reference pixels side by side 3.5σ nearer than the
    surface around (each other's surface, beyond the edge threshold of the rest) rejected the
    other frames' samples of the surface and gave their own depth to their blocks. A speck (at
    most 2 px along x, y and both diagonals) next to a surface within the noise of both
    (|Δanchor| ≤ the sum of their tolerances) now lets that surface's samples compete; a
    speck far in front of the wall (a small part the flow did not follow) keeps its own."""
    rng = np.random.default_rng(3)
    sigma, edge = 50.0, 141.0
    frames = (WALL + rng.laplace(0, sigma / np.sqrt(2), (9, 9, 9))).astype(np.float32)
    frames[:, 4, 4] = frames[:, 3, 5] = WALL  # (the speck's own samples, then its depth)
    speck = frames.copy()
    speck[4, 4, 4] = speck[4, 3, 5] = WALL - 175.0  # the reference's two outliers
    out = _fuse_trusted(speck, 4, sigma=sigma, edge=edge)
    block = out[4 * R : 5 * R, 4 * R : 5 * R]
    assert np.all(np.abs(block - WALL) < 2 * sigma)
    far = frames.copy()
    far[4, 4, 4] = far[4, 3, 5] = BAR  # a real speck: 1500 mm in front of the wall
    out = _fuse_trusted(far, 4, sigma=sigma, edge=edge)
    np.testing.assert_array_equal(out[4 * R : 5 * R, 4 * R : 5 * R], BAR)


def test_a_thin_outlier_within_the_noise_of_the_surface_on_one_side_is_outvoted():
    """Samba, r = 4, Laplacian σ = 30 (edge threshold 102 mm): the same pair of outliers
    (2997 / 3000 mm on a surface at about 2870), but the anchor of the pixel beside one of
    them (2897, 101 mm from the pair's 2998) continues their surface along the diagonal, so
    it passed for a thin line and kept its block against every other frame. A thin part
    whose every neighbour off its surface lies on one side of it (a ridge, a speck) lets a
    surface within the noise of both compete; one between a nearer and a farther surface (a
    floor at a grazing angle, steeper per pixel than the edge threshold) does not."""
    rng = np.random.default_rng(4)
    sigma, edge = 30.0, 102.0
    ref = np.array(
        [
            [2824, 2885, 2897, 2875, 2915, 2885, 2963],
            [2850, 2841, 2828, 2868, 2905, 2908, 2905],
            [2842, 2886, 2850, 2858, 3000, 2868, 2937],
            [2887, 2840, 2890, 2997, 2889, 2897, 2906],
            [2848, 2845, 2849, 2853, 2873, 2899, 2937],
            [2839, 2846, 2857, 2870, 2884, 2916, 2906],
            [2847, 2882, 2891, 2833, 2921, 2906, 2960],
        ],
        np.float32,
    )
    frames = (2870.0 + rng.laplace(0, sigma / np.sqrt(2), (9, 7, 7))).astype(np.float32)
    frames[4] = ref
    out = _fuse_trusted(frames, 4, sigma=sigma, edge=edge)
    assert np.all(np.abs(out[3 * R : 4 * R, 3 * R : 4 * R] - 2870.0) < 2 * sigma)
    from upsr.method.alternatives import surface_alternatives

    floor = np.repeat(np.arange(2000.0, 2000.0 + 7 * 130.0, 130.0)[:, None], 7, 1)
    anchor, tol = reference_anchor(floor.astype(np.float32), sigma, 3.0, edge)
    assert anchor[3, 3] > 0 and tol[3, 3] + tol[2, 3] > 130.0  # within the noise of both
    assert all(
        (alt[:, :, 1:-1, 1:-1] == 0).all() for alt in surface_alternatives(anchor, tol, edge)
    )


def test_a_lone_outlier_of_the_reference_is_neither_kept_nor_blanked():
    """It abstains: the other frames decide, and with none its neighbours' depth, never 0."""
    from upsr.method.mixed import split_mixed_pixels
    from upsr.method.trust import abstain_lone_outliers

    rng = np.random.default_rng(8)
    frames = (WALL + rng.laplace(0, 10 / np.sqrt(2), (9, 12, 16))).astype(np.float32)
    frames[4, 5, 7] = WALL + 400.0
    maps = np.zeros((9, 12 * R, 16 * R, 2), np.float32)
    maps[:4, ..., 1] = -1000.0  # frames 0-3: outside
    maps[5:, ..., 0] = 0.5 * R  # frames 5-8: half a low-res pixel away (low vote weights)
    guide = np.full((12 * R, 16 * R), np.nan, np.float32)
    guide[5 * R : 6 * R, 7 * R : 8 * R] = frames[4, 5, 7]  # the nearest forward sample
    anchor, tol = reference_anchor(frames[4], 10.0, 3.0, 100.0)
    assert anchor[5, 7] == 0.0
    kw = dict(edge_mm=100.0, anchor=anchor, tolerance=tol, min_trusted=3, guide=guide)
    kw["weight_sigma_px"] = 0.35 * R
    block = (slice(5 * R, 6 * R), slice(7 * R, 8 * R))
    marked = abstain_lone_outliers(frames, 4, anchor)
    assert marked[4, 5, 7] < 0 and (np.delete(marked, 4, 0) == np.delete(frames, 4, 0)).all()
    fused = register_and_fuse(marked, maps, R, 4, **kw)
    assert (np.abs(fused[block] - WALL) < 30).all()
    # no other frame at all: the neighbours' depth, never 0
    alone = register_and_fuse(marked[4:5], maps[4:5], R, 0, **kw)
    filled = split_mixed_pixels(alone, frames[4], marked[4], anchor)
    assert (alone[block] == 0).all() and (np.abs(filled[block] - WALL) < 30).all()
    out = upsr.super_resolve(frames, R, 9)[4]
    assert (np.abs(out[block] - WALL) < 30).all()


def test_the_engine_never_blanks_what_the_reference_measured_on_the_demo_scene():
    """The demo's wall had r×r holes at its top border (lone outliers that won their block,
    then the speckle filter): 54 px over 15 frames before."""
    from upsr.research.synth import dynamic_scene

    video = dynamic_scene(n_frames=15, lowres_shape=(48, 64), scale=4, noise_sigma_mm=30.0)
    out = upsr.super_resolve(video.lowres, 4, 9)
    measured = upsample_nearest(video.lowres, 4) > 0
    assert not ((out == 0) & measured & (video.truth > 0)).any()


def test_the_ends_of_a_clip_approaching_a_wall_under_strong_noise_are_not_biased():
    """Frames 5-8 away from an off-centre reference move 125-200 mm, beyond the edge
    threshold within which the offsets are measured; those truncated near it used to bias the
    first and last output frames by up to 19 mm (σ = 30 mm); they abstain now (11 mm)."""
    from upsr.method.trust import far_offsets

    video, truth = _approach_video(t=12, h=24, w=30, noise=30.0)
    out = upsr.super_resolve(video, 2, 9, edge_weight_px=None)
    bias = np.mean(out - upsample_nearest(truth, 2), axis=(1, 2))
    assert np.abs(bias).max() < 12.0  # 18.7 mm before
    assert far_offsets(np.array([10.0, -70.0, 130.0]), 120.0).tolist() == [False, True, True]


def test_a_state_that_moved_along_the_ray_as_a_whole_is_tested_at_the_lower_significance():
    """state_significance: a state everywhere 3 standard errors nearer than the frame (a camera
    walking towards a wall, zero flow) is `along`, its significance capped; a state that
    agrees with the frame, or has too few samples within the edge threshold, is not."""
    from upsr.method.trust import OFFSET_SIGNIFICANCE, state_significance

    rng = np.random.default_rng(0)
    frame = (2000.0 + rng.normal(0, 10.0, (20, 24))).astype(np.float32)
    flow = np.zeros((40, 48, 2), np.float32)
    kw = dict(sigma_mm=10.0, edge_mm=100.0, radius_px=2, noise_factor=0.75)
    se = 1.2533 * np.sqrt(2.0) * 0.75 * 10.0 / 5
    nearer = (frame - 3.0 * se)[None]
    sig, along = state_significance(flow, nearer, frame, **kw, along_significance=3.0)
    assert along and (sig == 3.0).all()
    same = frame[None].copy()
    sig, along = state_significance(flow, same, frame, **kw, along_significance=3.0)
    assert not along and (sig == OFFSET_SIGNIFICANCE).all()
    beyond = (frame - 150.0)[None]  # beyond the edge threshold: another surface, no evidence
    assert not state_significance(flow, beyond, frame, **kw, along_significance=3.0)[1]
