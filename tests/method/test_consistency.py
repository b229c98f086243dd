"""The registration check (upsr.method.consistency): frames the motion did not follow."""

import numpy as np
import pytest

import upsr
from upsr.method.consistency import misregistered, registered_samples
from upsr.method.fusion import register_and_fuse
from upsr.research.oracle import misregistered_numpy, registered_samples_numpy

WALL, BODY = 3000.0, 1800.0


def _square_video(n=5, h=16, w=20, step=5, noise=0.0, seed=0):
    """A 6×6 px square jumping ``step`` px per frame in front of a wall; the middle frame is
    the reference."""
    rng = np.random.default_rng(seed)
    ref = (n - 1) // 2
    frames = np.full((n, h, w), WALL, np.float32)
    for k in range(n):
        c = 7 + step * (k - ref)
        frames[k, 5:11, max(c, 0) : max(c + 6, 0)] = BODY
    if noise:
        frames += rng.laplace(0, noise / np.sqrt(2), frames.shape).astype(np.float32)
    return frames, ref


@pytest.mark.parametrize(("s", "r"), [(2, 2), (1, 4), (2, 4), (3, 3)])
def test_registered_samples_equal_the_numpy_reference(s, r):
    rng = np.random.default_rng(s * 10 + r)
    n, h, w = 4, 7, 9
    low = rng.uniform(500, 4000, (n, h, w)).astype(np.float32)
    low[rng.random(low.shape) < 0.1] = 0
    maps = rng.normal(0, 3, (n, s * h, s * w, 2)).astype(np.float32)  # some leave the frame
    fast = registered_samples(low, maps, r)
    slow = registered_samples_numpy(low, maps, r)
    np.testing.assert_array_equal(np.isnan(fast), np.isnan(slow))
    assert np.isnan(fast).any() and not np.isnan(fast).all()
    np.testing.assert_array_equal(np.nan_to_num(fast, nan=-7), np.nan_to_num(slow, nan=-7))


def test_zero_motion_samples_each_frame_at_the_reference_pixel():
    frames, _ = _square_video()
    maps = np.zeros((5, 32, 40, 2), np.float32)
    np.testing.assert_array_equal(registered_samples(frames, maps, 2), frames)
    with pytest.raises(ValueError, match="maps"):
        registered_samples(frames, maps[:3], 2)


@pytest.mark.parametrize("seed", range(3))
def test_misregistered_equals_the_numpy_reference(seed):
    frames, ref = _square_video(noise=30.0, seed=seed)
    rng = np.random.default_rng(seed)
    frames[rng.random(frames.shape) < 0.05] = 0
    reg = registered_samples(frames, rng.normal(0, 1.5, (5, 16, 20, 2)).astype(np.float32), 1)
    offsets = rng.normal(0, 20, frames.shape).astype(np.float32)
    for offs in (None, offsets):
        fast = misregistered(reg, frames[ref], ref, edge_mm=120.0, offsets=offs)
        slow = misregistered_numpy(reg, frames[ref], ref, edge_mm=120.0, offsets=offs)
        np.testing.assert_array_equal(fast, slow)
        assert fast.any() and not fast[ref].any()


def test_a_frame_the_motion_did_not_follow_is_flagged_where_it_disagrees():
    frames, ref = _square_video()
    reg = registered_samples(frames, np.zeros((5, 16, 20, 2), np.float32), 1)  # flow: none
    bad = misregistered(reg, frames[ref], ref, edge_mm=100.0)
    assert not bad[ref].any()
    # frame ref+1 has the square 5 px to the right: flagged around the square's two
    # positions, not on the wall far from it
    assert bad[ref + 1, 5:11, 7:13].all()
    assert not bad[ref + 1, :, :3].any() and not bad[ref + 1, 14:, :].any()
    assert bad[ref - 1, 5:11, 2:8].all()  # the square 5 px to the left


