"""upsr.viz.pointcloud_colors: per-pixel colours of point clouds."""

from __future__ import annotations

import numpy as np
import pytest

from upsr.errors import InputError
from upsr.viz.colormaps import colorize_depth
from upsr.viz.pointcloud_colors import color_for_depth


def _depth() -> np.ndarray:
    d = np.linspace(500, 3000, 6 * 8, dtype=np.float32).reshape(6, 8)
    d[0, 0] = 0
    return d


def test_colour_coded_depth_without_an_image() -> None:
    d = _depth()
    np.testing.assert_array_equal(color_for_depth(d), colorize_depth(d))
    np.testing.assert_array_equal(
        color_for_depth(d, vmin_mm=600, vmax_mm=2000), colorize_depth(d, 600, 2000)
    )


@pytest.mark.parametrize(
    "img",
    [
        np.full((6, 8), 7, np.uint8),
        np.full((6, 8, 4), 7, np.uint8),
        np.full((6, 8, 3), 7 << 8, np.uint16),
        np.full((3, 4, 3), 7, np.uint8),
        np.full((12, 16, 3), 7, np.uint8),
    ],
)
def test_registered_image_is_bgr_at_the_depth_size(img: np.ndarray) -> None:
    col = color_for_depth(_depth(), img)
    assert col.shape == (6, 8, 3) and col.dtype == np.uint8
    assert (col == 7).all()


@pytest.mark.parametrize(
    "img", [np.zeros((6, 8), np.float32), np.zeros((6, 8, 2), np.uint8), np.zeros((0, 8), np.uint8)]
)
def test_bad_images(img: np.ndarray) -> None:
    with pytest.raises(InputError, match="colour image"):
        color_for_depth(_depth(), img)
