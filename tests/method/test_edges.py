"""Sub-pixel depth edges from the bilinear votes of each frame's samples (upsr.method.edges)."""

import numpy as np
import pytest

from upsr.method.edges import (
    REVERT_MIN_SHARE,
    SURFACE_GAP,
    VOTE_FRAMES,
    cell_ranges,
    edge_band,
    state_votes,
    vote_surface,
    votes_may_move,
)
from upsr.method.fusion import register_and_fuse

FG, BG = 1000.0, 2000.0


def _disc(shape, r, centre, radius):
    """A foreground disc (FG) before a wall (BG): the high-res truth and its point samples at
    the low-res pixel centres ((i + 0.5)·r − 0.5)."""
    hh, ww = shape[0] * r, shape[1] * r
    y, x = np.mgrid[0:hh, 0:ww].astype(np.float64)
    truth = np.where(np.hypot(y - centre[0], x - centre[1]) <= radius, FG, BG)
    c = (np.arange(shape[0]) + 0.5) * r - 0.5, (np.arange(shape[1]) + 0.5) * r - 0.5
    yl, xl = np.meshgrid(*c, indexing="ij")
    low = np.where(np.hypot(yl - centre[0], xl - centre[1]) <= radius, FG, BG)
    return truth.astype(np.float32), low.astype(np.float32)


def test_the_band_lies_along_depth_edges_only():
    z = np.full((12, 16), BG, np.float32)
    z[:, :6] = FG
    band = edge_band(z, 100.0)
    assert band[:, 5:7].all()  # the pixels whose 3×3 neighbourhood spans the edge (5 | 6)
    assert not band[:, :5].any() and not band[:, 7:].any()
    assert not edge_band(np.full((12, 16), BG, np.float32), 100.0).any()
    z = np.full((12, 16), BG, np.float32)
    z[5, 7] = 0.0  # a hole, depth beside no depth: one surface, nothing to vote on
    assert not edge_band(z, 100.0).any()


def test_one_frame_places_a_curved_edge_better_than_the_block_grid():
    """A disc sampled by one frame: the votes of the four samples around each pixel cut the
    corners of nearest upsampling's staircase; every output value is a measured one."""
    r = 4
    truth, low = _disc((16, 20), r, centre=(31.3, 38.7), radius=21.0)
    maps = np.zeros((1, 16 * r, 20 * r, 2), np.float32)
    nearest = register_and_fuse(low[None], maps, r, 0)
    voted = register_and_fuse(low[None], maps, r, 0, edge_votes=True)
    wrong = lambda est: int((est != truth).sum())  # noqa: E731
    assert wrong(voted) < 0.9 * wrong(nearest)
    assert set(np.unique(voted)) <= {FG, BG}
    np.testing.assert_array_equal(nearest, np.repeat(np.repeat(low, r, axis=0), r, axis=1))


def test_a_slope_stepping_beyond_the_threshold_is_no_second_surface():
    """A pixel 3/4 of the way from one low-res row to the next takes the next row's surface
    when the rows lie on both sides of an occlusion edge, but keeps the fusion's depth on a
    floor at a grazing angle stepping 150 mm per row (> edge_mm, < SURFACE_GAP of it)."""
    r, edge = 4, 100.0
    py = np.array([(1.75 + 0.5) * r - 0.5])  # output row of low-res coordinate 1.75
    scratch = np.empty(4, np.float32), np.empty(4, np.float32)

    def vote(column, fused):
        low = np.asarray(column, np.float32)[None, :, None]
        args = (np.zeros(1, np.float32), np.array([fused], np.float32), np.zeros(1), py, r)
        return vote_surface(low, *args, edge, -np.inf, np.float32(fused), *scratch)

    assert vote([1000.0, 1000.0, 2000.0], 1000.0) == 2000.0
    assert vote([1000.0, 1150.0, 1300.0], 1150.0) == 1150.0
    assert SURFACE_GAP * edge > 150.0
    # "no depth" outweighs the wall there: the fusion's depth stays (never emptied), and
    # where the fusion left no depth the wall's weight adds none
    assert vote([1000.0, 2000.0, 0.0], 1000.0) == 1000.0
    assert vote([0.0, 0.0, 2000.0], 0.0) == 0.0