def test_noise_dropouts_and_a_frame_without_depth_are_no_evidence():
    rng = np.random.default_rng(1)
    frames = np.full((5, 24, 30), WALL, np.float32)
    frames += rng.laplace(0, 30 / np.sqrt(2), frames.shape).astype(np.float32)
    frames[rng.random(frames.shape) < 0.05] = 0  # dropouts
    frames[1] = 0  # a frame without any depth
    reg = registered_samples(frames, np.zeros((5, 24, 30, 2), np.float32), 1)
    bad = misregistered(reg, frames[2], 2, edge_mm=120.0)  # the edge threshold 4σ
    assert bad.mean() < 0.01
    empty_ref = misregistered(reg, frames[1], 1, edge_mm=120.0)
    assert not empty_ref.any()


def test_a_misregistered_sample_cannot_vote():
    frames, ref = _square_video()
    maps = np.zeros((5, 32, 40, 2), np.float32)
    untrusted = np.ones(frames.shape, bool)
    untrusted[ref] = False
    # every frame but the reference flagged: the output is the reference's own depth
    out = register_and_fuse(frames, maps, 2, ref, edge_mm=100.0, untrusted=untrusted)
    np.testing.assert_array_equal(out, np.repeat(np.repeat(frames[ref], 2, 0), 2, 1))
    # unflagged, the other frames' wall samples outvote the square at its reference position
    voted = register_and_fuse(frames, maps, 2, ref, edge_mm=100.0)
    assert np.mean(voted[10:22, 14:26] == BODY) < 0.5


def test_a_fast_deforming_body_is_no_worse_than_its_input():
    """The head of the deforming body moves ≈ 25 px per frame: the flow does not follow it and
    its frames' samples landed on the wall (rmse 190 mm against nearest's 122 before)."""
    from upsr.research import baselines
    from upsr.research.metrics import evaluate, near_discontinuity
    from upsr.research.synth.realistic import make_realistic

    video = make_realistic("deforming", (40, 48), n_frames=7)
    low, r = video.lowres, video.scale

    def moving_surface_rmse(est):
        surf = (est > 0) & (video.truth > 0) & ~near_discontinuity(video.truth, r) & video.moving
        return float(np.sqrt(np.mean((est - video.truth)[surf] ** 2)))

    near = baselines.nearest(low, r)
    out = upsr.super_resolve(low, r, 7, progress=False)
    unchecked = upsr.super_resolve(low, r, 7, check_registration=False, progress=False)
    m_out, m_near = evaluate(out, video.truth, r), evaluate(near, video.truth, r)
    assert moving_surface_rmse(out) <= moving_surface_rmse(near)
    assert m_out["rmse"] <= m_near["rmse"]
    assert m_out["edge_accuracy"] >= m_near["edge_accuracy"]
    assert m_out["missing"] <= m_near["missing"] + 0.005
    assert m_out["flying_pixels"] < 0.005
    # without the check, the misregistered frames' wall samples win at the head's edges
    assert evaluate(unchecked, video.truth, r)["rmse"] > 1.05 * m_near["rmse"]


def test_hole_backgrounds_are_the_farthest_measured_neighbour_of_each_hole():
    from upsr.method.consistency import hole_backgrounds

    z = np.full((5, 6), WALL, np.float32)
    z[:, :2] = BODY
    z[2, 2] = 0.0  # a shadow pixel beside the body: body and wall around it
    z[0, 0] = np.nan  # a hole with only the body around it
    z[4, 5] = -1.0  # a removed pixel (negative marker): not a hole, and not a depth
    bg = hole_backgrounds(z)
    assert bg[2, 2] == WALL and bg[0, 0] == BODY
    assert bg[4, 5] == 0.0 and np.count_nonzero(bg) == 2
    assert not hole_backgrounds(np.zeros((3, 3), np.float32)).any()


def test_the_middle_of_a_wide_shadow_takes_the_farthest_depth_of_its_rim():
    """A projector shadow several pixels wide: the wall on its far side lies within reach
    through the hole, for every pixel of it (before: the 8 neighbours only, so its middle had
    no limit and the pixels beside the body took the body: the Kinect animal's and body's
    rmse above nearest's)."""
    from upsr.method.consistency import hole_backgrounds

    z = np.full((5, 12), WALL, np.float32)
    z[:, :3] = BODY
    z[:, 3:9] = 0.0  # a shadow 6 px wide between the body and the wall
    bg = hole_backgrounds(z)
    assert (bg[:, 3:9] == WALL).all() and not bg[:, :3].any() and not bg[:, 9:].any()
    near = hole_backgrounds(z, reach_px=1)  # only the 8 neighbours: the middle unlimited
    assert (near[:, 3] == BODY).all() and (near[:, 8] == WALL).all() and not near[:, 4:8].any()
    z[:, 9:] = 0.0  # nothing measured beyond: the body is all there is around the hole
    far = hole_backgrounds(z)
    assert (far[:, 3:11] == BODY).all() and not far[:, 11].any()  # 8 px from the body at most


