import numpy as np
import pytest

from upsr import InputError
from upsr.method.validation import as_depth_frame, as_depth_video


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


def test_one_empty_frame_is_fine():
    v = np.ones((3, 4, 4))
    v[1] = 0
    assert as_depth_video(v).shape == (3, 4, 4)
