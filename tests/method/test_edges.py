"""Sub-pixel depth edges from the bilinear votes of each frame's samples (upsr.method.edges)."""

import numpy as np

from upsr.method.edges import SURFACE_GAP, edge_band, vote_surface
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
