"""Thin parts of a ToF frame, mixed along their whole length (upsr.method.thin)."""

import numpy as np
import pytest

import upsr
from upsr.method.mixed import mixed_pixels, remove_mixed_pixels, split_mixed_pixels
from upsr.method.thin import ThinParts, split_thin_parts, thin_parts
from upsr.research.metrics import flying_pixel_mask
from upsr.research.synth.degradation import tof_footprint

WALL, BODY, R = 3000.0, 1800.0, 4


def _animal(leg_x_px=41.0, leg_width_px=2.0, n=24, r=R, leg_depth=BODY):
    """High-res truth: a body in front of a wall and a leg narrower than a low-res pixel
    growing down from it (a galloping animal's leg on a 64×56 ToF sensor)."""
    yy, xx = np.mgrid[0 : n * r, 0 : n * r] + 0.5
    truth = np.full(yy.shape, WALL, np.float32)
    truth[3 * r : 8 * r, 4 * r : 20 * r] = BODY
    leg = (xx > leg_x_px) & (xx < leg_x_px + leg_width_px) & (yy >= 8 * r) & (yy < 20 * r)
    truth[leg] = leg_depth
    return truth


def test_a_leg_narrower_than_a_pixel_is_found_with_its_depth_and_the_wall_behind():
    low = tof_footprint(_animal(), R)
    near, far = thin_parts(low, 100.0)
    leg = np.zeros(low.shape, bool)
    leg[8:20, 10] = True
    assert low[leg] == pytest.approx(0.5 * (BODY + WALL))  # mixed along its whole length
    np.testing.assert_array_equal(near > 0, leg)
    np.testing.assert_allclose(near[leg], BODY)
    np.testing.assert_allclose(far[leg], WALL)
    assert (far[~leg] == 0).all()


def test_a_part_that_fills_its_pixels_or_has_no_nearer_surface_is_not_split():
    # a leg a whole pixel wide at the body's depth: measured as it is, no mix
    whole = tof_footprint(_animal(leg_x_px=40.0, leg_width_px=4.0), R)
    assert (thin_parts(whole, 100.0)[0] == 0).all()
    # a thin cable hanging in front of the wall, nothing nearer within reach: nothing says
    # how deep it is, so it is left as measured
    truth = np.full((24 * R, 24 * R), WALL, np.float32)
    truth[4 * R : 20 * R, 41:43] = 2000.0
    low = tof_footprint(truth, R)
    fused = np.kron(low, np.ones((R, R), np.float32))
    np.testing.assert_array_equal(split_thin_parts(fused, low, 100.0), fused)
    # the leg far from the body it grows out of (beyond the reach): left as measured too
    near, _ = thin_parts(tof_footprint(_animal(), R), 100.0, reach_px=3)
    assert (near[8:11, 10] > 0).all() and (near[11:20, 10] == 0).all()


@pytest.mark.parametrize("leg_x_px", [40.0, 41.0, 42.0])
def test_the_split_keeps_the_footprints_mean_and_leaves_no_flying_pixel(leg_x_px):
    truth = _animal(leg_x_px=leg_x_px)
    low = tof_footprint(truth, R)
    fused = np.kron(low, np.ones((R, R), np.float32))  # nearest upsampling: the mixes
    assert flying_pixel_mask(fused, truth, R).sum() >= 12 * R * R
    out = split_thin_parts(fused, low, 100.0)
    assert flying_pixel_mask(out, truth, R).sum() == 0
    blocks = out[8 * R : 20 * R, 10 * R : 11 * R].reshape(12, R, R)
    assert set(np.unique(blocks)) == {BODY, WALL}
    np.testing.assert_allclose(blocks.mean(axis=(1, 2)), low[8:20, 10])  # the mean kept
    # one frame cannot tell where in its pixel the leg lies: it runs down the middle of the
    # column of blocks (a line, not scattered pixels), widening into the body at its top
    np.testing.assert_array_equal(blocks[1:-1, :, 1:3], BODY)
    assert (blocks[0, 0] == BODY).all()
    np.testing.assert_array_equal(np.delete(out, range(10 * R, 11 * R), axis=1),
                                  np.delete(fused, range(10 * R, 11 * R), axis=1))  # fmt: skip


