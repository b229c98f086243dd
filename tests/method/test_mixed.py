"""Mixed (flying) input pixels: detection, abstention and the split of the reference's
(upsr.method.mixed)."""

import numpy as np
import pytest

import upsr
from tests.method._helpers import WALL, tof_edge_frames
from upsr.method.config import UPSRConfig
from upsr.method.mixed import remove_mixed_pixels


def _mixed_column(row, column, r=4):
    """Five rows of the profile ``row`` (mm) whose pixel ``column`` is removed as mixed:
    (measured, cleaned, fused), the fusion as the cleaned frame upsampled by ``r``."""
    measured = np.repeat(np.asarray(row, np.float32)[None], 5, axis=0)
    cleaned = measured.copy()
    cleaned[:, column] = 0.0
    return measured, cleaned, np.repeat(np.repeat(cleaned, r, axis=0), r, axis=1)


def test_mixed_pixels_are_removed_and_never_reach_the_output():
    frames = np.full((5, 8, 10), WALL, np.float32)
    frames[:, :, :5] = 1000.0
    mixed = frames.copy()
    for k in range(5):
        mixed[k, 2 + k % 3, 5] = 2000.0  # ToF footprint across the edge, in every frame
    clean = remove_mixed_pixels(mixed, 100.0)
    np.testing.assert_array_equal(clean, np.where(mixed != frames, 0.0, frames))
    # edges, slopes and single outliers at one side are not mixed pixels
    np.testing.assert_array_equal(remove_mixed_pixels(frames, 100.0), frames)
    kw = dict(deblur=False, noise_mm=2.0, speckle_px=0)
    out = upsr.super_resolve(mixed, 2, 5, remove_mixed=True, **kw)
    valid = out[out > 0]
    near_surface = (np.abs(valid - 1000) <= 100) | (np.abs(valid - WALL) <= 100)
    assert near_surface.all()
    # without it (nor the bilinear votes at edges, which outvote this one) it survives
    off = upsr.super_resolve(mixed, 2, 5, remove_mixed=False, edge_votes=False, **kw)
    assert np.any(np.abs(off - 2000) < 100)


def test_a_steep_slope_is_not_taken_for_mixed_pixels():
    """A floor seen at a grazing angle steps by more than edge_mm from pixel to pixel, evenly
    (or growing with depth): none of it is a mixed pixel; a pixel between two flat runs is."""
    from upsr.method.mixed import remove_mixed_pixels

    rows = 1000.0 + 150.0 * np.arange(12, dtype=np.float32) ** 1.3  # steps 150..~500 mm
    floor = np.repeat(rows[:, None], 10, axis=1)
    np.testing.assert_array_equal(remove_mixed_pixels(floor, 100.0), floor)
    edge = np.full((9, 9), 1000.0, np.float32)
    edge[:, 5:] = 3000.0
    edge[:, 4] = 2000.0  # the mixed column between the two flat surfaces
    out = remove_mixed_pixels(edge, 100.0)
    assert (out[:, 4] == 0).all() and (out[:, :4] == 1000).all() and (out[:, 5:] == 3000).all()


def test_remove_mixed_auto_follows_the_sensor():
    from upsr.method.frontend import MotionFrontEnd
    from upsr.method.statistics import fix_video_statistics

    tof = np.repeat(tof_edge_frames(), 3, axis=0)
    point = np.where(tof > 2000, WALL, 1000.0).astype(np.float32)
    for frames, expected in ((tof, True), (point, False)):
        cfg = UPSRConfig(scale=2, n_frames=9)
        stats = fix_video_statistics(MotionFrontEnd(cfg, frames.shape[-1]), frames, cfg)
        assert stats.remove_mixed is expected
    cfg = UPSRConfig(scale=2, n_frames=9, remove_mixed=False)
    assert not fix_video_statistics(MotionFrontEnd(cfg, 16), tof, cfg).remove_mixed


