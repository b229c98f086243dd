import numpy as np
import pytest

from upsr import InputError
from upsr.method.validation import as_depth_frame, as_depth_video, nan_as_zero


def test_nan_becomes_invalid_and_integers_are_converted():
    v = as_depth_video(np.array([[[np.nan, 1000.0]]]))
    assert v.dtype == np.float32 and v[0, 0, 0] == 0 and v[0, 0, 1] == 1000
    assert as_depth_frame(np.full((2, 2), 1500, np.uint16)).dtype == np.float32


def test_input_is_not_modified():
    a = np.array([[[np.nan, 1.0]]])
    as_depth_video(a)
    assert np.isnan(a[0, 0, 0])


@pytest.mark.parametrize(
    "bad",
    [
        np.ones((4, 4)),  # 2-D: not a video
        np.ones((2, 3, 4, 5)),
        np.ones((0, 4, 4)),
        np.ones((2, 4, 4), complex),
        np.array([[["a"]]]),
        np.array([[[1.0, np.inf]]]),
        np.array([[[1.0, -5.0]]]),
        np.zeros((3, 4, 4)),
        np.full((3, 4, 4), np.nan),
        np.ones((2, 2, 2), bool),
    ],
)
def test_bad_videos_rejected(bad):
    with pytest.raises(InputError):
        as_depth_video(bad)


def test_a_generator_of_frames_is_a_video():
    """super_resolve((f for f in video)) said "object arrays are not depth data"."""
    frames = [np.full((2, 3), 1000.0 + t) for t in range(3)]
    np.testing.assert_array_equal(as_depth_video(f for f in frames), np.stack(frames))
    np.testing.assert_array_equal(as_depth_video(iter(frames)), np.stack(frames))


def test_one_empty_frame_is_fine():
    v = np.ones((3, 4, 4))
    v[1] = 0
    assert as_depth_video(v).shape == (3, 4, 4)


def test_depths_outside_the_valid_range_are_no_measurement():
    frame = np.array([[50.0, 100.0, 2000.0], [65535.0, 0.0, np.nan]])
    out = as_depth_frame(frame, valid_range_mm=(100.0, 10000.0))
    assert out.tolist() == [[0.0, 100.0, 2000.0], [0.0, 0.0, 0.0]]
    with pytest.raises(InputError, match="outside 70000-80000 mm"):
        as_depth_video(frame[None], valid_range_mm=(70000.0, 80000.0))


def test_nan_as_zero_reads_a_finite_float32_frame_in_place_and_copies_anything_else():
    """What ``np.nan_to_num(np.asarray(z, np.float32), nan=0.0)`` gives, without the copy
    where nothing is to change (the method's per-frame helpers only read it)."""
    z = np.array([[1000.0, 0.0], [1500.0, 2000.0]], np.float32)
    assert nan_as_zero(z) is z
    for bad in (
        np.array([[np.nan, 1000.0], [0.0, 2000.0]], np.float32),
        np.array([[np.inf, 1000.0], [-np.inf, 2000.0]], np.float32),
        np.array([[np.nan, 1000.0], [0.0, 2000.0]], np.float64),
        [[1000, 0], [1, 2]],
    ):
        before = np.array(bad, copy=True)
        out = nan_as_zero(bad)
        expected = np.nan_to_num(np.asarray(bad, np.float32), nan=0.0)
        assert out.dtype == np.float32 and out is not bad
        np.testing.assert_array_equal(out, expected)
        np.testing.assert_array_equal(np.asarray(bad), before)  # the input is left as it was


def test_check_ref_is_the_one_check_of_a_windows_reference():
    """temporal_median refused ref=True with an InputError, register_and_fuse took it as 1
    and raised plain ValueErrors for the rest (review): one check for both."""
    from upsr.method.fusion import register_and_fuse, temporal_median
    from upsr.method.validation import check_ref

    assert check_ref(None, 5) == 2 and check_ref(np.int64(4), 5) == 4
    lowres = np.full((3, 4, 4), 1000.0, np.float32)
    maps = np.zeros((3, 8, 8, 2), np.float32)
    for bad in (True, 3, -1, 1.5):
        with pytest.raises(InputError, match=r"ref must be an integer in \[0, 3\)"):
            check_ref(bad, 3)
        with pytest.raises(InputError, match="ref must be an integer"):
            register_and_fuse(lowres, maps, 2, bad)
        with pytest.raises(InputError, match="ref must be an integer"):
            temporal_median(np.ones((3, 2, 2), np.float32), bad)
    with pytest.raises(InputError, match="estimator"):
        register_and_fuse(lowres, maps, 2, estimator="mode")