def test_split_mixed_pixels_splits_thin_parts_for_a_footprint_sensor_only():
    truth = _animal()
    low = tof_footprint(truth, R)
    fused = np.kron(low, np.ones((R, R), np.float32))
    tof = split_mixed_pixels(fused, low, low, low, keep_mean=True, edge_mm=100.0)
    assert flying_pixel_mask(tof, truth, R).sum() == 0
    # a point-sampling sensor's thin part measured its depth: kept
    np.testing.assert_array_equal(split_mixed_pixels(fused, low, low, low, edge_mm=100.0), fused)


@pytest.mark.parametrize("mode", ["windowed", "recursive"])
def test_a_thin_leg_of_a_tof_video_reaches_the_output_without_flying_pixels(mode):
    """End to end: a leg half a ToF pixel wide, moving 1 high-res px per frame, survives at
    the body's depth and no pixel of the output lies between it and the wall."""
    truths = np.stack([_animal(leg_x_px=38.0 + k) for k in range(7)])
    low = tof_footprint(truths, R)
    out = upsr.super_resolve(low, R, 5, remove_mixed=True, mode=mode)
    assert flying_pixel_mask(out, truths, R).sum() == 0
    legs = out[:, 8 * R : 20 * R, 9 * R : 12 * R]
    width = (np.abs(legs - BODY) < 100).sum(axis=2)
    # every row of its blocks keeps it, 2 px wide as it is, but those of its two ends: there
    # the part is drawn towards the body, or split across a diagonal at its tip, where it
    # straddles two pixels (one frame cannot tell)
    assert width[:, R:-R].min() == 2 and width[:, R:-R].max() == 2
    assert width[:, :R].sum(axis=1).min() >= 8 and width[:, -R:].sum(axis=1).min() >= 8
    hit = (np.abs(legs - BODY) < 100) & (
        np.abs(truths[:, 8 * R : 20 * R, 9 * R : 12 * R] - BODY) < 1
    )
    assert hit.sum() >= 0.5 * width.sum()  # mostly where it is
    # the mixes without the rule
    for options in (dict(remove_mixed=False), dict(remove_mixed=True, thin_parts=False)):
        off = upsr.super_resolve(low, R, 5, mode=mode, deblur=False, **options)
        assert flying_pixel_mask(off, truths, R).sum() > 0, options


def test_a_leg_beside_a_gap_one_pixel_wide_is_found():
    # two legs half a pixel wide, the second closing in on the first: one pixel of wall
    # between them further down, whose surface there is only the gap's pixels above and below
    truth = _animal()
    yy, xx = np.mgrid[0 : truth.shape[0], 0 : truth.shape[1]] + 0.5
    truth[(xx > 53.0) & (xx < 55.0) & (yy >= 8 * R) & (yy < 14 * R)] = BODY
    truth[(xx > 49.0) & (xx < 51.0) & (yy >= 14 * R) & (yy < 20 * R)] = BODY
    low = tof_footprint(truth, R)
    near, far = thin_parts(low, 100.0)
    legs = np.zeros(low.shape, bool)
    legs[8:20, 10] = legs[8:14, 13] = legs[14:20, 12] = True
    np.testing.assert_array_equal(near > 0, legs)
    np.testing.assert_allclose(near[legs], BODY)
    np.testing.assert_allclose(far[legs], WALL)


# A box's top-left corner in front of a wall, realistic ToF room (seed 2, frame 0): a line
# of mixed pixels along the box's top edge (3016, 3010, ...) and down its left side (4106,
# 4125), a face sloping towards the camera below it.
BOX_CORNER = np.array(
    [[4494, 4504, 4481, 4481, 4489, 4472, 4458, 4467, 4470, 4461, 4455],
     [4486, 4476, 4488, 4471, 4479, 4465, 4477, 4469, 4492, 4441, 4457],
     [4482, 4482, 4486, 4106, 3016, 3010, 3036, 3022, 3007, 3008, 2998],
     [4485, 4476, 4479, 4125, 2413, 2374, 2378, 2347, 2375, 2378, 2374],
     [4491, 4463, 4474, 4477, 3137, 2215, 2220, 2212, 2204, 2213, 2230],
     [4486, 4469, 4475, 4487, 4197, 2147, 2084, 2080, 2084, 2087, 2079],
     [4420, 4423, 4397, 4435, 4423, 3110, 1976, 1939, 1983, 1953, 1961],
     [4189, 4198, 4198, 4200, 4199, 4100, 2068, 1856, 1865, 1861, 1860],
     [3972, 3989, 3929, 3702, 3721, 3708, 2780, 1798, 1784, 1780, 1785],
     [3786, 3789, 3529, 2731, 2738, 2718, 2679, 1848, 1788, 1781, 1786]],
    np.float32,
)  # fmt: skip


