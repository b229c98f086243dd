"""Sorting networks and medians (upsr.method.sorting)."""

import numpy as np

from upsr.method.sorting import median_beyond, weighted_median


def test_median_beyond_decides_as_the_median_does():
    """median_beyond (used by the recursive mode: whether the state as a whole lies nearer or
    farther than the frame) decides by counting: it must agree with the median itself, odd
    and even counts, values that tie with the limit and halves that split exactly at it
    included."""
    rng = np.random.default_rng(2)
    cases = [np.array([-1.0, 1.0, 3.0, 5.0], np.float32), np.array([2.0, 2.0, 2.0], np.float32)]
    for n in (25, 26, 101, 1000):
        for shift in np.linspace(-3.0, 3.0, 13):
            cases.append((shift + rng.normal(0, 1.0, n)).astype(np.float32))
            cases.append(np.round(shift + rng.normal(0, 1.0, n)).astype(np.float32))
    decided = {True: 0, False: 0}
    for values in cases:
        for limit in (0.5, 1.0, 2.0):
            want = abs(float(np.median(values))) > limit
            assert median_beyond(values, limit) == want
            decided[want] += 1
    assert min(decided.values()) > 20


def test_the_small_medians_are_the_median_ties_included():
    """The medians of the anchor and the radial offsets (``sorting._small_median``, m ≤ 25
    by rank counting; ``trust._select_median``, quickselect beyond) give numpy's median for
    every count, odd and even, with and without ties."""
    from upsr.method.sorting import _small_median
    from upsr.method.trust import _select_median

    rng = np.random.default_rng(3)
    for m in range(1, 41):
        for draw in range(6):
            values = rng.normal(0.0, 50.0, m).astype(np.float32)
            if draw % 2:
                values = np.round(values / 40.0).astype(np.float32)  # many ties
            want = np.float32(np.median(values.astype(np.float64)))
            if m <= 25:
                assert np.float32(_small_median(values.copy(), m)) == want
            assert np.float32(_select_median(values.copy(), m)) == want


def test_the_weighted_median_is_the_lower_one_where_half_the_weight_is_reached():
    values = np.array([5.0, 1.0, 3.0, 2.0])
    assert weighted_median(values, np.array([1, 1, 1, 1])) == 2.0  # (the lower of 2 and 3)
    assert weighted_median(values, np.array([1.0, 0.5, 0.5, 3.0])) == 2.0
    assert weighted_median(values, np.array([9, 1, 1, 1])) == 5.0
    assert weighted_median(np.array([7.0]), np.array([2])) == 7.0