def test_votes_never_add_depth_nor_remove_it():
    """Where the fusion leaves a pixel without depth it stays so, and a pixel with depth keeps
    depth, whatever the votes around it."""
    r = 4
    _truth, low = _disc((12, 12), r, centre=(23.5, 23.5), radius=14.0)
    low[:, 6:][low[:, 6:] == BG] = 0.0  # the wall out of range on the right: no depth there
    low[:6, 7:] = 0.0  # and a hole that reaches into the disc
    maps = np.zeros((1, 12 * r, 12 * r, 2), np.float32)
    nearest = register_and_fuse(low[None], maps, r, 0)
    voted = register_and_fuse(low[None], maps, r, 0, edge_votes=True)
    assert (voted != nearest).any()  # the votes act on the edge before the wall
    np.testing.assert_array_equal(voted > 0, nearest > 0)


def _random_frames(rng, n, h, w, r):
    """Radial offsets, frames that abstain (NaN) and positions anywhere in the frame for n
    frames of h×w low-res pixels at scale r: the arguments of vote_surface after the frames."""
    offsets = rng.choice([0.0, 0.0, 4.0, -6.0], n).astype(np.float32)
    raw = np.where(rng.random(n) < 0.2, np.nan, 1.0).astype(np.float32)
    px = rng.uniform(-0.5, w * r - 0.5, n).astype(np.float32)
    py = rng.uniform(-0.5, h * r - 0.5, n).astype(np.float32)
    return offsets, raw, px, py


def test_the_first_test_of_the_votes_never_skips_a_pixel_they_would_move():
    """votes_may_move (each frame's nearest and farthest depth per cell of four samples) is
    False only where vote_surface keeps the fusion's value: random windows of two surfaces
    about the surface gap apart (a few mm either side of it), holes, removed samples (< 0),
    radial offsets, frames that abstain (NaN) and positions anywhere in the frame."""
    rng = np.random.default_rng(7)
    edge = 100.0
    gap = SURFACE_GAP * edge
    skipped = moved = 0
    for _ in range(4000):
        n, h, w, r = rng.integers(1, 10), rng.integers(2, 6), rng.integers(2, 6), rng.choice([2, 4])
        near = 1000.0
        far = near + gap + rng.choice([-3.0, 0.0, 0.01, 3.0, 9.0, gap])
        share = rng.random(4)
        levels = rng.choice([near, far, 0.0, -1.0], (n, h, w), p=share / share.sum())
        low = levels.astype(np.float32)
        offsets, raw, px, py = _random_frames(rng, n, h, w, r)
        fused = np.float32(rng.choice([0.0, near, far]) + rng.choice([0.0, -5.0, 5.0]))
        floor = rng.choice([-np.inf, 900.0])
        lo, hi = cell_ranges(low)
        scratch = np.empty(4 * n, np.float32), np.empty(4 * n, np.float32)
        voted = vote_surface(low, offsets, raw, px, py, r, edge, floor, fused, *scratch)
        moved += voted != fused
        if not votes_may_move(lo, hi, offsets, raw, px, py, r, edge, fused):
            skipped += 1
            assert voted == fused
    assert skipped > 1000 and moved > 500  # (both outcomes are exercised)


def _votes_by_sorting(low, offsets, raw, px, py, r, edge, floor, fused):
    """What vote_surface returns, in plain Python: every voting frame's four samples around
    its position sorted by depth, cut into surfaces (gaps beyond ``edge``; "no depth" one of
    its own), the heaviest surface (the first of equal ones) moves the pixel to its weighted
    median when it has depth and lies wholly beyond the gap from ``fused``; None when the
    two heaviest surfaces weigh the same."""
    if not fused > 0:
        return fused
    n, h, w = low.shape
    gap = SURFACE_GAP * edge
    samples = []
    for k in range(n):
        if np.isnan(raw[k]):
            continue
        u, t = (float(py[k]) + 0.5) / r - 0.5, (float(px[k]) + 0.5) / r - 0.5
        i0, j0 = int(np.floor(u)), int(np.floor(t))
        for di in (0, 1):
            for dj in (0, 1):
                wt = (u - i0 if di else 1 - (u - i0)) * (t - j0 if dj else 1 - (t - j0))
                wt = float(np.float32(wt))  # (as kept: float32, added up in float64)
                z = low[k, min(max(i0 + di, 0), h - 1), min(max(j0 + dj, 0), w - 1)]
                val = z - offsets[k] if z > 0 else np.float32(np.inf)
                if wt > 0 and z >= 0 and val >= floor:
                    samples.append((val, wt))
    if not any(np.isfinite(val) and abs(val - fused) > gap for val, _ in samples):
        return fused
    samples.sort(key=lambda s: s[0])  # (stable)
    runs, start = [], 0
    for p in range(1, len(samples) + 1):
        with np.errstate(invalid="ignore"):  # (inf − inf: no gap within "no depth")
            if p == len(samples) or samples[p][0] - samples[p - 1][0] > edge:
                runs.append(samples[start:p])
                start = p
    weights = sorted((sum(wt for _, wt in run) for run in runs), reverse=True)
    if len(weights) > 1 and weights[0] - weights[1] < 1e-6:
        return None  # equal surfaces: float rounding of their weights decides, not the rule
    best = max(runs, key=lambda run: sum(wt for _, wt in run))
    lo, hi = best[0][0], best[-1][0]
    if lo == np.inf or lo - gap <= fused <= hi + gap:
        return fused
    half, acc = 0.5 * sum(wt for _, wt in best), 0.0
    for val, wt in best:
        acc += wt
        if acc >= half:
            return val
    return hi


