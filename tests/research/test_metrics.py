"""Metrics of SPEC §6 on hand-made cases with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.method.upsampling import upsample_nearest
from upsr.research import metrics as m

FG, BG = 1000.0, 2000.0


def step(h: int = 20, w: int = 20, col: int = 10) -> np.ndarray:
    """Foreground (1000 mm) on columns < col, background (2000 mm) from col on."""
    t = np.full((h, w), BG, np.float32)
    t[:, :col] = FG
    return t


def test_discontinuity_mask_step_marks_both_sides_only():
    d = m.discontinuity_mask(step())
    expected = np.zeros((20, 20), bool)
    expected[:, 9:11] = True
    np.testing.assert_array_equal(d, expected)


def test_discontinuity_threshold_is_strict():
    t = np.full((4, 4), 1000.0)
    t[:, 2:] = 1100.0
    assert not m.discontinuity_mask(t, threshold_mm=100.0).any()
    t[:, 2:] = 1100.5
    assert m.discontinuity_mask(t, threshold_mm=100.0)[:, 1:3].all()


def test_valid_invalid_transition_is_a_discontinuity():
    t = np.full((5, 5), 1000.0)
    t[2, 2] = 0.0
    d = m.discontinuity_mask(t)
    expected = np.zeros((5, 5), bool)
    expected[2, 2] = expected[1, 2] = expected[3, 2] = expected[2, 1] = expected[2, 3] = True
    np.testing.assert_array_equal(d, expected)
    # NaN is invalid too
    t[2, 2] = np.nan
    np.testing.assert_array_equal(m.discontinuity_mask(t), expected)


def test_discontinuities_are_per_frame():
    video = np.stack([np.full((6, 6), FG), np.full((6, 6), BG)])
    assert not m.discontinuity_mask(video).any()
    video[1, :, 3:] = FG
    d = m.discontinuity_mask(video)
    assert not d[0].any()
    assert d[1, :, 2:4].all() and d[1].sum() == 12


def test_near_discontinuity_is_square_dilation():
    t = np.full((11, 11), BG)
    t[5, 5] = FG  # isolated bump: discontinuity at the centre and its 4 neighbours
    near = m.near_discontinuity(t, 2)
    # the Chebyshev ball of radius 2 around the plus-shaped discontinuity
    expected = np.zeros((11, 11), bool)
    expected[2:9, 3:8] = True
    expected[3:8, 2:9] = True
    np.testing.assert_array_equal(near, expected)
    assert near[3, 3]  # diagonal corner: Chebyshev, not Euclidean
    np.testing.assert_array_equal(m.near_discontinuity(t, 0), m.discontinuity_mask(t))


def test_perfect_estimate():
    t = step()
    t[0, 0] = 0.0  # one invalid true pixel
    res = m.evaluate(t.copy(), t, 2)
    assert res["rmse"] == 0.0 and res["mse"] == 0.0 and res["surface_rmse"] == 0.0
    assert res["edge_accuracy"] == 1.0
    assert res["flying_pixels"] == 0.0
    assert res["missing"] == 0.0 and res["invented"] == 0.0
    assert res["n_truth_valid"] == 399


def test_constant_offset_rmse_and_mse():
    t = step()
    res = m.evaluate(t + 10.0, t, 2)
    assert res["rmse"] == pytest.approx(10.0)
    assert res["mse"] == pytest.approx(100.0)
    assert res["surface_rmse"] == pytest.approx(10.0)
    assert m.rmse(t + 10.0, t) == pytest.approx(10.0)
    assert m.mse(t + 10.0, t) == pytest.approx(100.0)


def test_surface_rmse_ignores_edge_band():
    t = step()
    est = t.copy()
    est[4, 11] += 500.0  # 1 px from the edge: not a surface pixel for r = 2
    assert m.surface_rmse(est, t, 2) == 0.0
    assert m.rmse(est, t) == pytest.approx(math.sqrt(500.0**2 / 400))
    est[4, 16] += 40.0  # 6 px from the edge: a surface pixel
    n_surface = 20 * (20 - 6)
    assert m.surface_rmse(est, t, 2) == pytest.approx(math.sqrt(40.0**2 / n_surface))


def test_hand_placed_flying_pixel():
    t = step()
    est = t.copy()
    est[5, 10] = 1500.0  # halfway between foreground and background: flying
    fly = m.flying_pixel_mask(est, t, 2)
    assert fly[5, 10] and fly.sum() == 1
    n_candidates = 20 * 6  # columns 7..12 are within 2 px of the edge (columns 9, 10)
    assert m.flying_pixels(est, t, 2) == pytest.approx(1 / n_candidates)
    assert m.evaluate(est, t, 2)["flying_pixels"] == pytest.approx(1 / n_candidates)
    assert m.evaluate(est, t, 2)["n_flying"] == 1


def test_flying_threshold_is_150_mm_from_nearest_true_depth():
    t = step()
    est = t.copy()
    est[5, 9] = FG + 140.0  # close to the foreground: not flying
    est[6, 9] = FG + 160.0  # 160 mm from fg, 840 mm from bg: flying
    est[7, 10] = BG - 149.0
    fly = m.flying_pixel_mask(est, t, 2)
    assert not fly[5, 9] and fly[6, 9] and not fly[7, 10]
    assert fly.sum() == 1


def test_flying_neighbourhood_is_2r_plus_1_square():
    t = step()
    est = t.copy()
    # column 12 is 2 px from the edge column 10, but its 5x5 neighbourhood (cols 10..14)
    # holds only background: a foreground depth there matches nothing -> flying
    est[5, 12] = FG
    # column 11: its neighbourhood (cols 9..13) reaches the foreground -> plausible
    est[8, 11] = FG
    fly = m.flying_pixel_mask(est, t, 2)
    assert fly[5, 12] and not fly[8, 11]
    assert m.evaluate(est, t, 2)["n_flying"] == 1
    # a larger radius makes both plausible
    assert not m.flying_pixel_mask(est, t, 3)[5, 12]
    assert m.evaluate(est, t, 3)["n_flying"] == 0


def test_flying_pixels_only_counted_near_edges():
    t = step()
    est = t.copy()
    est[5, 18] = 1500.0  # far from the edge: a plain error, not a flying pixel
    assert not m.flying_pixel_mask(est, t, 2).any()
    assert m.flying_pixels(est, t, 2) == 0.0


def test_edge_accuracy_counts_missing_and_wrong():
    t = step()
    est = t.copy()
    est[0, 9] = 0.0  # missing near the edge: wrong
    est[1, 10] = np.nan  # NaN = missing: wrong
    est[2, 11] = BG + 150.0  # 150 mm off: wrong
    est[3, 12] = BG + 100.0  # exactly at the tolerance: right
    n_edge = 20 * 6
    assert m.edge_accuracy(est, t, 2) == pytest.approx(1 - 3 / n_edge)
    res = m.evaluate(est, t, 2)
    assert res["edge_accuracy"] == pytest.approx(1 - 3 / n_edge)
    assert res["n_edge"] == n_edge


def test_missing_output_is_wrong_even_for_tiny_true_depths():
    # 50 mm next to "no return": a missing output is within 100 mm of 50 mm, yet wrong
    t = np.zeros((6, 6))
    t[:, :3] = 50.0
    est = t.copy()
    est[0, 2] = 0.0
    assert m.edge_accuracy(est, t, 1) == pytest.approx(1 - 1 / 12)
    assert m.evaluate(est, t, 1)["edge_accuracy"] == pytest.approx(1 - 1 / 12)


def test_missing_pixels():
    t = step()
    est = t.copy()
    est[:2, :] = 0.0
    est[2, 0] = np.nan
    assert m.missing(est, t) == pytest.approx(41 / 400)
    res = m.evaluate(est, t, 2)
    assert res["missing"] == pytest.approx(41 / 400)
    # missing outputs do not enter the rmse
    assert res["rmse"] == 0.0


def test_invented_pixels():
    t = step()
    t[10:12, 15:19] = 0.0  # 8 pixels with no true depth
    est = step()
    est[10, 15] = 0.0  # 7 of the 8 are filled in by the estimate
    assert m.invented(est, t) == pytest.approx(7 / 8)
    assert m.evaluate(est, t, 2)["invented"] == pytest.approx(7 / 8)
    # no invalid truth at all: nothing can be invented
    assert m.invented(step(), step()) == 0.0


def test_nearest_upsampled_step_misses_edge_but_does_not_fly():
    r = 4
    lr_centres = (np.arange(8) + 0.5) * r - 0.5  # SPEC §1 pixel geometry
    hr_centres = np.arange(8 * r, dtype=float)
    x_edge = 10.3  # edge between high-res columns 10 and 11, inside low-res pixel 2

    def render(x):
        return np.where(x < x_edge, FG, BG)

    truth = np.tile(render(hr_centres), (8 * r, 1)).astype(np.float32)
    lowres = np.tile(render(lr_centres), (8, 1)).astype(np.float32)
    est = upsample_nearest(lowres, r)
    res = m.evaluate(est, truth, r)
    assert res["edge_accuracy"] < 1.0
    assert res["flying_pixels"] == 0.0
    assert res["missing"] == 0.0
    # a simple 2-tap linear interpolation creates intermediate depths at the edge: flying
    lin = np.interp(hr_centres, lr_centres, render(lr_centres))
    est_lin = np.tile(lin, (8 * r, 1))
    assert m.evaluate(est_lin, truth, r)["flying_pixels"] > 0.0


def test_video_metrics_pool_frames():
    t = np.stack([step(), step(col=5)])
    est = t.copy()
    est[1, 3, 5] = 1500.0
    res = m.evaluate(est, t, 2)
    assert res["n_flying"] == 1
    per_frame = m.evaluate(est[1], t[1], 2)
    assert per_frame["n_flying"] == 1
    assert res["flying_pixels"] == pytest.approx(0.5 * per_frame["flying_pixels"])


def test_evaluate_matches_individual_functions():
    rng = np.random.default_rng(1)
    t = step(24, 24, 12)
    t[3:6, 3:6] = 0.0
    est = np.where(t > 0, t + rng.laplace(0, 60.0, t.shape), 0.0)
    est[rng.random(t.shape) < 0.05] = 0.0
    est[0:2, 20:22] = 1500.0
    res = m.evaluate(est, t, 3)
    assert res["rmse"] == pytest.approx(m.rmse(est, t))
    assert res["mse"] == pytest.approx(m.mse(est, t))
    assert res["surface_rmse"] == pytest.approx(m.surface_rmse(est, t, 3))
    assert res["edge_accuracy"] == pytest.approx(m.edge_accuracy(est, t, 3))
    assert res["flying_pixels"] == pytest.approx(m.flying_pixels(est, t, 3))
    assert res["missing"] == pytest.approx(m.missing(est, t))
    assert res["invented"] == pytest.approx(m.invented(est, t))
    assert 0 < res["edge_accuracy"] < 1 and 0 < res["missing"] < 1


def test_undefined_values_are_nan():
    t = np.full((6, 6), FG)
    res = m.evaluate(np.zeros_like(t), t, 1)
    assert math.isnan(res["rmse"]) and math.isnan(res["surface_rmse"])
    assert math.isnan(res["edge_accuracy"])  # no discontinuity in the truth
    assert res["missing"] == 1.0


@pytest.mark.parametrize(
    ("est", "truth", "match"),
    [
        (np.ones((4, 4)), np.ones((4, 5)), "shape"),
        (np.ones((4,)), np.ones((4,)), "expected a depth"),
        (np.ones((2, 2, 2, 2)), np.ones((2, 2, 2, 2)), "expected a depth"),
        (-np.ones((4, 4)), np.ones((4, 4)), "negative"),
        (np.full((4, 4), np.inf), np.ones((4, 4)), "inf"),
        (np.ones((4, 4)), np.zeros((4, 4)), "no valid depth"),
        (np.array([["a"]], dtype=object), np.ones((1, 1)), "numeric"),
    ],
)
def test_bad_input_raises_input_error(est, truth, match):
    with pytest.raises(InputError, match=match):
        m.evaluate(est, truth, 1)


def test_bad_radius_raises():
    with pytest.raises(InputError, match="radius"):
        m.near_discontinuity(step(), -1)
    with pytest.raises(InputError, match="radius"):
        m.evaluate(step(), step(), 1.5)
