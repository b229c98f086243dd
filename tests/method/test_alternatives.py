"""The other surfaces a sample may show at a depth edge (upsr.method.alternatives)."""

import numpy as np

from upsr.method.alternatives import alternatives_on_grid, side_of_centre, surface_alternatives

WALL = 3000.0


def test_alternatives_are_on_the_side_of_their_neighbour_only():
    np.testing.assert_array_equal(side_of_centre(8, 4), [-1, -1, 1, 1, -1, -1, 1, 1])
    np.testing.assert_array_equal(side_of_centre(6, 3), [-1, 0, 1, -1, 0, 1])
    anchor = np.full((7, 9), WALL, np.float32)
    anchor[:, :4] = 1000.0  # a wide foreground: columns 0..3
    tol = np.full_like(anchor, 10.0)
    near, near_tol, far, far_tol = surface_alternatives(anchor, tol, 100.0)
    assert near.shape == (3, 3, 7, 9)
    # the foreground's edge column 3: the wall competes only on its right side (sx = +1)
    assert (far[:, 2, :, 3] == WALL).all() and (far[:, :2, :, 3] == 0).all()
    assert (far_tol[:, 2, :, 3] == 10.0).all()
    assert (near[:, 0, :, 4] == 1000.0).all() and (near[:, 1:, :, 4] == 0).all()
    assert (near[1, 1] == 0).all() and (far[1, 1] == 0).all()  # never at the centre
    grid_near, _, grid_far, _ = alternatives_on_grid((near, near_tol, far, far_tol), 4)
    assert grid_far.shape == (28, 36)
    np.testing.assert_array_equal(grid_far[:, 12:16] == WALL, np.tile([0, 0, 1, 1], (28, 1)) == 1)
    np.testing.assert_array_equal(
        grid_near[:, 16:20] == 1000.0, np.tile([1, 1, 0, 0], (28, 1)) == 1
    )


def test_a_removed_mix_has_the_surfaces_around_it_continued_towards_it():
    """A removed mixed pixel (anchor 0) between a slanted wall above and a box below: on
    every side of its centre the box (nearest) and the wall continued one pixel down its
    slope (farthest), with their tolerances; with the box rows removed too, the wall alone
    is known and the near side is any depth up to the mix's own."""
    from upsr.method.alternatives import OPEN_MM, mix_tolerance

    anchor = np.zeros((5, 5), np.float32)
    anchor[0], anchor[1] = 3200.0, 3100.0  # a wall receding 100 mm per row towards row 2
    anchor[3:] = 1500.0
    tol = np.where(anchor > 0, np.float32(20.0), np.float32(0.0))
    mixes = np.zeros_like(anchor)
    mixes[2] = 2200.0  # the removed row of mixes
    near, near_tol, far, far_tol = surface_alternatives(anchor, tol, 150.0, mixes)
    assert (near[:, :, 2, 2] == 1500.0).all() and (near_tol[:, :, 2, 2] == 20.0).all()
    # the wall at row 1 (3100) continued to row 2 (3000): the interval between, plus τ
    assert (far[:, :, 2, 2] == 3050.0).all() and (far_tol[:, :, 2, 2] == 70.0).all()
    without = surface_alternatives(anchor, tol, 150.0)
    assert all((a[:, :, 2, 2] == 0).all() for a in without)  # no rule without the mixes
    np.testing.assert_array_equal(mix_tolerance(anchor, tol, mixes)[2], 20.0)
    assert not mix_tolerance(anchor, tol, mixes)[[0, 1, 3, 4]].any()
    anchor[3:] = 0.0  # the box not anchored: the wall alone is known, farther than the mix
    near, near_tol, far, _ = surface_alternatives(anchor, tol, 150.0, mixes)
    assert (far[:, :, 2, 2] == 3050.0).all()
    lo, hi = near[0, 0, 2, 2] - near_tol[0, 0, 2, 2], near[0, 0, 2, 2] + near_tol[0, 0, 2, 2]
    assert hi == 2200.0 and lo < -OPEN_MM  # any depth nearer than the mix


def test_a_misregistered_sample_of_a_third_surface_never_fills_a_removed_mix():
    """The ToF room: a mixed pixel between a wall and a box top, removed from the
    reference, took the depth of another box 800 mm away whose samples the flow carried
    there (flying pixels). Only samples of the surfaces around it, or near its own depth,
    are taken; without ``mixes_mm`` the stray depth wins."""
    from upsr.method.anchor import reference_anchor
    from upsr.method.fusion import register_and_fuse
    from upsr.method.mixed import ABSTAIN

    r, box = 2, 1500.0
    n, h, w, ref = 7, 6, 10, 3
    frames = np.full((n, h, w), WALL, np.float32)
    frames[:, :, :5] = box
    frames[ref, :, 5] = ABSTAIN  # the reference's column of mixes, removed
    for k, v in ((0, 2400.0), (1, 2400.0), (2, 2400.0), (4, 2400.0), (5, WALL), (6, box)):
        frames[k, :, 5] = v  # four misregistered samples of a third surface, two true ones
    anchor, tol = reference_anchor(np.maximum(frames[ref], 0), 3.0, 3.0, 100.0)
    mixes = np.zeros((h, w), np.float32)
    mixes[:, 5] = 2200.0
    maps = np.zeros((n, h * r, w * r, 2), np.float32)
    kw = {"anchor": anchor, "tolerance": tol, "edge_mm": 100.0, "min_trusted": 3}
    out = register_and_fuse(frames, maps, r, ref, mixes_mm=mixes, **kw)[:, 5 * r : 6 * r]
    assert np.isin(out, [box, WALL]).all()
    before = register_and_fuse(frames, maps, r, ref, **kw)[:, 5 * r : 6 * r]
    assert (before == 2400.0).all()


