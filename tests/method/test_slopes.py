"""Slanted surfaces: output blocks follow their surface's slope (upsr.method.slopes)."""

import numpy as np
import pytest

import upsr
from upsr.method.slopes import follow_slopes, plane_slopes, sloped_pixels, surface_slopes


def _blocks(low: np.ndarray, r: int) -> np.ndarray:
    return np.repeat(np.repeat(low, r, axis=-2), r, axis=-1)


def _plane(h: int, w: int, r: int, gx: float, gy: float, z0: float = 2000.0):
    """A plane sampled at the low-res pixel centres, and its high-res truth (mm)."""
    yh, xh = np.mgrid[0 : h * r, 0 : w * r].astype(np.float64)
    truth = z0 + gx * (xh + 0.5) / r + gy * (yh + 0.5) / r
    yl, xl = np.mgrid[0:h, 0:w].astype(np.float64)
    low = z0 + gx * (xl + 0.5) + gy * (yl + 0.5)
    return low.astype(np.float32), truth.astype(np.float32)


@pytest.mark.parametrize("r", [2, 3, 4])
def test_a_staircase_on_a_plane_becomes_the_plane(r):
    low, truth = _plane(8, 10, r, gx=40.0, gy=-25.0)
    out = follow_slopes(_blocks(low, r), low, sigma_mm=0.0, edge_mm=100.0)
    np.testing.assert_allclose(out, truth, atol=1e-2)


def test_a_floor_steeper_than_the_edge_threshold_is_followed_evenly():
    """A floor at a grazing angle steps by 150-300 mm per low-res px (beyond edge_mm): a run of
    agreeing steps is one surface."""
    rows = 2000.0 + 150.0 * np.arange(10) + 8.0 * np.arange(10) ** 2  # steps 158..294 mm
    low = np.repeat(rows[:, None], 6, axis=1).astype(np.float32)
    sy, sx = surface_slopes(low, 100.0)
    assert (sx == 0).all()
    assert (sy[1:-1, 0] > 150).all() and (sy[0] > 0).all() and (sy[-1] > 0).all()
    out = follow_slopes(_blocks(low, 4), low, sigma_mm=5.0, edge_mm=100.0)
    col = out[:, 0]
    assert (np.diff(col) > 0).all()  # a ramp, not a staircase
    assert np.abs(out.reshape(10, 4, 6, 4).mean(axis=(1, 3)) - low).max() < 1e-2  # means kept


def test_never_across_a_depth_edge():
    """Two surfaces, and a staircase of two edges (which agree, but are only two steps): no
    slope links them, and no output pixel takes a depth between them."""
    low = np.full((6, 9), 3000.0, np.float32)
    low[:, :3] = 1000.0
    low[:, 3:5] = 2000.0  # 1000 -> 2000 -> 3000: two edges of 1 m
    sy, sx = surface_slopes(low, 100.0)
    assert (sx == 0).all() and (sy == 0).all()
    up = _blocks(low, 4)
    np.testing.assert_array_equal(follow_slopes(up, low, sigma_mm=0.0, edge_mm=100.0), up)
    # a slanted surface ending at an edge: its last block follows its own side only
    ramp = np.tile(1000.0 + 30.0 * np.arange(9, dtype=np.float32), (6, 1))
    ramp[:, 6:] = 4000.0
    out = follow_slopes(_blocks(ramp, 4), ramp, sigma_mm=0.0, edge_mm=100.0)
    near = out[:, : 6 * 4]
    assert near.min() >= 1000.0 - 15.0 - 1e-3 and near.max() <= 1150.0 + 15.0 + 1e-3
    assert (out[:, 6 * 4 :] == 4000.0).all()


def test_a_face_seen_obliquely_is_one_surface():
    """A box's side seen obliquely, two low-res px wide between two flat surfaces (the
    profile of the realistic camera-toward-wall scene): its steps 57, 125, 95 mm do not agree
    within STEEP_RATIO, yet the middle one joins the face (both steps beside it go the same
    way within FACE_RATIO), so both face pixels take the central slope and the output ramps
    across them instead of jumping by 125 mm."""
    row = np.array([2123.0, 2123.0, 2123.0, 2180.0, 2305.0, 2400.0, 2400.0, 2400.0], np.float32)
    low = np.tile(row, (5, 1))
    sy, sx = surface_slopes(low, 100.0)
    assert not sy.any()
    np.testing.assert_allclose(sx[:, 3:5], [[91.0, 110.0]] * 5)
    out = follow_slopes(_blocks(low, 4), low, sigma_mm=0.0, edge_mm=100.0)
    assert np.abs(np.diff(out[8, 12:20])).max() < 60.0  # nearest upsampling: a 125 mm jump
    assert np.abs(out.reshape(5, 4, 8, 4).mean(axis=(1, 3)) - low).max() < 1e-2  # means kept