def test_a_mixed_reference_pixel_no_frame_fills_is_split_between_its_neighbours():
    from upsr.method.mixed import split_mixed_pixels

    measured = np.full((6, 7), WALL, np.float32)
    measured[:, :3] = 1000.0
    measured[:, 3] = 2200.0  # mixed in every row
    cleaned = remove_mixed_pixels(measured, 100.0)
    assert (cleaned[:, 3] == 0).all()
    fused = np.repeat(np.repeat(cleaned, 4, 0), 4, 1)
    fused[0, 13] = 1500.0  # a value some frame gave: kept
    out = split_mixed_pixels(fused, measured, cleaned, cleaned)
    block = out[4:8, 12:16]
    # the side facing the foreground takes it, the other the wall, in the shares of the mix
    # (0.4 : 0.6 of the footprint): never 0, never 2200
    assert set(np.unique(block)) == {1000.0, WALL}
    assert (block == 1000.0).sum() == round(0.4 * 16)
    np.testing.assert_array_equal(block[:, 0], 1000.0)
    np.testing.assert_array_equal(block[:, 2:], WALL)
    assert out[0, 13] == 1500.0
    np.testing.assert_array_equal(
        np.delete(out, range(12, 16), axis=1), np.delete(fused, range(12, 16), axis=1)
    )
    # nothing removed: unchanged
    np.testing.assert_array_equal(split_mixed_pixels(fused, cleaned, cleaned, cleaned), fused)


def test_remove_mixed_can_mark_pixels_to_abstain():
    from upsr.method.mixed import ABSTAIN

    frames = np.full((2, 5, 7), WALL, np.float32)
    frames[:, :, :3] = 1000.0
    frames[:, :, 3] = 2200.0
    out = remove_mixed_pixels(frames, 100.0, marker=ABSTAIN)
    assert (out[:, :, 3] == ABSTAIN).all() and ABSTAIN < 0


@pytest.mark.parametrize("slant", [0.15, 0.2, 0.3])
@pytest.mark.parametrize("offset_px", [0.0, 0.3, 0.5])
def test_a_slanted_thin_leg_is_mixed_along_its_columns(slant, offset_px):
    """A leg 1.5 px wide that crosses the pixel grid at a slant (ToF footprints of r = 4): along
    a column its share of each footprint grows row by row, a ramp of mixed pixels that steps
    like a slope seen at a grazing angle. Across it lie the wall and the leg's next column,
    which do not step the same way: every pixel more than edge_mm from both the leg and the
    wall is mixed (before: 1-8 of them kept at these slants)."""
    r, n = 4, 24
    yy, xx = np.mgrid[0 : n * r, 0 : n * r] + 0.5
    truth = np.full(yy.shape, WALL)
    truth[: 5 * r] = 1800.0  # the body the leg grows from
    centre = 8 * r + offset_px * r + slant * (yy - 5 * r)
    truth[(np.abs(xx - centre) < 0.75 * r) & (yy > 5 * r) & (yy < 20 * r)] = 2000.0
    low = truth.reshape(n, r, n, r).mean(axis=(1, 3)).astype(np.float32)
    out = remove_mixed_pixels(low, 100.0)
    mixed = (low - 2000.0 > 100.0) & (WALL - low > 100.0)
    mixed[:6] = False  # the body's own edge
    assert mixed.sum() >= 8
    assert (out[mixed] == 0).all()


def test_a_steep_slope_from_another_surface_is_kept_a_short_ramp_is_not():
    from upsr.method.mixed import remove_mixed_pixels

    # a floor (steps of 300 mm) that begins below a flat back wall: four steep steps
    col = np.array([4500, 4500, 4500, 4000, 3700, 3400, 3100, 2800], np.float32)
    floor = np.repeat(col[:, None], 6, axis=1)
    np.testing.assert_array_equal(remove_mixed_pixels(floor, 100.0), floor)
    # a ToF ramp of two mixed pixels between two flat surfaces
    col = np.array([4500, 4500, 4500, 3800, 2700, 1500, 1500, 1500], np.float32)
    ramp = np.repeat(col[:, None], 6, axis=1)
    out = remove_mixed_pixels(ramp, 100.0)
    assert (out[3:5] == 0).all() and (out[:3] == 4500).all() and (out[5:] == 1500).all()