def test_a_sample_nearer_than_a_hole_of_the_reference_allows_abstains():
    ref = np.full((4, 6), WALL, np.float32)
    ref[:, :2] = BODY
    ref[:, 2] = 0.0  # the projector's shadow of the body in the reference (frame 2)
    frames = np.stack([ref] * 5)
    frames[[0, 1], :, 2] = BODY  # frames that show the body there (misregistered)
    frames[[3, 4], :, 2] = WALL + 30.0  # frames that show the wall there
    maps = np.zeros((5, 8, 12, 2), np.float32)
    kw = dict(edge_mm=100.0, measured_only=True)

    def fuse(video, **more):
        return register_and_fuse(video, maps, 2, 2, **kw, **more)

    plain, fused = fuse(frames), fuse(frames, hole_floors=True)
    np.testing.assert_array_equal(fused[:, 4:6], WALL + 30.0)
    np.testing.assert_array_equal(fused[:, 6:], plain[:, 6:])
    np.testing.assert_array_equal(fused[:, :4], plain[:, :4])
    frames[3, :, 2] = BODY  # three frames show the body, none the wall
    frames[4, :, 2] = 0.0
    assert (fuse(frames)[:, 4:6] == BODY).all()
    assert not fuse(frames, hole_floors=True)[:, 4:6].any()


@pytest.mark.parametrize("mode", ["windowed", "recursive"])
def test_the_projector_shadow_of_a_moving_body_never_takes_the_body(mode):
    """Kinect-like frames of a deforming body in front of a wall: where the reference has a
    hole beside an edge (its projector shadow), the output is the background side or 0, never
    a surface nearer than everything the reference measured around the hole."""
    from upsr.method.consistency import hole_backgrounds
    from upsr.research.synth.realistic import degrade, make_realistic

    video = make_realistic("deforming", (120, 160), scale=2, n_frames=9, seed=2)
    low = degrade(video, "kinect", np.random.default_rng(5), sigma_mm=0.0)
    out = upsr.super_resolve(low, 2, 9, mode=mode)
    for t in range(low.shape[0]):
        bg = np.repeat(np.repeat(hole_backgrounds(low[t]), 2, axis=0), 2, axis=1)
        holes = bg > 0
        assert holes.sum() > 20  # there are shadows to fill
        # (the rule holds for the fused samples, edge_mm = 100; the deblurring that follows
        # moves a pixel by a few mm)
        wrong = holes & (out[t] > 0) & (out[t] < bg - 120.0)
        assert not wrong.any(), (t, int(wrong.sum()))


def test_stale_fills_beside_a_nearer_surface_are_emptied_on_its_side_only():
    """A hole of the reference along a body's edge, filled with the wall other frames saw
    there before the body moved in: the half of the hole's block towards the body is emptied
    (it may be body), the far half keeps the wall; a fill showing the body stays, removed
    pixels (negative markers) are not holes, and nothing is filled that was not."""
    from upsr.method.consistency import clear_stale_fills

    r = 2
    ref = np.full((4, 6), WALL, np.float32)
    ref[:, :2] = BODY
    ref[:, 2] = 0.0  # the hole beside the body
    fused = np.full((4 * r, 6 * r), WALL, np.float32)
    fused[:, : 2 * r] = BODY
    out = clear_stale_fills(fused, ref, r, 100.0)
    assert (out[:, 2 * r] == 0).all()  # the body's side of the hole's block
    assert (out[:, 2 * r + 1] == WALL).all()  # its far side: the shadow's background
    np.testing.assert_array_equal(out[:, : 2 * r], fused[:, : 2 * r])
    np.testing.assert_array_equal(out[:, 3 * r :], fused[:, 3 * r :])
    fused[:, 2 * r : 3 * r] = BODY + 20.0  # other frames showed the body there
    np.testing.assert_array_equal(clear_stale_fills(fused, ref, r, 100.0), fused)
    ref[:, 2] = -1.0  # a removed (mixed) pixel: not a hole, left to the split
    fused[:, 2 * r : 3 * r] = WALL
    np.testing.assert_array_equal(clear_stale_fills(fused, ref, r, 100.0), fused)
    odd = clear_stale_fills(
        np.full((12, 18), WALL, np.float32), np.where(ref == -1, 0, ref), 3, 100.0
    )
    assert (odd[:, 6] == 0).all() and (odd[:, 7:9] == WALL).all()  # r = 3: the centre column