def test_an_occlusion_edge_with_a_flat_side_is_no_face():
    """A ramp (80 mm per px) ending in a 200 mm step to a flat wall: the step agrees with the
    ramp within FACE_RATIO, but the wall's side is flat: an edge, not a face."""
    row = np.array([1000.0, 1080.0, 1160.0, 1240.0, 1440.0, 1440.0, 1440.0], np.float32)
    sy, sx = surface_slopes(np.tile(row, (5, 1)), 100.0)
    assert not sy.any()
    np.testing.assert_allclose(sx, [[80.0, 80.0, 80.0, 80.0, 0.0, 0.0, 0.0]] * 5)


def test_holes_edges_inside_a_block_and_invalid_pixels_are_left_alone():
    low, _ = _plane(6, 6, 4, gx=50.0, gy=0.0)
    up = _blocks(low, 4)
    up[8:12, 8:10] = 0.0  # a hole in block (2, 2)
    up[12:14, 12:16] = 5000.0  # another surface inside block (3, 3)
    low[0, 5] = 0.0
    up[0:4, 20:24] = 0.0  # a pixel without depth
    out = follow_slopes(up, low, sigma_mm=0.0, edge_mm=100.0)
    np.testing.assert_array_equal(out[8:12, 8:12], up[8:12, 8:12])
    np.testing.assert_array_equal(out[12:16, 12:16], up[12:16, 12:16])
    assert (out[0:4, 20:24] == 0).all()
    assert (out[(up == 0)] == 0).all()


def test_an_insignificant_slope_keeps_the_blocks_own_detail():
    """On a flat noisy surface the slope of the anchor is noise (below 2 σ): a block keeps the
    sub-pixel trend the fusion found."""
    low = np.full((6, 6), 2000.0, np.float32)
    low[2, 3] = 2010.0  # noise of the anchor: a slope of 5 mm/px around it
    up = _blocks(low, 4).astype(np.float32)
    up[8:12, 8:12] += np.linspace(-6, 6, 4, dtype=np.float32)  # the fusion's own detail
    out = follow_slopes(up, low, sigma_mm=10.0, edge_mm=100.0)
    np.testing.assert_array_equal(out, up)
    # with no noise the same slope is significant
    assert not np.array_equal(follow_slopes(up, low, sigma_mm=0.0, edge_mm=100.0), up)


def test_at_scale_1_nothing_changes():
    low, _ = _plane(5, 6, 1, gx=60.0, gy=20.0)
    np.testing.assert_array_equal(follow_slopes(low, low, sigma_mm=0.0, edge_mm=100.0), low)


def test_follow_slopes_checks_its_shapes():
    with pytest.raises(ValueError, match="multiple"):
        follow_slopes(np.ones((10, 12), np.float32), np.ones((4, 4), np.float32), sigma_mm=0.0,
                      edge_mm=100.0)  # fmt: skip


@pytest.mark.parametrize("mode", ["windowed", "recursive"])
@pytest.mark.parametrize("deblur", [True, False])
def test_upsr_follows_a_slanted_wall_that_the_frames_cannot_resolve(mode, deblur):
    """A static camera in front of a slanted wall: every frame samples the same points, the
    fusion can only give the staircase; the slopes give the wall (and --no-slopes does not)."""
    r = 4
    low, truth = _plane(14, 16, r, gx=60.0, gy=20.0)
    video = np.repeat(low[None], 5, axis=0)
    kw = dict(mode=mode, noise_mm=1.0, deblur=deblur)
    on = upsr.super_resolve(video, r, 5, **kw)
    off = upsr.super_resolve(video, r, 5, follow_slopes=False, **kw)
    # (the anchor, a 3×3 median, is biased on the frame's border rows and columns)
    inner = (slice(None), slice(2 * r, -2 * r), slice(2 * r, -2 * r))

    def rms(est):
        return float(np.sqrt(np.mean((est[inner] - truth[None][inner]) ** 2)))

    # the staircase of steps of 60 and 20 mm (18 mm rms; the deblurring and the final
    # smoothing along the staircase's own slope round it off to 3.0–4.5 mm)
    assert rms(off) > (2.5 if deblur else 17.0)
    assert rms(on) < (0.3 * rms(off) if deblur else 0.01)
    assert (on > 0).all()