def test_a_slope_that_tapers_into_a_flat_surface_is_kept():
    """A box side seen at a grazing angle, two ToF pixels wide between the wall and the box
    front (the realistic approaching camera): its second pixel steps like the first, whose
    step from the wall stays within the edge threshold; a footprint across a depth edge
    mixes one pixel per column, so this is a slope, not a mix. The same pixel between a
    flat run and a run that steps beyond the threshold stays mixed."""
    col = np.array([2400, 2400, 2400, 2321, 2172, 2046, 2046, 2046], np.float32)
    face = np.repeat(col[:, None], 6, axis=1)
    np.testing.assert_array_equal(remove_mixed_pixels(face, 100.0), face)
    # a ToF footprint of a high-res face 8 px wide between the two flat surfaces (where the
    # face begins 2 px into a block instead, its first pixel is within 12 mm of the wall and
    # the second is taken for a mix: that footprint cannot tell the two apart)
    from upsr.research.synth.degradation import tof_footprint

    r = 4
    y = np.arange(12 * r, dtype=np.float32)
    hr_col = np.clip(2400.0 - 45.0 * (y - 3 * r), 2046.0, 2400.0)
    z = tof_footprint(np.repeat(hr_col[:, None], 6 * r, axis=1), r)
    between = (z[:, 0] < 2390) & (z[:, 0] > 2056)
    assert between.sum() == 2  # the face: two pixels between the surfaces
    np.testing.assert_array_equal(remove_mixed_pixels(z, 100.0), z)
    # a mixed pixel whose steps agree with the next one, which exceeds the threshold (the
    # realistic room: a wall, the mixed line, a mixed ramp onto the floor)
    col = np.array([4430, 4430, 4430, 3553, 3093, 2840, 2840, 2840], np.float32)
    z = np.repeat(col[:, None], 6, axis=1)
    out = remove_mixed_pixels(z, 100.0)
    assert (out[3] == 0).all()
    np.testing.assert_array_equal(out[:3], z[:3])
    np.testing.assert_array_equal(out[5:], z[5:])


def test_a_line_of_mixed_pixels_beside_a_steep_surface_is_mixed():
    """A ToF row along the edge between a flat wall and a box top seen at a grazing angle: the
    step from the line into the box top (-519 mm) is 2.4 times the next one (-217), which a
    slope seen at a grazing angle never does; the steep box top itself stays."""
    col = np.array([3430, 3431, 3429, 3430, 2958, 2439, 2222, 2080, 1960, 1850], np.float32)
    z = np.repeat(col[:, None], 8, axis=1)
    out = remove_mixed_pixels(z, 100.0)
    assert (out[4] == 0).all()  # the mixed line
    np.testing.assert_array_equal(np.delete(out, 4, axis=0), np.delete(z, 4, axis=0))


def test_the_split_of_a_mixed_pixel_keeps_its_footprints_mean():
    """A ToF pixel a quarter on the near wall and three quarters on the far one is split 4 : 12
    (r = 4), the near pixels on the near wall's side: the block's mean is the measurement,
    and no pixel takes a depth between the walls."""
    from upsr.method.mixed import split_mixed_pixels

    r = 4
    measured = np.full((5, 7), 3000.0, np.float32)
    measured[:, :3] = 1000.0
    measured[:, 3] = 0.25 * 1000.0 + 0.75 * 3000.0
    cleaned = remove_mixed_pixels(measured, 100.0)
    assert (cleaned[:, 3] == 0).all()
    fused = np.repeat(np.repeat(cleaned, r, axis=0), r, axis=1)
    out = split_mixed_pixels(fused, measured, cleaned, cleaned)
    block = out[2 * r : 3 * r, 3 * r : 4 * r]
    assert set(np.unique(block)) == {1000.0, 3000.0}
    assert block.mean() == pytest.approx(measured[2, 3])
    assert (block[:, 0] == 1000.0).all() and (block[:, 1:] == 3000.0).all()
    # a lone outlier (one side only) takes its neighbours' depth
    lone = np.full((5, 5), 2000.0, np.float32)
    lone[2, 2] = 2600.0
    kept = lone.copy()
    kept[2, 2] = 0.0
    out = split_mixed_pixels(np.repeat(np.repeat(kept, r, 0), r, 1), lone, kept, kept)
    assert (out == 2000.0).all()


def test_the_first_pixel_of_a_steep_slope_beside_a_mixed_line_is_kept():
    """A ToF column from the back wall over the line of mixed pixels in front of it onto a box
    top seen at a grazing angle (the realistic ToF room): the slope's first pixel lies between
    the mixed line and its own slope, not between two surfaces; only the line is mixed."""
    col = np.array([4460, 4459, 4460, 3491, 2387, 2220, 2050, 1890, 1760], np.float32)
    z = np.repeat(col[:, None], 8, axis=1)
    out = remove_mixed_pixels(z, 100.0)
    assert (out[3] == 0).all()
    np.testing.assert_array_equal(np.delete(out, 3, axis=0), np.delete(z, 3, axis=0))


