"""Thin parts of a ToF frame, mixed along their whole length (upsr.method.thin)."""

import numpy as np
import pytest

import upsr
from upsr.method.mixed import split_mixed_pixels
from upsr.method.thin import split_thin_parts, thin_parts
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