def test_the_votes_keep_the_fusions_value_exactly_where_sorting_them_would():
    """vote_surface (which decides most pixels without sorting their samples: the surface
    near the fusion's value outweighs all samples beyond the gap on either side) against
    its samples sorted into surfaces: random windows of three surfaces around the surface
    gap apart, holes, removed samples, offsets, abstaining frames, positions anywhere."""
    rng = np.random.default_rng(11)
    edge = 100.0
    gap = SURFACE_GAP * edge
    kept = moved = 0
    for _ in range(3000):
        n, h, w, r = rng.integers(1, 10), rng.integers(2, 6), rng.integers(2, 6), rng.choice([2, 4])
        mid = 2000.0
        near = mid - gap - rng.choice([-30.0, 5.0, 60.0, gap])
        far = mid + gap + rng.choice([-30.0, 5.0, 60.0, gap])
        share = rng.random(5)
        levels = rng.choice([near, mid, far, 0.0, -1.0], (n, h, w), p=share / share.sum())
        low = (levels + rng.normal(0.0, 20.0, levels.shape) * (levels > 0)).astype(np.float32)
        offsets, raw, px, py = _random_frames(rng, n, h, w, r)
        fused = np.float32(rng.choice([0.0, near, mid, far]) + rng.normal(0.0, 20.0))
        floor = rng.choice([-np.inf, near + 50.0])
        scratch = np.empty(4 * n, np.float32), np.empty(4 * n, np.float32)
        voted = vote_surface(low, offsets, raw, px, py, r, edge, floor, fused, *scratch)
        expected = _votes_by_sorting(low, offsets, raw, px, py, r, edge, floor, fused)
        if expected is None:
            continue
        assert voted == np.float32(expected)
        far_samples = ((np.abs(low - fused) > gap) & (low > 0)).any()
        kept += bool(voted == fused and fused > 0 and far_samples)
        moved += bool(voted != fused)
    assert kept > 500 and moved > 300  # (both outcomes are exercised)


def test_several_frames_shifted_by_sub_pixel_motion_vote_together():
    """Three frames of a disc moving 1/3 low-res px per frame, registered with their exact
    motion: the votes place the edge better than one frame's."""
    r = 4
    shape = (16, 20)
    frames, maps = [], []
    for dx in (-4 / 3, 0.0, 4 / 3):
        _t, low = _disc(shape, r, centre=(31.3, 38.7 + dx), radius=21.0)
        frames.append(low)
        m = np.zeros((shape[0] * r, shape[1] * r, 2), np.float32)
        m[..., 0] = dx  # reference pixel p lies at p + dx in frame k
        maps.append(m)
    truth, _ = _disc(shape, r, centre=(31.3, 38.7), radius=21.0)
    lowres, maps = np.stack(frames), np.stack(maps)
    one = register_and_fuse(lowres[1:2], maps[1:2], r, 0, edge_votes=True)
    three = register_and_fuse(lowres, maps, r, 1, edge_votes=True)
    assert (three != truth).sum() < (one != truth).sum()


# -- the recursive state's votes (state_votes) ------------------------------------------------
R7, X = 7, 14  # high-res column 14 at r = 7: 4/7 low-res px right of the FG column's centre


