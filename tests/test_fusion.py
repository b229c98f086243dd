import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from upsr.fusion import temporal_median

NAN = np.nan


def px(*samples):
    """A (N, 1, 1) stack holding the samples of one pixel."""
    return np.array(samples, np.float32)[:, None, None]


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(500, 4000, width=32), min_size=1, max_size=15), st.data())
def test_all_valid_unimodal_is_plain_median(values, data):
    # samples on one surface (spread <= edge_mm): the ordinary median, average of the middle two
    values = np.array(values, np.float32)
    values = values[0] + (values - values[0]) * (50.0 / max(np.ptp(values), 1.0))
    ref = data.draw(st.integers(0, len(values) - 1))
    out = temporal_median(px(*values), ref)
    assert out[0, 0] == pytest.approx(np.median(values), rel=1e-6)


def test_invalid_samples_do_not_vote_on_depth():
    # 0 = no return, NaN = outside: the median of the valid ones only
    assert temporal_median(px(1000, 0, 1010, 1020, 0, NAN, NAN), 0)[0, 0] == 1010


def test_random_dropout_is_filled():
    assert temporal_median(px(1000, 0, 1004, 1008, 0, 1002, 1006, 0, 1001), 1)[0, 0] == 1003


def test_one_stray_sample_never_invents_depth():
    # background out of range: most samples say "no return"
    assert temporal_median(px(0, 0, 0, 0, 1500, 0, 0, 0, 0), 4)[0, 0] == 0
    assert temporal_median(px(0, 0, 0, 1500, 1500, 0, 0, 0, 0), 4)[0, 0] == 0


def test_outside_samples_abstain_and_ties_follow_reference():
    assert temporal_median(px(NAN, NAN, NAN, 1200, 0), 3)[0, 0] == 1200
    assert temporal_median(px(NAN, NAN, NAN, 1200, 0), 4)[0, 0] == 0
    assert temporal_median(px(NAN, NAN, NAN), 1)[0, 0] == 0


def test_even_count_never_averages_foreground_and_background():
    # two surfaces with equal votes: the reference's surface wins, never a depth in between
    assert temporal_median(px(1000, 1005, 3000, 3010), 0)[0, 0] == 1002.5
    assert temporal_median(px(1000, 1005, 3000, 3010), 3)[0, 0] == 3005
    assert temporal_median(px(1000, 1005, 3000, 3010, 1003, 2990), 1)[0, 0] == 1003
    assert temporal_median(px(1000, 1005, 3000, 3010, 1003, 2990), 2)[0, 0] == 3000
    # on one surface the two middle samples are averaged
    assert temporal_median(px(1000, 1004, 1008, 1012), 0)[0, 0] == 1006


def test_weights_decide_the_surface_at_an_edge():
    stack = px(1000, 1001, 1002, 3000, 3001)
    # unweighted: three foreground samples win
    assert temporal_median(stack, 0)[0, 0] == 1001
    w = px(0.1, 0.1, 0.1, 1.0, 1.0)
    assert temporal_median(stack, 0, weights=w)[0, 0] == pytest.approx(3000.5)


def test_image_stack_and_static_scene():
    rng = np.random.default_rng(0)
    frames = rng.uniform(960, 1040, (7, 20, 30)).astype(np.float32)
    np.testing.assert_allclose(temporal_median(frames), np.median(frames, axis=0), rtol=1e-6)


def test_bad_arguments():
    with pytest.raises(ValueError):
        temporal_median(np.ones((3, 3)))
    with pytest.raises(ValueError):
        temporal_median(np.ones((3, 2, 2)), ref=3)