def test_a_face_the_anchor_flattens_follows_the_frames_slope():
    """A box side seen at a grazing angle, two pixels wide (the realistic approaching camera):
    the anchor's 3×3 median pulls the face towards the flat surfaces beside it, so the face
    rule no longer joins its links and its middle block keeps its staircase; the frame's own
    slope, steep beyond half the edge threshold, takes over where the anchor gives none. A
    noisy flat surface stays as it was (its slopes are far below that)."""
    from upsr.method.trust import reference_anchor

    row = np.array([2400, 2400, 2400, 2333, 2170, 2069, 2030, 2030, 2030], np.float32)
    low = np.repeat(row[None], 5, axis=0)
    anchor = reference_anchor(low, 10.0, 3.0, 100.0)[0]
    up = _blocks(low, 4)
    kw = dict(sigma_mm=10.0, edge_mm=100.0)
    plain = follow_slopes(up, anchor, **kw)[8, 16:20]
    np.testing.assert_array_equal(plain, 2170.0)  # the staircase
    face = follow_slopes(up, anchor, frame=low, **kw)[8, 16:20]
    np.testing.assert_allclose(np.diff(face), (2069.0 - 2333.0) / 2 / 4, atol=0.5)
    assert face.mean() == pytest.approx(2170.0, abs=0.01)  # the block's mean kept
    rng = np.random.default_rng(0)
    flat = (2000.0 + rng.normal(0, 10.0, (12, 12))).astype(np.float32)
    anchor = reference_anchor(flat, 10.0, 3.0, 100.0)[0]
    np.testing.assert_array_equal(
        follow_slopes(_blocks(flat, 4), anchor, frame=flat, **kw),
        follow_slopes(_blocks(flat, 4), anchor, **kw),
    )


def test_a_grazing_surface_whose_first_pixel_was_removed_as_mixed_follows_its_slope():
    """A box top seen at a grazing angle behind a ToF pixel the mixed-pixel test removed (its
    footprint is all top, but it steps 600 mm from the wall like a mix: the fan's box). Without
    it the top's run of steep steps is too short to join (the block kept its staircase); read
    on the frame as measured, the run joins and the block follows the top's slope."""
    col = np.array([3133, 3133, 3133, 2531, 2387, 2264, 2177, 2200, 2200], np.float32)
    measured = np.repeat(col[:, None], 5, axis=1)
    cleaned = measured.copy()
    cleaned[3] = 0.0  # removed as mixed
    r = 4
    kw = dict(sigma_mm=0.0, edge_mm=100.0, frame=cleaned)
    before = follow_slopes(_blocks(cleaned, r), cleaned, **kw)[4 * r : 5 * r, 2 * r]
    np.testing.assert_array_equal(before, 2387.0)  # the staircase
    after = follow_slopes(_blocks(cleaned, r), cleaned, measured=measured, **kw)
    block = after[4 * r : 5 * r, 2 * r]
    np.testing.assert_allclose(np.diff(block), (2264.0 - 2531.0) / 2 / r, atol=0.01)
    assert block.mean() == pytest.approx(2387.0, abs=0.01)
    assert (after[3 * r : 4 * r] == 0).all()  # the removed pixel's block is left alone
    with pytest.raises(ValueError, match="shape"):
        follow_slopes(_blocks(cleaned, r), cleaned, measured=measured[:, :4], **kw)