def test_a_fused_block_that_misses_the_mixed_pixels_mean_is_split_afresh():
    """Misregistered samples that filled a mixed pixel's block wholly with the far wall leave
    its mean (2000 mm) far from what it measured: with keep_mean the block is split 8 : 8 as if
    no frame had filled it; a fill that keeps the mean stays; without keep_mean (outliers of a
    point-sampling sensor) nothing changes."""
    from upsr.method.mixed import split_mixed_pixels

    r = 4
    measured = np.full((5, 7), 3000.0, np.float32)
    measured[:, :3] = 1000.0
    measured[:, 3] = 2000.0
    cleaned = remove_mixed_pixels(measured, 100.0)
    fused = np.repeat(np.repeat(measured, r, axis=0), r, axis=1)
    fused[:, 3 * r : 4 * r] = 3000.0  # misregistered: the wall over the whole block
    out = split_mixed_pixels(fused, measured, cleaned, cleaned, keep_mean=True)
    block = out[:, 3 * r : 4 * r]
    assert np.allclose(block.reshape(5, r, r).mean(axis=(1, 2)), 2000.0)
    assert (block[:, : r // 2] == 1000.0).all() and (block[:, r // 2 :] == 3000.0).all()
    np.testing.assert_array_equal(split_mixed_pixels(fused, measured, cleaned, cleaned), fused)
    good = fused.copy()
    good[:, 3 * r : 3 * r + r // 2] = 1000.0  # a fill that followed the edge
    good[:, 3 * r + 1 : 3 * r + 2] = 1000.0 + 1.0  # (its own values, within the tolerance)
    np.testing.assert_array_equal(
        split_mixed_pixels(good, measured, cleaned, cleaned, keep_mean=True), good
    )


def test_the_split_follows_the_slope_of_each_side_into_the_block():
    """A mixed pixel between a flat wall (1000 mm) and a floor seen at a grazing angle that
    nears it by 300 mm per pixel: the far half of the block continues the floor's slope
    (2700 mm at the next pixel's centre, 300 mm less per pixel towards the block), the near
    half stays on the flat wall."""
    from upsr.method.mixed import split_mixed_pixels

    r = 4
    measured, cleaned, fused = _mixed_column([1000, 1000, 1000, 1850, 2700, 3000, 3300, 3600], 3)
    out = split_mixed_pixels(fused, measured, cleaned, cleaned, keep_mean=True)
    block = out[2 * r : 3 * r, 3 * r : 4 * r]
    assert (block[:, :2] == 1000.0).all()
    # far pixels at x = 14, 15: 0.875 and 0.625 px from the next pixel's centre (x = 17.5)
    np.testing.assert_allclose(block[:, 2:], [[2437.5, 2512.5]] * r)
    # its steps beyond the edge threshold go on alike: a slope with the threshold too
    np.testing.assert_array_equal(
        split_mixed_pixels(fused, measured, cleaned, cleaned, keep_mean=True, edge_mm=100.0), out
    )


def test_the_split_does_not_take_a_like_mix_beside_a_thin_part_for_its_slope():
    """A leg at 1850 mm, one pixel wide, between a mixed pixel on its left (removed) and a
    column of like mixes of another leg on its right (2330 / 2350 mm, kept) in front of a
    wall at 3000 mm (the realistic ToF animal): the step from the first like mix to the leg
    (−480 mm) is no slope of the leg, since the next step (−20 mm) does not go on alike. The
    removed pixel's near side takes the leg's depth, never 1850 − 480 mm, nearer than any
    surface there."""
    from upsr.method.mixed import split_mixed_pixels

    r = 4
    measured, cleaned, fused = _mixed_column([3000, 3000, 2400, 1850, 2330, 2350, 3000, 3000], 2)
    out = split_mixed_pixels(fused, measured, cleaned, cleaned, keep_mean=True, edge_mm=100.0)
    block = out[:, 2 * r : 3 * r]
    assert set(np.unique(block)) == {1850.0, 3000.0}
    # without the edge threshold the step counts as the leg's slope
    loose = split_mixed_pixels(fused, measured, cleaned, cleaned, keep_mean=True)
    assert loose[:, 2 * r : 3 * r].min() < 1850.0 - 100.0
    # a steep step towards the mix is followed however the next one steps (a floor strip
    # seen at a grazing angle that ends at a box)
    measured, cleaned, fused = _mixed_column([690, 700, 1000, 2000, 3000, 3000, 3000], 3)
    out = split_mixed_pixels(fused, measured, cleaned, cleaned, keep_mean=True, edge_mm=100.0)
    near = out[:, 3 * r : 4 * r][out[:, 3 * r : 4 * r] < 2000.0]
    assert near.size and (near > 1000.0 + 100.0).all()


def test_a_fill_of_other_frames_mixes_is_split_afresh():
    """Other frames' mixes that their own test missed fill the block with about what the
    reference measured (its mean is kept) but lie between the surfaces: with keep_mean the
    block is split, without it kept."""
    from upsr.method.mixed import split_mixed_pixels

    r = 4
    measured = np.full((5, 7), 3000.0, np.float32)
    measured[:, :3] = 1000.0
    measured[:, 3] = 2000.0
    cleaned = remove_mixed_pixels(measured, 100.0)
    fused = np.repeat(np.repeat(measured, r, axis=0), r, axis=1)  # the mixes, 2000 mm
    out = split_mixed_pixels(fused, measured, cleaned, cleaned, keep_mean=True)
    assert set(np.unique(out[:, 3 * r : 4 * r])) == {1000.0, 3000.0}
    np.testing.assert_array_equal(split_mixed_pixels(fused, measured, cleaned, cleaned), fused)


def test_a_fill_beyond_the_edge_threshold_from_both_surfaces_is_split_afresh():
    """A leg 1150 mm in front of the wall, its ToF pixel a quarter on the leg: the fusion put
    the leg's column 275 mm behind the leg (within a quarter of the step, beyond the edge
    threshold). With the threshold that column lies between the surfaces and the block is
    split afresh (the leg's column takes the leg's depth); without it the fill stays."""
    from upsr.method.mixed import split_mixed_pixels

    r = 4
    leg, wall = 1850.0, 3000.0
    measured = np.full((5, 7), wall, np.float32)
    measured[:, 4:] = leg
    measured[:, 3] = 0.25 * leg + 0.75 * wall
    cleaned = remove_mixed_pixels(measured, 100.0)
    assert (cleaned[:, 3] == 0).all()
    fused = np.repeat(np.repeat(cleaned, r, axis=0), r, axis=1)
    fused[:, 3 * r : 4 * r - 1] = wall
    fused[:, 4 * r - 1] = leg + 275.0  # the block's mean stays within the tolerance
    args = (fused, measured, cleaned, cleaned)
    kept = split_mixed_pixels(*args, keep_mean=True)
    np.testing.assert_array_equal(kept, fused)
    out = split_mixed_pixels(*args, keep_mean=True, edge_mm=100.0)
    block = out[:, 3 * r : 4 * r]
    assert set(np.unique(block)) == {leg, wall}
    assert (block[:, -1] == leg).all() and (block[:, :-1] == wall).all()


@pytest.mark.parametrize("side", ["left", "right", "top", "bottom"])
def test_a_footprint_across_an_edge_beyond_the_image_border_is_mixed(side):
    """The first column of a ToF frame a quarter on a wall that no other pixel sees and three
    quarters on the box in front of it (realistic ToF room, seed 2): nothing shows the depth
    behind it, yet it belongs to neither surface; a border pixel on a surface of its own, or
    one beside a slope, stays."""
    from upsr.research.synth.degradation import tof_footprint

    r = 4
    hr = np.full((12 * r, 14 * r), 1500.0, np.float32)
    hr[:, :1] = 2480.0  # the wall's sliver inside the first column's footprint
    hr[: 6 * r, : 3 * r] = 2480.0  # above: the wall seen over three pixels
    hr[6 * r : 7 * r, :r] = 2480.0  # and one pixel of it at the border below them
    low = tof_footprint(hr, r)
    turn = {"left": 0, "bottom": 1, "right": 2, "top": 3}[side]
    z = np.rot90(low, turn).copy()
    out = np.rot90(remove_mixed_pixels(z, 100.0), -turn)
    assert low[8, 0] == pytest.approx(0.25 * 2480 + 0.75 * 1500)
    assert (out[7:, 0] == 0).all()  # the mix, all the way along the border below the wall
    np.testing.assert_array_equal(out[:, 1:], low[:, 1:])
    # the wall: a surface inward of it, also diagonally (the pixel of wall beside the box)
    np.testing.assert_array_equal(out[:7, 0], 2480.0)
    # a floor at a grazing angle down to the border: steps beyond the threshold, no mix
    floor = np.repeat((1000.0 + 150.0 * np.arange(10, dtype=np.float32) ** 1.3)[None], 6, 0)
    np.testing.assert_array_equal(remove_mixed_pixels(floor, 100.0), floor)
    # a surface whose edge falls on the pixels' boundary, nothing beyond it along the border
    # (a box top seen at the image's top, the wall above it beyond the image): kept
    # a slope that tapers into a flat surface at the border, something nearer above: kept
    taper = np.repeat((1000.0 + np.cumsum([0, 111, 95, 95, 95, 95, 95, 95]))[None], 9, 0)
    taper[:3] = 500.0
    kept = np.rot90(remove_mixed_pixels(np.rot90(taper.astype(np.float32), turn), 100.0), -turn)
    np.testing.assert_array_equal(kept[4:], taper[4:])  # (row 3: between the two surfaces)
    aligned = np.full((12, 14), 1500.0, np.float32)
    aligned[:, 0] = 2480.0
    aligned = np.rot90(aligned, turn).copy()
    np.testing.assert_array_equal(remove_mixed_pixels(aligned, 100.0), aligned)


def test_a_slope_two_pixels_wide_along_a_straight_edge_is_kept():
    """The realistic approaching camera (ToF σ = 10 mm, seed 1, frame 5, rows 12–26, columns
    37–43): a box side seen at a grazing angle spans two pixels of every row, its steep middle
    across their boundary (~2325 | ~2088 between the wall at ~2370 and the box at ~1985). A
    footprint across a straight edge mixes one pixel per row, so the same two pixels along
    seven rows are a slope, kept (`mixed.RAMP_ALONG_PX`; four of them were taken for mixed
    before). The same ramp on five rows only and a mixed line whose next pixel is the far
    surface a little nearer (2307 | 2117 above 2114) stay mixed."""
    side = np.array(
        [
            [2373, 2372, 2319, 2101, 2005, 1985, 1989],
            [2364, 2383, 2328, 2090, 1996, 1982, 1986],
            [2383, 2397, 2326, 2088, 1989, 1992, 1969],
            [2366, 2364, 2325, 2064, 1987, 1982, 2005],
            [2366, 2364, 2331, 2087, 1987, 1990, 1940],
            [2371, 2366, 2313, 2083, 1991, 2003, 1993],
            [2375, 2366, 2330, 2105, 1976, 1983, 1991],
            [2371, 2374, 2345, 2089, 1983, 1960, 1999],
            [2367, 2359, 2314, 2076, 1984, 1984, 2018],
            [2360, 2375, 2334, 2081, 1979, 1998, 1990],
            [2379, 2376, 2334, 2099, 1940, 1981, 1993],
            [2376, 2367, 2310, 2093, 1971, 1984, 1993],
            [2367, 2360, 2335, 2091, 1984, 1994, 1981],
            [2376, 2379, 2336, 2095, 1997, 1996, 2021],
            [2374, 2375, 2316, 2078, 2014, 1947, 1993],
        ],
        np.float32,
    )
    # (the rows with three more of the edge on either side: the patch's first row, without
    # rows above it here, is split)
    np.testing.assert_array_equal(remove_mixed_pixels(side, 100.0)[3:12], side[3:12])
    short = side.copy()
    short[[0, 1, 2, 3, 4, 10, 11, 12, 13, 14], 2] = 2370.0  # one mix per row outside rows 5-9
    short[[0, 1, 2, 3, 4, 10, 11, 12, 13, 14], 3] = 2200.0
    assert (remove_mixed_pixels(short, 100.0)[6:8, 3] == 0).all()

    rng = np.random.default_rng(5)
    col = np.array([2500, 2500, 2500, 2307, 2117, 2114, 2114, 2114], np.float32)
    line = col[:, None] + rng.normal(0.0, 8.0, (8, 9)).astype(np.float32)
    line[4] = line[5] + 3.0  # the pixel after the mix a little nearer than the far surface
    out = remove_mixed_pixels(line, 100.0)
    assert (out[3, 1:-1] == 0).all()


def test_a_mix_between_an_edge_and_a_slope_is_not_a_pixel_of_the_slope():
    """The realistic ToF room (σ = 10 mm, seed 3, frame 2, column 36 from row 38): a steep
    strip one pixel high between the wall and a slope seen at a grazing angle straddles two
    pixels, both mixed (the second a quarter strip, three quarters slope). Its five pixels'
    steps agree within a factor 3, but the second's step into the slope (358 mm) is 2.4 times
    the slope's next one (152): not a pixel of the slope (`slopes.STEEP_RUN_RATIO`; it reached
    the output as 1.9 % flying pixels). A slope's pixel whose step beyond is larger (a mix
    there) is a pixel of the slope."""
    col = np.array([4467, 4466, 4466, 3717, 2729, 2371, 2219, 2080, 1950, 1830], np.float32)
    z = np.repeat(col[:, None], 6, axis=1)
    out = remove_mixed_pixels(z, 100.0)
    assert (out[3:5] == 0).all()
    np.testing.assert_array_equal(out[5:], z[5:])

    col = np.array([2000, 2000, 2000, 2130, 2300, 2450, 2900, 3400, 3400, 3400], np.float32)
    z = np.repeat(col[:, None], 6, axis=1)
    out = remove_mixed_pixels(z, 100.0)
    np.testing.assert_array_equal(out[4], z[4])  # 170 | 150 then 450 to the mix
    assert (out[6] == 0).all()


def test_a_mix_beside_a_steep_floor_does_not_start_its_run():
    """The realistic ToF room (σ = 20 mm, 1 % dropouts, seed 1, frame 7, column 9 from row
    47): a floor seen at a grazing angle steps 170–180 mm per pixel, then a pixel mostly
    floor, partly the nearer surface below it, 334 mm, 1.83 times the floor's next step: a
    mix, not the first pixel of the floor's steep run (`slopes.STEEP_FIRST_RATIO`); the
    floor's own pixels, each stepping evenly into the next, stay."""
    col = np.array([3982, 3779, 3610, 3427, 3093, 2310, 2211, 2134, 2048], np.float32)
    z = np.repeat(col[:, None], 6, axis=1)
    out = remove_mixed_pixels(z, 100.0)
    assert (out[4] == 0).all()
    np.testing.assert_array_equal(out[:4], z[:4])
    np.testing.assert_array_equal(out[5:], z[5:])
    # the floor's last pixel stepping on at its own pace (1.3 times) to a nearer surface
    col = np.array([3982, 3779, 3610, 3427, 3189, 2589, 2580, 2571, 2562], np.float32)
    z = np.repeat(col[:, None], 6, axis=1)
    np.testing.assert_array_equal(remove_mixed_pixels(z, 100.0), z)


def test_the_bottom_of_a_gap_between_two_crossing_legs_is_mixed():
    """Two legs of the realistic galloping animal cross in front of the wall (128×112 ToF,
    seed 0, frame 1; legs at 2125 and 1850 mm, wall at 3000): the gap between them is
    narrower than a pixel, and its column (2298 … 2444 mm) is a mix of both legs and the
    wall, farther than both legs, while only the pixels beyond the legs show the wall. The
    thin parts' mirror image misses it (its sides are no surfaces of their own); it is mixed
    all the same. A gap one pixel wide that shows the wall itself is no mix."""
    patch = np.array(
        [
            [3033, 3010, 2987, 2779, 2125, 1929, 2141, 2994, 3001, 2972],
            [3004, 2994, 2994, 2782, 2124, 1941, 2152, 3004, 3004, 2997],
            [3001, 2997, 3001, 2780, 2126, 1927, 2142, 2994, 2995, 3011],
            [2973, 3010, 3003, 2685, 2123, 2014, 2145, 2998, 3003, 2999],
            [3000, 2996, 2998, 2571, 2137, 2133, 2138, 3004, 3021, 3002],
            [2996, 2986, 3003, 2557, 2123, 2298, 1995, 2997, 3001, 2994],
            [2992, 2992, 2998, 2563, 2125, 2428, 1858, 3001, 2990, 2999],
            [3006, 2989, 3000, 2559, 2129, 2434, 1847, 2998, 3001, 2994],
            [2997, 3004, 3008, 2570, 2107, 2443, 1847, 2999, 3003, 3008],
            [2983, 3005, 3002, 2566, 2129, 2414, 1852, 2991, 2998, 2997],
            [3006, 3012, 3001, 2365, 2342, 2444, 1845, 3003, 3009, 2992],
            [2993, 3013, 2996, 2335, 2363, 2437, 1851, 3002, 3017, 2993],
        ],
        np.float32,
    )
    out = remove_mixed_pixels(patch, 100.0, -1.0)
    assert (out[6:10, 5] < 0).all()
    assert (out[5:10, 4] == patch[5:10, 4]).all() and (out[6:10, 6] == patch[6:10, 6]).all()
    z = np.full((16, 16), 3000.0, np.float32)
    z[2:14, 6] = 2000.0
    z[2:14, 8] = 1900.0  # the wall seen whole between the two legs (column 7)
    assert (remove_mixed_pixels(z, 100.0, -1.0)[3:13, 7] == 3000.0).all()


def test_a_slope_stepping_by_about_the_edge_threshold_is_no_gap():
    """A wall seen at a grazing angle steps by about the edge threshold per pixel; where a
    nearer box stands beside it, a pixel of the wall lies behind both of its neighbours
    along a diagonal, one by just over the threshold (the slope), one by far more (the
    box): no gap between two nearer parts (realistic ToF room, seed 2)."""
    z = np.array(
        [
            [3211, 3316, 3433, 3539, 3176, 2650],
            [3216, 3306, 3423, 3084, 2654, 2651],
            [3213, 3311, 3409, 3080, 2648, 2652],
            [3219, 3329, 3424, 3076, 2653, 2649],
            [3220, 3318, 3406, 3056, 2650, 2650],
        ],
        np.float32,
    )
    out = remove_mixed_pixels(z, 100.0, -1.0)
    assert out[2, 2] == z[2, 2]


def test_a_mix_whose_only_neighbours_on_its_depth_are_mixes_is_mixed():
    """Beside two legs of the realistic galloping animal (128×112 ToF, seed 0, frame 1), the
    pixel at the centre (2127 mm: a quarter wall at 3000, three quarters leg at 1852) has
    three 8-neighbours within the edge threshold of it, the mixes of the legs' edges (2145,
    2064, 2126 mm): on no surface of its own, it is mixed. The legs and the wall are kept."""
    patch = np.array(
        [
            [2596, 1886, 1893, 1866, 1861, 1840, 1831, 1821, 1816, 1806, 1831],
            [3009, 2819, 2053, 1889, 1875, 1872, 1848, 1839, 1850, 1822, 1804],
            [2998, 3009, 2996, 2621, 2072, 1886, 1852, 1882, 1860, 1843, 1835],
            [3002, 3003, 2992, 3013, 3007, 2316, 1846, 1918, 1899, 1881, 1869],
            [2999, 3000, 3001, 3011, 3003, 2145, 1923, 2124, 2443, 2333, 2067],
            [3001, 2997, 3018, 3003, 2993, 2127, 1920, 2126, 2735, 2998, 2995],
            [2999, 3022, 3020, 3005, 3000, 2064, 2215, 2124, 2579, 2996, 2994],
            [3000, 3000, 3004, 3003, 2987, 1854, 2421, 2078, 2577, 3007, 3005],
            [3001, 2996, 2994, 3017, 3003, 1873, 2426, 2166, 2458, 3015, 2991],
            [3009, 3006, 2997, 3002, 2841, 1835, 2561, 2329, 2348, 2978, 2998],
            [2999, 3000, 3000, 2988, 2728, 1848, 2717, 2348, 2337, 2992, 3005],
        ],
        np.float32,
    )
    out = remove_mixed_pixels(patch, 100.0, -1.0)
    assert out[5, 5] < 0
    assert (out[5:7, 6] == patch[5:7, 6]).all() and (out[7:11, 5] == patch[7:11, 5]).all()
    assert (out[3:9, 0:4] == patch[3:9, 0:4]).all()