def _state_case(state_cols, updated_cols, share):
    """Three low-res rows: the frame measures FG on columns 0-1, BG on 2-3 (the frame gives FG
    3/7 of its weight at column X, whose nearest sample is BG); the previous state (FG on
    high-res columns < ``state_cols``, BG beyond, count 3, share ``share`` at column X and 1
    elsewhere) and the update's result (FG on columns < ``updated_cols``), registered without
    motion. Returns (new depth, new count, new share)."""
    meas = np.tile(np.array([FG, FG, BG, BG], np.float32), (3, 1))
    hh, ww = 3 * R7, 4 * R7
    cols = np.arange(ww)[None, :].repeat(hh, axis=0)
    prev_d = np.where(cols < state_cols, FG, BG).astype(np.float32)
    depth = np.where(cols < updated_cols, FG, BG).astype(np.float32)
    count = np.full((hh, ww), 3.0, np.float32)
    prev_s = np.where(cols == X, share, 1.0).astype(np.float32)
    qy, qx = np.mgrid[0:hh, 0:ww].astype(np.float32)
    offsets = np.zeros((3, 4), np.float32)
    previous = (prev_d, count.copy(), prev_s)
    new = state_votes(depth, count, previous, (qx, qy), meas, offsets, scale=R7, edge_mm=100.0)
    return depth, count, new


def test_the_state_leaves_its_surface_once_its_share_falls_below_half():
    """A state on FG at column X with share 0.45 (over VOTE_FRAMES frames with the frame's
    3/7: below one half) moves to the frame's BG sample; with share 0.9 it stays FG."""
    w_fg = 3.0 / 7.0
    depth, count, share = _state_case(state_cols=X + 1, updated_cols=X + 1, share=0.45)
    assert depth[10, X] == BG and count[10, X] == 1.0
    assert share[10, X] == pytest.approx(1.0 - (0.45 + (w_fg - 0.45) / VOTE_FRAMES), abs=1e-5)
    assert (depth[:, :X] == FG).all() and (depth[:, X + 1 :] == BG).all()
    depth, _count, share = _state_case(state_cols=X + 1, updated_cols=X + 1, share=0.9)
    assert depth[10, X] == FG
    assert share[10, X] == pytest.approx(0.9 + (w_fg - 0.9) / VOTE_FRAMES, abs=1e-5)


def test_the_state_keeps_its_surface_against_the_frames_staircase_where_it_is_registered():
    """The update moved column X to the frame's nearest sample (BG), but the state had FG
    there with share 0.9, and the frame still gives FG 3/7 (≥ REVERT_MIN_SHARE) of its
    weight: FG stays, with the state's count. Not when the state is not registered there (at
    its block's centre, column 17, it holds FG where the frame measured BG: a thin part the
    state did not follow), nor without the frame's weight (the state's FG one column
    farther, where the frame gives FG 2/7)."""
    assert REVERT_MIN_SHARE <= 3.0 / 7.0
    depth, count, _share = _state_case(state_cols=X + 1, updated_cols=X, share=0.9)
    assert depth[10, X] == FG and count[10, X] == 3.0
    depth, _count, _share = _state_case(state_cols=X + 4, updated_cols=X, share=0.9)
    assert depth[10, X] == BG
    depth, _count, _share = _state_case(state_cols=X + 2, updated_cols=X, share=1.0)
    assert depth[10, X + 1] == BG


def test_state_votes_never_add_depth_nor_remove_it():
    """A pixel the update left without depth keeps none (share 0), and a pixel with depth
    never moves to "no depth" when the other samples around it have none."""
    r = 5
    meas = np.tile(np.array([FG, FG, 0.0, 0.0], np.float32), (3, 1))
    meas[:, 3] = BG  # an edge (FG | hole | BG): the band holds columns 1-3
    hh, ww = 3 * r, 4 * r
    depth = np.repeat(np.repeat(meas, r, axis=0), r, axis=1)
    before = depth.copy()
    count = np.full((hh, ww), 3.0, np.float32)
    previous = (before.copy(), count.copy(), np.full((hh, ww), 0.3, np.float32))
    qy, qx = np.mgrid[0:hh, 0:ww].astype(np.float32)
    offsets = np.zeros((3, 4), np.float32)
    share = state_votes(depth, count, previous, (qx, qy), meas, offsets, scale=r, edge_mm=100.0)
    np.testing.assert_array_equal(depth > 0, before > 0)
    assert (share[before == 0] == 0).all()


def test_the_band_of_the_state_votes_leaves_out_steep_floors():
    """A floor seen at a grazing angle (even steps of 250 mm per row, beyond the edge
    threshold) spans more than edge_mm in every 3×3: edge_band holds it, the slope-aware
    band does not; an occlusion edge is in both."""
    floor = np.tile((1000.0 + 250.0 * np.arange(8, dtype=np.float32))[:, None], (1, 6))
    assert edge_band(floor, 100.0).all()
    assert not edge_band(floor, 100.0, slopes=True).any()
    z = np.full((8, 6), BG, np.float32)
    z[:, :3] = FG
    np.testing.assert_array_equal(edge_band(z, 100.0, slopes=True), edge_band(z, 100.0))
