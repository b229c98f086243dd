"""Whether a sensor integrates a footprint: the per-video decision (upsr.method.footprint)."""

import numpy as np
import pytest

from tests.method._helpers import WALL, tof_edge_frames


def test_footprint_share_tells_a_tof_sensor_from_a_point_sampling_one():
    from upsr.method.footprint import MIXED_SHARE, footprint_share, has_mixed_pixels

    tof = tof_edge_frames()
    point = np.full_like(tof, WALL)
    point[:, :, :8] = 1000.0
    # every edge mixed beyond the threshold: the share over what a footprint would give
    expected = 1.0 - 2.0 * 100.0 / abs(WALL - 1000.0)
    assert footprint_share(tof, 100.0) == pytest.approx(1.0 / expected)
    assert has_mixed_pixels(footprint_share(tof, 100.0))
    assert footprint_share(point, 100.0) == 0.0 and not has_mixed_pixels(0.0)
    assert footprint_share(np.full((2, 8, 8), WALL, np.float32), 100.0) == 0.0  # no edge
    assert 0 < MIXED_SHARE < 1


def test_footprint_share_counts_against_what_a_footprint_would_mix():
    """Near surfaces (a step of 350 mm at a threshold of 100): a footprint across the edge mixes
    beyond the threshold from both sides only where it covers 29–71 % of either, 3 of 8 edge
    places here; that is what a ToF sensor gives there, near the expectation, far from a
    point sampler's 0 (the approaching camera of seed 3 had a plain share of the edges of
    0.28, and a point-sampled room 0.30)."""
    from upsr.method.footprint import MIXED_SHARE, footprint_share
    from upsr.research.synth.degradation import tof_footprint

    r = 8
    hr = np.full((8, 12 * r, 16 * r), 2350.0, np.float32)
    for k in range(8):
        hr[k, :, : 7 * r + k] = 2000.0  # the edge k/8 into the 8th low-res column
    share = footprint_share(tof_footprint(hr, r), 100.0)
    assert MIXED_SHARE <= share < 1.5
    point = hr[:, r // 2 :: r, r // 2 :: r]  # the same scene point-sampled
    assert footprint_share(point, 100.0) == 0.0


def test_one_straight_edge_weighs_as_the_root_of_its_length():
    """A long straight edge decides the share no more than √(its length) pixels would: a
    point sampler's box side seen edge-on (one pixel between the surfaces all along, a
    pixel-by-pixel share of 0.63; 0.32 with the runs) is not a mixing sensor; a ToF sensor
    whose long edges happen to lie on its pixels' boundaries (no mix along them, a
    pixel-by-pixel share of 0.49; 0.79 with the runs) still is, from the short edges at other
    places that mix."""
    from upsr.method.footprint import footprint_share, has_mixed_pixels
    from upsr.research.synth.degradation import tof_footprint

    point = np.full((1, 32, 40), WALL, np.float32)
    point[:, :, :10] = 1000.0
    point[:, :, 10] = 2000.0  # the side, edge-on
    point[:, 20:23, 25:28] = 1000.0  # a small box: eight short edges, none with a mix
    assert not has_mixed_pixels(footprint_share(point, 100.0))
    r = 4
    hr = np.full((1, 32 * r, 40 * r), WALL, np.float32)
    hr[:, :, : 10 * r] = 1000.0  # on a boundary
    for k, (i, j) in enumerate(((4, 20), (14, 30), (24, 20))):
        hr[:, i * r + 1 + k : (i + 3) * r + 1 + k, j * r + 2 : (j + 3) * r + 2] = 1000.0
    assert has_mixed_pixels(footprint_share(tof_footprint(hr, r), 100.0))


def test_the_decision_from_the_frames_so_far_turns_off_only_clearly():
    from upsr.method.footprint import MIXED_SHARE, MIXED_SHARE_HYSTERESIS, has_mixed_pixels

    share = MIXED_SHARE - 0.5 * MIXED_SHARE_HYSTERESIS
    assert not has_mixed_pixels(share) and has_mixed_pixels(share, was=True)
    assert not has_mixed_pixels(MIXED_SHARE - 1.5 * MIXED_SHARE_HYSTERESIS, was=True)
    assert has_mixed_pixels(MIXED_SHARE)


def test_a_thin_part_seen_by_a_footprint_is_no_flat_surface_beside_an_edge():
    """A ToF sensor sees a part 1–2 px wide as a band of mixes itself, with no mix beside it:
    its sides are not counted as edges between flat surfaces (a table's 1.2 px legs and a
    propeller's 1.5 px blades read 0.22 and 0.32 against 0.5, their mixes kept: 37.5 % and
    8.5 % flying pixels, ``benchmarks/outside_eval.py``); a wide part's edges still are."""
    from upsr.method.footprint import footprint_counts, footprint_share, has_mixed_pixels
    from upsr.research.synth.degradation import tof_footprint

    r = 4
    hr = np.full((1, 24 * r, 40 * r), WALL, np.float32)
    hr[:, :, 30 * r + 1 : 36 * r + 1] = 1000.0  # a wide part: two edges that mix
    for j in (6, 14, 22):
        hr[:, :, j * r + 1 : j * r + 7] = 1000.0  # three legs 1.5 px wide: two pixels ¾ leg
    tof = tof_footprint(hr, r)
    assert has_mixed_pixels(footprint_share(tof, 100.0))
    # the wide part's two straight edges (each weighs √24 in all), mixed as expected
    between, expected = footprint_counts(tof, 100.0)
    assert between == pytest.approx(2 * np.sqrt(24))
    assert expected == pytest.approx(between * (1.0 - 2.0 * 100.0 / abs(WALL - 1000.0)))
    # a point sampler's thin parts (pure, 2 px wide) are no evidence either way
    point = hr[:, r // 2 :: r, r // 2 :: r]
    assert footprint_share(point, 100.0) == 0.0