def test_a_mixed_pixel_never_ends_a_run():
    # a line of mixed pixels has two neighbours on it (before and after along the edge), as
    # many as the wall seen through a one-pixel gap: its own test keeps it from being taken
    # for the surface behind a thin part, whose depth the split would give half a block
    mixed = mixed_pixels(BOX_CORNER, 100.0)
    assert mixed[2, 3:].all()
    near, far = thin_parts(BOX_CORNER, 100.0)
    assert not set(far[near > 0].tolist()) & set(BOX_CORNER[mixed].tolist())
    _, unguarded = thin_parts(BOX_CORNER, 100.0, mixed=np.zeros(BOX_CORNER.shape, bool))
    assert 3010.0 in unguarded  # (without the test, a mix of the line is taken for B)


def test_two_ends_on_one_surface_need_one_neighbour_each():
    # two legs with one pixel of wall between them, closed by the body above and a foot
    # below: the gap's first and last pixels have one neighbour on the wall, which both
    # ends of each leg's row see (ends within the edge threshold of each other)
    z = np.full((12, 10), WALL, np.float32)
    z[0:2, 1:9] = BODY
    z[2:8, 3] = z[2:8, 5] = 2400.0
    z[8, 2:7] = 2400.0
    near, far = thin_parts(z, 100.0)
    legs = np.zeros(z.shape, bool)
    legs[2:8, [3, 5]] = legs[8, 2:7] = True
    np.testing.assert_array_equal(near > 0, legs)
    np.testing.assert_allclose(near[legs], BODY)
    np.testing.assert_allclose(far[legs], WALL)


def _leg_through_a_pixel_of_leg(step_beside=False):
    """A leg two pixels wide holding a quarter of wall below a pixel that the leg fills but
    for a sliver (2282 mm, less than the edge threshold in front of the leg's mixes, beside
    a mix of leg and wall 2804 mm: the realistic ToF galloping animal, seed 0, frame 1)."""
    z = np.full((10, 10), WALL, np.float32)
    z[0:2, 2:9] = 2115.0
    z[2, 4:7] = 2385.0, 2282.0, 2250.0 if step_beside else 2804.0
    z[3:7, 4] = 2340.0
    z[3:7, 5] = 2330.0
    return z


def test_a_part_reaches_its_surface_through_a_pixel_it_fills():
    near, far = thin_parts(_leg_through_a_pixel_of_leg(), 100.0)
    leg = np.zeros((10, 10), bool)
    leg[3:7, 4:6] = True
    np.testing.assert_array_equal(near > 0, leg)
    np.testing.assert_allclose(near[leg], 2115.0)
    np.testing.assert_allclose(far[leg], WALL)
    # that pixel with a neighbour on its own surface (a step of a staircase one pixel tall,
    # a box's corner) is a surface, not the part: no depth through it
    assert (thin_parts(_leg_through_a_pixel_of_leg(step_beside=True), 100.0)[0] == 0).all()


def test_the_thin_parts_of_the_removal_are_those_the_split_would_find():
    # found once per frame: remove_mixed_pixels hands them to split_mixed_pixels
    low = tof_footprint(_animal(), R)
    video = np.stack([low, tof_footprint(_animal(leg_x_px=42.0), R)])
    cleaned, thin = remove_mixed_pixels(video, 100.0, return_thin_parts=True)
    np.testing.assert_array_equal(cleaned, remove_mixed_pixels(video, 100.0))
    near, far = thin_parts(low, 100.0)
    np.testing.assert_array_equal(thin.near[0], near)
    np.testing.assert_array_equal(thin.far[0], far)
    assert (thin.axis[0][near > 0] == 0).all()  # a leg along a column: its run is a row's
    fused = np.kron(low, np.ones((R, R), np.float32))
    kw = {"keep_mean": True, "edge_mm": 100.0}
    once = split_mixed_pixels(
        fused, low, cleaned[0], low, **kw, thin=ThinParts(*(a[0] for a in thin))
    )
    np.testing.assert_array_equal(once, split_mixed_pixels(fused, low, cleaned[0], low, **kw))
    assert (once != fused).any()
    with pytest.raises(ValueError, match="thin parts"):
        split_thin_parts(fused, low, 100.0, parts=thin)  # a video's, not the frame's
    assert remove_mixed_pixels(low, 100.0, thin_parts=False, return_thin_parts=True)[1] is None