def _bar_in_front(width_px: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """A bar ``width_px`` columns wide at 1200 mm in front of the wall, tolerances 30 mm."""
    anchor = np.full((9, 11), WALL, np.float32)
    anchor[:, 4 : 4 + width_px] = 1200.0
    return anchor, np.full_like(anchor, 30.0)


def test_thin_fronts_are_thin_parts_standing_apart_from_a_surface_beside_them():
    from upsr.method.alternatives import thin_fronts

    anchor, tol = _bar_in_front(2)
    np.testing.assert_array_equal(thin_fronts(anchor, tol, 100.0), anchor < WALL)
    # three columns wide: not thin
    assert not thin_fronts(*_bar_in_front(3), 100.0).any()
    # a floor at a grazing angle (rows 150 mm apart, between a nearer and a farther row): no
    floor = np.repeat(np.arange(9, dtype=np.float32)[:, None] * 150.0 + 2000.0, 11, axis=1)
    assert not thin_fronts(floor, np.full_like(floor, 30.0), 100.0).any()
    # two noise outliers side by side, within the two tolerances of the surface: no
    specks = np.full((9, 11), WALL, np.float32)
    specks[4, 4:6] = WALL - 150.0
    assert not thin_fronts(specks, np.full_like(specks, 90.0), 100.0).any()
    assert thin_fronts(specks, np.full_like(specks, 30.0), 100.0)[4, 4:6].all()


def test_a_thin_part_the_motion_followed_has_the_surface_behind_it_compete():
    """The bar keeps its own samples against the wall (no alternative at its pixels) unless
    the motion followed it; then the wall competes on the side of each column's centre
    that faces it, as at any edge."""
    anchor, tol = _bar_in_front(2)
    _, _, far, _ = surface_alternatives(anchor, tol, 100.0)
    assert (far[:, :, :, 4:6] == 0).all()
    followed = np.zeros(anchor.shape, bool)
    followed[:, 4:6] = True
    _, _, far, far_tol = surface_alternatives(anchor, tol, 100.0, followed=followed)
    assert (far[:, 0, :, 4] == WALL).all() and (far[:, 2, :, 4] == 0).all()  # left column
    assert (far[:, 2, :, 5] == WALL).all() and (far[:, 0, :, 5] == 0).all()  # right column
    assert (far_tol[:, 0, :, 4] == 30.0).all()


def test_a_strip_along_the_image_border_is_a_thin_part_in_front():
    """With ``border_strips`` (point-sampling sensors), a surface one pixel wide along the
    image's border in front of the wall (the top of a box entering the view from below, or
    leaving it) is a thin part: what lies beyond the border is not known to be the same
    surface. It keeps its own samples against the wall beside it unless the motion followed
    it. Without it (a sensor that mixes) the border counts as the surface going on."""
    from upsr.method.alternatives import thin_fronts

    anchor = np.full((7, 9), WALL, np.float32)
    anchor[-1] = 1500.0  # the bottom row
    tol = np.full_like(anchor, 30.0)
    strips = {"border_strips": True}
    np.testing.assert_array_equal(thin_fronts(anchor, tol, 100.0, **strips), anchor < WALL)
    assert not thin_fronts(anchor, tol, 100.0).any()
    _, _, far, _ = surface_alternatives(anchor, tol, 100.0, **strips)
    assert (far[:, :, -1] == 0).all()
    _, _, far, _ = surface_alternatives(anchor, tol, 100.0)
    assert (far[0, :, -1] == WALL).all()  # the wall competes on the row's upper side
    anchor[-3:] = 1500.0  # three rows: wide enough to be a surface of its own
    assert not thin_fronts(anchor, tol, 100.0, **strips).any()
    _, _, far, _ = surface_alternatives(anchor, tol, 100.0, **strips)
    assert (far[0, :, -3] == WALL).all()
    # a floor at a grazing angle: its border rows are no strips (no surface 2 px deep beside)
    floor = np.repeat(np.arange(9, dtype=np.float32)[:, None] * 150.0 + 2000.0, 11, axis=1)
    assert not thin_fronts(floor, np.full_like(floor, 30.0), 100.0, **strips).any()


def test_a_strip_that_leaves_the_view_keeps_its_block_in_the_frame_that_sees_it():
    """Kinect room of seed 1 (``benchmarks/edge_losses.py --scene room --sensor kinect
    --seed 1``): a box top one pixel wide along the bottom border, seen in the first frames
    of the window and then out of view. The frames that no longer see it registered the
    wall's samples of the border row onto it, which outvoted the reference on the upper
    half of its block. Static here (no motion to follow): the strip keeps its whole block."""
    import upsr

    n, h, w, r = 9, 12, 16, 2
    rng = np.random.default_rng(0)
    frames = (WALL + rng.normal(0.0, 3.0, (n, h, w))).astype(np.float32)
    frames[:4, -1] = 1500.0 + rng.normal(0.0, 3.0, (4, w))  # seen in frames 0-3 only
    out = upsr.super_resolve(frames, r, n, remove_mixed=False)  # a point-sampling sensor
    strip = out[3, -r:]
    assert np.abs(strip - 1500.0).max() < 20.0