def test_a_staircase_of_removed_mixes_is_no_face():
    """Across a ToF edge the mixed pixels the test removed step like the middle of a face
    (−690, −407, −901 mm): read on the frame as measured, a link into a removed pixel joins
    one surface only within the edge threshold or in a steep run, so the kept pixel between
    them keeps its block (the face rule there gave it a slope of 400 mm per pixel)."""
    col = np.array([4449, 4459, 3769, 3362, 2461, 1967, 1855, 1855], np.float32)
    measured = np.repeat(col[:, None], 5, axis=1)
    cleaned = measured.copy()
    cleaned[[2, 4, 5]] = 0.0  # removed as mixed
    sy, _ = surface_slopes(measured, 100.0)
    assert abs(sy[3, 2]) > 400.0  # every pixel may join a face
    kept = cleaned > 0
    assert surface_slopes(measured, 100.0, kept=kept)[0][3, 2] == 0.0
    up = _blocks(cleaned, 4)
    kw = dict(sigma_mm=0.0, edge_mm=100.0, frame=cleaned)
    out = follow_slopes(up, cleaned, measured=measured, **kw)
    np.testing.assert_array_equal(out[12:16], 3362.0)
    np.testing.assert_array_equal(out, follow_slopes(up, cleaned, **kw))


def test_a_pixel_where_its_surface_bends_steeply_keeps_its_depth_for_the_slopes():
    """Steps of 150 mm per pixel (a surface seen at a grazing angle, beyond the edge threshold)
    bending into steps of 50 mm: the anchor's 3×3 median at the bend drops the steep side and
    leans towards the gentle one (1475 for 1450 mm), so the next block's slope was 37.5 mm per
    pixel instead of 50; over a symmetric neighbourhood it keeps 1450 and the blocks follow the
    truth."""
    from upsr.method.slopes import plane_anchor
    from upsr.method.trust import reference_anchor

    col = 1000.0 + np.array([0, 150, 300, 450, 500, 550, 600, 650], np.float64)
    low = np.repeat(col[:, None], 5, axis=1).astype(np.float32)
    anchor = reference_anchor(low, 1.0, 3.0, 100.0)[0]
    assert anchor[3, 2] == pytest.approx(1475.0)
    plane = plane_anchor(low, anchor, 100.0)
    assert plane[3, 2] == pytest.approx(1450.0)
    r = 4
    truth_rows = 1500.0 + 50.0 * ((np.arange(4 * r, 5 * r) + 0.5) / r - 4.5)  # block of row 4
    kw = dict(sigma_mm=0.0, edge_mm=100.0)
    out = follow_slopes(_blocks(low, r), anchor, frame=low, **kw)
    np.testing.assert_allclose(out[4 * r : 5 * r, 2 * r], truth_rows, atol=0.01)
    old = follow_slopes(_blocks(low, r), anchor, **kw)  # slopes on the anchor alone
    assert np.abs(old[4 * r : 5 * r, 2 * r] - truth_rows).max() > 2.0


def test_the_rims_of_a_surface_keep_their_anchor():
    """Beside a depth edge or a pixel without depth the anchor is left as it is (a curved
    body's silhouette: its one-sided median keeps the slopes of the blocks beside it gentler,
    as the body's blocks are); inside a surface without steep bends the symmetric median is
    the anchor. (Along the image's border, whose surfaces go on beyond it, the next test.)"""
    from upsr.method.slopes import plane_anchor
    from upsr.method.trust import reference_anchor

    low = np.tile(2000.0 + 40.0 * np.arange(10, dtype=np.float32), (9, 1))  # along x
    low[:, 7:] = 4000.0  # a depth edge
    low[:, 2] = 0.0  # a column without depth
    anchor = reference_anchor(low, 1.0, 3.0, 100.0)[0]
    # one-sided beside the edge and the hole
    assert anchor[4, 6] == pytest.approx(low[4, 6] - 20.0)
    assert anchor[4, 3] == pytest.approx(low[4, 3] + 20.0)
    inner = (slice(1, -1), slice(1, -1))
    np.testing.assert_array_equal(plane_anchor(low, anchor, 100.0)[inner], anchor[inner])
    with pytest.raises(ValueError, match="shape"):
        plane_anchor(low, anchor[:-1], 100.0)