def _gap(leg_depth=2100.0, r=R, n=24):
    """High-res truth: a body with two legs a pixel and a half wide, at different depths,
    and between them a gap of the wall half a low-res pixel wide, open below the legs."""
    truth = np.full((n * r, n * r), WALL, np.float32)
    truth[3 * r : 8 * r, 4 * r : 20 * r] = BODY
    truth[8 * r : 18 * r, 24:30] = BODY  # the left leg
    truth[8 * r : 18 * r, 32:38] = leg_depth  # the right leg, 2 px of wall between them
    return truth


def test_a_gap_narrower_than_a_pixel_is_split_between_the_wall_and_the_legs():
    """The mirror image of a thin part: the pixels that straddle the gap mix a leg and the
    wall, farther than both legs beside them. F is the wall's depth where the gap opens onto
    it, B the nearer side's; the split keeps the mean and leaves no flying pixel."""
    truth = _gap()
    low = tof_footprint(truth, R)
    near, far = thin_parts(low, 100.0)
    assert (low[8:18, 7] > 2100.0 + 100.0).all()  # farther than both legs
    # (its first and last pixels, beside the body's corner and the legs' tips, are left to
    # the mixed-pixel test and the thin-part search)
    gap = near > far
    np.testing.assert_array_equal(np.argwhere(gap), [[i, 7] for i in range(9, 17)])
    np.testing.assert_allclose(near[gap], WALL)
    np.testing.assert_allclose(far[gap], 2100.0)
    fused = np.kron(low, np.ones((R, R), np.float32))
    assert flying_pixel_mask(fused, truth, R).sum() >= 10 * R * R
    out = split_thin_parts(fused, low, 100.0)
    blocks = out[9 * R : 17 * R, 7 * R : 8 * R].reshape(8, R, R)
    assert set(np.unique(blocks)) == {2100.0, WALL}
    np.testing.assert_allclose(blocks.mean(axis=(1, 2)), low[9:17, 7], atol=0.5 * 900 / R**2)
    assert not flying_pixel_mask(out, truth, R)[9 * R : 17 * R, 7 * R : 8 * R].any()
    # end to end, both modes
    for mode in ("windowed", "recursive"):
        video = np.stack([low] * 5)
        res = upsr.super_resolve(video, R, 5, remove_mixed=True, mode=mode)
        assert flying_pixel_mask(res, np.stack([truth] * 5), R).sum() == 0, mode


def test_a_leg_that_fills_a_pixel_across_gives_its_depth_to_the_part_below_it():
    """A leg that fills one column of pixels (each one a thin run itself, its depth found
    nowhere nearer) and then runs on between two columns, three quarters of each: the mixes
    take the depth of the tip of the line above them (realistic ToF galloping animal, σ = 20
    mm, seed 0, frame 4: 1265 flying pixels here before)."""
    yy, xx = np.mgrid[0 : 24 * R, 0 : 24 * R] + 0.5
    truth = np.full(yy.shape, WALL, np.float32)
    truth[3 * R : 8 * R, 4 * R : 20 * R] = BODY
    truth[(xx > 40) & (xx < 44) & (yy >= 8 * R) & (yy < 12 * R)] = BODY  # column 10
    truth[(xx > 37) & (xx < 43) & (yy >= 12 * R) & (yy < 20 * R)] = BODY  # 3/4 of 9 and 10
    low = tof_footprint(truth, R)
    near, far = thin_parts(low, 100.0)
    part = np.zeros(low.shape, bool)
    part[12:20, 9:11] = True
    np.testing.assert_array_equal(near > 0, part)
    np.testing.assert_allclose(near[part], BODY)
    np.testing.assert_allclose(far[part], WALL)
    for mode in ("windowed", "recursive"):
        res = upsr.super_resolve(np.stack([low] * 5), R, 5, remove_mixed=True, mode=mode)
        assert flying_pixel_mask(res, np.stack([truth] * 5), R).sum() == 0, mode
    # a line of mixes with nothing nearer (a cable thinning in front of the wall) gives its
    # depth to nothing: its tip is a mix
    cable = np.full((12, 12), WALL, np.float32)
    cable[0:6, 5] = 2400.0
    cable[6:10, 5] = 2700.0
    assert (thin_parts(cable, 100.0)[0] == 0).all()