def _bar_frames(shifts_px, r=4, h=12, w=16, x0=25.0, width_px=6.0):
    """Point samples (r·h × r·w output grid, pixel centres) of a bar ``width_px`` output px
    wide at 1200 mm in front of the wall, its left side at x0 + shift in each frame; and the
    truth of each frame on the output grid."""
    xs = np.arange(w * r, dtype=np.float64)
    centres = (np.arange(w) + 0.5) * r - 0.5
    low, truth = [], []
    for s in shifts_px:
        low.append(np.where((centres >= x0 + s) & (centres < x0 + s + width_px), 1200.0, WALL))
        truth.append(np.where((xs >= x0 + s - 0.5) & (xs < x0 + s + width_px - 0.5), 1200.0, WALL))
    low = np.repeat(np.asarray(low, np.float32)[:, None, :], h, axis=1)
    truth = np.repeat(np.asarray(truth, np.float32)[:, None, :], h * r, axis=1)
    return low, truth


def test_thin_parts_followed_counts_the_frames_whose_sample_stays_on_the_part():
    from upsr.method.consistency import thin_parts_followed

    reg = np.full((5, 3, 6), WALL, np.float32)
    reg[:, :, 2:4] = 1200.0  # a bar two pixels wide that every frame followed ...
    reg[4, :, 2:4] = WALL  # ... but frame 4
    reg[0, 0] = np.nan  # frame 0 outside the frame on row 0 (no evidence either way)
    anchor = reg[2].copy()
    tol = np.full_like(anchor, 30.0)
    fronts = anchor < WALL
    followed, lost = thin_parts_followed(reg, anchor, tol, fronts, 2, edge_mm=100.0, min_trusted=3)
    np.testing.assert_array_equal(followed, fronts)
    np.testing.assert_array_equal(lost[4], fronts)
    assert not lost[[0, 1, 2, 3]].any()
    # followed by one of the other four frames only: not followed, nothing abstains
    reg[[0, 1], :, 2:4] = WALL
    followed, lost = thin_parts_followed(reg, anchor, tol, fronts, 2, edge_mm=100.0, min_trusted=3)
    assert not followed.any() and not lost.any()
    # the radial offsets are subtracted first: a frame 500 mm nearer follows after them
    reg[[0, 1, 4], :, 2:4] = 700.0
    offsets = np.where(reg == 700.0, -500.0, 0.0).astype(np.float32)
    followed, _ = thin_parts_followed(reg, anchor, tol, fronts, 2, edge_mm=100.0, offsets=offsets)
    np.testing.assert_array_equal(followed, fronts)