def test_a_surface_sloping_across_the_border_keeps_its_slope_there():
    """The 3×3 anchor of a border pixel is one-sided: on a floor rising 70 mm per low-res
    row it leans half a row inwards, and the last blocks' slope came out at half the floor's
    (the last block 15–37 mm off at r = 4). Along the border the anchor is the median of the
    pixel and its two neighbours there (a centrally symmetric neighbourhood), where that
    lies more than σ from it: the border keeps its depth, the blocks their slope. The
    corners (no symmetric pair), a border pixel beside a hole and a lean within σ (a flat
    surface: the median of 6 is the less noisy) keep the anchor."""
    from upsr.method.slopes import plane_anchor, plane_slopes
    from upsr.method.trust import reference_anchor

    ys, xs = np.mgrid[0:8, 0:9].astype(np.float32)
    low = 1800.0 + 70.0 * ys + 5.0 * xs
    anchor = reference_anchor(low, 1.0, 3.0, 100.0)[0]
    assert anchor[7, 4] == pytest.approx(low[7, 4] - 35.0)  # leans inwards
    plane = plane_anchor(low, anchor, 100.0, 10.0)
    np.testing.assert_allclose(plane[[0, -1], 1:-1], low[[0, -1], 1:-1])
    corners = ([0, 0, -1, -1], [0, -1, 0, -1])
    np.testing.assert_array_equal(plane[corners], anchor[corners])
    # across the left and right borders the lean (2.5 mm) is within σ
    np.testing.assert_array_equal(plane[:, [0, -1]], anchor[:, [0, -1]])
    sy = plane_slopes(low, anchor, 100.0, 10.0)[0]
    np.testing.assert_allclose(sy[:, 1:-1], 70.0, atol=1e-3)
    up = np.repeat(np.repeat(low, 4, axis=0), 4, axis=1)
    out = follow_slopes(up, anchor, sigma_mm=10.0, edge_mm=100.0, frame=low)
    # (the 5 mm across a block is within 2σ: the blocks keep their own trend along x)
    truth = 1800.0 + 70.0 * (np.arange(32) - 1.5) / 4.0 + 5.0 * 4
    np.testing.assert_allclose(out[:, 17], truth, atol=1e-2)
    # a lean within σ: the anchor
    np.testing.assert_array_equal(plane_anchor(low, anchor, 100.0, 40.0)[[0, -1]], anchor[[0, -1]])
    holed = low.copy()
    holed[6, 0] = 0.0
    a2 = reference_anchor(holed, 1.0, 3.0, 100.0)[0]
    assert plane_anchor(holed, a2, 100.0)[7, 1] == a2[7, 1]


def test_a_block_never_follows_its_slope_through_the_camera():
    """A steep slope a few mm away (a sensor's stray near values): its first block would reach
    1 − 0.375 × 40 = −14 mm; it keeps its depth, the others follow the slope."""
    low = np.array([[1.0, 41.0, 81.0, 121.0]] * 3)
    up = np.repeat(np.repeat(low, 2, axis=0), 2, axis=1)
    out = follow_slopes(up, low, sigma_mm=0.0, edge_mm=100.0)
    assert (out > 0).all()
    assert out[2, :2].tolist() == [1.0, 1.0]
    assert out[2, 2:6].tolist() == [31.0, 51.0, 71.0, 91.0]


def test_sloped_pixels_read_the_noise_at_their_depth():
    """60 mm per pixel is beyond 2σ where a profile σ = 5·(z / 1 m)² mm gives σ ≤ 27 mm
    (2–2.3 m), not where it gives 80–92 mm (4–4.3 m); a flat frame has no slope."""
    near = np.tile(2000.0 + 60.0 * np.arange(6), (5, 1)).astype(np.float32)
    far = near + 2000.0
    profile = (5.0, 2.0)
    slopes = plane_slopes(near, near, 100.0)
    assert sloped_pixels(near, slopes, 0.0, noise_profile=profile).all()
    assert not sloped_pixels(far, slopes, 0.0, noise_profile=profile).any()
    flat = np.full((5, 6), 2000.0, np.float32)
    assert not sloped_pixels(flat, plane_slopes(flat, flat, 100.0), 10.0).any()


def test_sloped_pixels_take_a_significance():
    """15 mm per pixel at σ = 10 mm: a slope from 1σ (the recursive mode's innovation
    caps), not from :data:`SIGNIFICANCE` = 2σ (the finishing's)."""
    ramp = np.tile(1000.0 + 15.0 * np.arange(6), (5, 1)).astype(np.float32)
    slopes = plane_slopes(ramp, ramp, 100.0)
    assert not sloped_pixels(ramp, slopes, 10.0).any()
    assert sloped_pixels(ramp, slopes, 10.0, significance=1.0).all()