def test_a_thin_bar_the_motion_followed_keeps_its_width():
    """A bar 6 output px wide moving 1 output px per frame, registered exactly: kept to its
    own samples it fills the r×r blocks of its two reference pixels (8 px wide); with the
    frames that followed it voting with the wall behind it, its edges land within a pixel.
    A frame whose motion is wrong at the bar does not follow it and abstains there."""
    from upsr.method.alternatives import thin_fronts
    from upsr.method.consistency import thin_parts_followed

    r, n, ref = 4, 7, 3
    low, truth = _bar_frames(range(-3, 4))
    maps = np.zeros((n, low.shape[1] * r, low.shape[2] * r, 2), np.float32)
    maps[..., 0] = np.arange(-3, 4, dtype=np.float32)[:, None, None]  # exact motion
    anchor, tol = low[ref], np.full(low.shape[1:], 30.0, np.float32)
    common = dict(edge_mm=100.0, anchor=anchor, tolerance=tol, edge_votes=True)
    common.update(weight_sigma_px=0.35 * r, min_trusted=3)
    kept = register_and_fuse(low, maps, r, ref, **common)
    reg = registered_samples(low, maps, r)
    followed, lost = thin_parts_followed(
        reg, anchor, tol, thin_fronts(anchor, tol, 100.0), ref, edge_mm=100.0
    )
    assert followed[:, 6:8].all()  # (frames whose nearest sample missed the bar abstain)
    fused = register_and_fuse(low, maps, r, ref, untrusted=lost, followed=followed, **common)
    wrong = lambda out: int((np.abs(out - truth[ref]) > 100).sum(axis=1).max())  # noqa: E731
    assert wrong(kept) >= 2 and wrong(fused) <= 1
    assert ((fused == 1200.0).sum(axis=1) >= 5).all()  # the bar kept along its whole length
    assert np.isin(fused, [1200.0, WALL]).all()  # no depth between the two
    # frame 6 registered as if nothing moved: it does not follow the bar, and abstains there
    maps[6] = 0.0
    reg = registered_samples(low, maps, r)
    followed, lost = thin_parts_followed(
        reg, anchor, tol, thin_fronts(anchor, tol, 100.0), ref, edge_mm=100.0
    )
    assert lost[6][:, 6].all() and not lost[6][:, 7].any()  # (column 7 lands on the bar)


def test_a_frame_that_reaches_a_thin_part_at_one_pixel_only_did_not_follow_it():
    """A rotating blade: a frame whose registered samples lie on the part at one pixel but
    not at its neighbours along the part did not follow it there; the neighbours across a
    part two pixels wide do not count (a sub-pixel shift takes an edge column's nearest
    sample off the part)."""
    from upsr.method.consistency import thin_parts_followed

    reg = np.full((5, 5, 6), WALL, np.float32)
    reg[:, :, 2:4] = 1200.0  # a vertical bar two columns wide, followed by frames 0, 1, 3
    reg[4, :, 2:4] = WALL
    reg[4, 2, 2:4] = 1200.0  # frame 4 reaches it on row 2 only
    reg[1, :, 3] = WALL  # frame 1's nearest samples of the right column fell off the bar
    anchor, tol = reg[2].copy(), np.full((5, 6), 30.0, np.float32)
    followed, lost = thin_parts_followed(reg, anchor, tol, anchor < WALL, 2, edge_mm=100.0)
    assert followed[:, 2:4].all()
    assert lost[4, 2, 2:4].all()  # row 2: its neighbours above and below were not reached
    assert not lost[1, :, 2].any()  # the left column: frame 1 followed it


def test_map_spread_is_how_far_a_blocks_motion_strays_from_its_centres():
    from upsr.method.consistency import map_spread

    h, w, s = 4, 5, 3
    maps = np.zeros((2, h * s, w * s, 2), np.float32)
    maps[0] = (2.5, -7.0)  # a translation: every node of a block moves as its centre
    maps[1, ..., 0] = np.arange(w * s, dtype=np.float32)  # stretched: 1 flow px per node
    spread = map_spread(maps, (h, w))
    assert spread.shape == (2, h, w) and spread.dtype == np.float32
    np.testing.assert_array_equal(spread[0], 0.0)
    # the centre node of a block of 3 is its middle one: one node either side, 1/3 low-res px
    np.testing.assert_allclose(spread[1], 1.0 / s, rtol=1e-6)
    np.testing.assert_array_equal(map_spread(maps[:, ::s, ::s], (h, w)), 0.0)  # s = 1


def test_a_frame_whose_motion_stretches_across_a_thin_part_did_not_follow_it():
    """The bar of the test above, registered exactly by frames 0–5; frame 6's motion reaches
    the bar's centres as exactly but stretches across its blocks (a rotating blade: DIS
    blends the part's motion with the wall's at its sides), so its samples of the blocks'
    sides land elsewhere: it did not follow the bar there, and abstains (the outside
    propeller at r = 2 lost 0.7 points of edge accuracy against nearest's to such frames)."""
    from upsr.method.alternatives import thin_fronts
    from upsr.method.consistency import FOLLOWED_MAX_SPREAD_PX, thin_parts_followed

    r, n, ref = 4, 7, 3
    low, _truth = _bar_frames(range(-3, 4))
    maps = np.zeros((n, low.shape[1] * r, low.shape[2] * r, 2), np.float32)
    maps[..., 0] = np.arange(-3, 4, dtype=np.float32)[:, None, None]
    anchor, tol = low[ref], np.full(low.shape[1:], 30.0, np.float32)
    fronts = thin_fronts(anchor, tol, 100.0)
    reg = registered_samples(low, maps, r)

    def followed_by(maps):
        return thin_parts_followed(reg, anchor, tol, fronts, ref, edge_mm=100.0, maps=maps)

    followed, before = followed_by(maps)
    assert followed[:, 6:8].all() and not before[6].any()
    # across the bar's blocks the columns move apart: node q of a block (its centre node
    # r // 2 as before) by (q − r // 2) steps, FOLLOWED_MAX_SPREAD_PX + 0.2 low-res px at most
    step = (FOLLOWED_MAX_SPREAD_PX + 0.2) * r / (r // 2)
    stretch = np.tile((np.arange(r) - r // 2) * np.float32(step), 2)
    maps[6, :, 6 * r : 8 * r, 0] += stretch
    np.testing.assert_array_equal(registered_samples(low, maps, r), reg)
    followed, lost = followed_by(maps)
    assert followed[:, 6:8].all()  # five of the six others still follow it
    assert lost[6][:, 6:8].all()
    np.testing.assert_array_equal(lost[:6], before[:6])  # (the others as before)
    # a stretch within the limit is a turn the block shares: followed as before
    maps[6, :, 6 * r : 8 * r, 0] -= stretch * np.float32(0.3 / (FOLLOWED_MAX_SPREAD_PX + 0.2))
    _, lost = followed_by(maps)
    assert not lost[6].any()


def test_enclosed_holes_are_holes_inside_measured_surroundings():
    from upsr.method.consistency import enclosed_holes

    frame = np.full((20, 30), 2000.0, np.float32)
    frame[5, 5] = 0.0  # a dropout
    frame[2:18, 12:14] = np.nan  # a projector shadow two pixels wide
    frame[:, 22:] = 0.0  # nothing returns on the right
    frame[0, 0] = 0.0  # a dropout in a corner: the window is what lies inside the image
    got = enclosed_holes(frame)
    assert got[5, 5] and got[0, 0] and got[2:18, 12:14].all()
    assert not got[:, 22:].any()  # an open region (its first column: 4 of 9 columns measured)
    assert not got[frame > 0].any()
    np.testing.assert_array_equal(enclosed_holes(frame, share=1.0), np.zeros_like(got))


@pytest.mark.parametrize("reach", [1, 3, 8, 40])
def test_hole_backgrounds_are_a_grey_dilation_masked_to_the_holes(reach):
    """The compiled front-following kernel equals ``reach`` steps of a 3×3 grey dilation of
    the measured depths masked to the holes (its definition, as it was computed before)."""
    import cv2

    from upsr.method.consistency import hole_backgrounds

    rng = np.random.default_rng(reach)
    z = rng.uniform(500, 4000, (40, 50)).astype(np.float32)
    z[rng.random(z.shape) < 0.35] = 0.0
    z[10:30, 5:40] = 0.0  # a wide hole
    z[2:4, 2:4] = -1.0  # removed pixels: neither hole nor depth
    measured = np.maximum(z, 0.0)
    far = np.zeros_like(z)
    for _ in range(reach):
        grown = cv2.dilate(np.maximum(measured, far), np.ones((3, 3), np.uint8),
                           borderType=cv2.BORDER_CONSTANT)  # fmt: skip
        far = np.where(z == 0, grown, np.float32(0.0))
    np.testing.assert_array_equal(hole_backgrounds(z, reach_px=reach), far)
