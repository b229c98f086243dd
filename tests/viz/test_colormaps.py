"""OpenCV pictures: colour maps, colour bars, panel grids, atomic PNG writing."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from upsr.errors import InputError
from upsr.viz.colormaps import (
    INVALID_BGR,
    colorbar,
    colorize_depth,
    colorize_error,
    nice_ticks,
    panel_grid,
    write_png,
)


def lut(colormap: int) -> np.ndarray:
    return cv2.applyColorMap(np.arange(256, dtype=np.uint8)[None], colormap)[0]


def test_colorize_depth_range_and_invalid():
    d = np.array([[0.0, np.nan, 1000.0], [2000.0, 3000.0, 5000.0]])
    img = colorize_depth(d, 1000.0, 3000.0)
    assert img.shape == (2, 3, 3) and img.dtype == np.uint8
    turbo = lut(cv2.COLORMAP_TURBO)
    np.testing.assert_array_equal(img[0, 0], INVALID_BGR)
    np.testing.assert_array_equal(img[0, 1], INVALID_BGR)
    np.testing.assert_array_equal(img[0, 2], turbo[0])  # vmin
    np.testing.assert_array_equal(img[1, 1], turbo[255])  # vmax
    np.testing.assert_array_equal(img[1, 2], turbo[255])  # clipped
    np.testing.assert_array_equal(img[1, 0], turbo[128])  # middle
    # no valid depth is ever drawn in the invalid colour
    assert not (turbo == np.array(INVALID_BGR)).all(axis=1).any()


def test_colorize_depth_automatic_range():
    d = np.linspace(1000, 2000, 100).reshape(10, 10)
    d[0, 0] = 0
    img = colorize_depth(d)
    assert (img[0, 0] == INVALID_BGR).all()
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 20


def test_colorize_error():
    e = np.array([[0.0, -50.0, 50.0, 1e6, np.nan]])
    img = colorize_error(e, 100.0)
    viridis = lut(cv2.COLORMAP_VIRIDIS)
    np.testing.assert_array_equal(img[0, 0], viridis[0])
    np.testing.assert_array_equal(img[0, 1], img[0, 2])  # magnitude
    np.testing.assert_array_equal(img[0, 3], viridis[255])
    np.testing.assert_array_equal(img[0, 4], INVALID_BGR)
    assert not (viridis == np.array(INVALID_BGR)).all(axis=1).any()


def test_colorize_bad_input():
    with pytest.raises(InputError, match="vmin"):
        colorize_depth(np.ones((2, 2)), 10.0, 10.0)
    with pytest.raises(InputError, match="2-D"):
        colorize_depth(np.ones((2, 2, 2)), 0.0, 1.0)
    with pytest.raises(InputError):
        colorize_error(np.ones((2, 2)), 0.0)


def test_nice_ticks():
    np.testing.assert_allclose(nice_ticks(1000, 3000, 5), [1000, 1500, 2000, 2500, 3000])
    t = nice_ticks(1234, 2987, 5)
    assert (t >= 1234).all() and (t <= 2987).all() and 3 <= len(t) <= 7
    np.testing.assert_allclose(nice_ticks(0, 100, 5), [0, 25, 50, 75, 100])


def test_colorbar():
    bar = colorbar(200, 1000.0, 3000.0, "mm")
    assert bar.shape[0] == 200 and bar.dtype == np.uint8 and bar.ndim == 3
    assert 30 < bar.shape[1] < 200
    turbo = lut(cv2.COLORMAP_TURBO)
    # the bar column: far (vmax) colour at the top, near (vmin) at the bottom
    col = bar[:, 10].astype(int)
    top = col[30]
    bottom = col[190]
    assert np.abs(top - turbo[250]).sum() < np.abs(top - turbo[5]).sum()
    assert np.abs(bottom - turbo[5]).sum() < np.abs(bottom - turbo[250]).sum()
    # tick labels: dark text pixels to the right of the bar
    assert (bar[:, 25:].sum(axis=2) < 200).sum() > 50
    with pytest.raises(InputError, match="height_px"):
        colorbar(10, 0.0, 1.0)
    with pytest.raises(InputError, match="vmin"):
        colorbar(100, 2.0, 1.0)


def test_panel_grid_upscales_small_panels_blockwise():
    small = np.zeros((12, 16, 3), np.uint8)
    small[::2, ::2] = (0, 0, 255)
    big = np.full((48, 64, 3), 128, np.uint8)
    grey = np.full((24, 32), 200, np.uint8)
    grid = panel_grid(
        [("low-res", small), ("high-res", big), ("grey", grey)], title_height_px=20, gap_px=5
    )
    assert grid.dtype == np.uint8 and grid.shape == (20 + 48, 64 + 5 + 64 + 5 + 64, 3)
    # the small panel is enlarged x4 by replication: blocky, not interpolated
    expected = cv2.resize(small, (64, 48), interpolation=cv2.INTER_NEAREST)
    np.testing.assert_array_equal(grid[20:, :64], expected)
    np.testing.assert_array_equal(grid[20:, 69:133], big)
    assert (grid[20:, 138:] == 200).all()
    # titles are drawn: some dark pixels in the title strip
    assert (grid[:20].sum(axis=2) < 300).any()


def test_panel_grid_min_height_and_rows():
    a = np.full((10, 10, 3), 50, np.uint8)
    grid = panel_grid(
        [("a", a), ("b", a), ("c", a)], ncols=2, min_height_px=35, title_height_px=10, gap_px=2
    )
    # k = 3 (3·10 <= 35), 2 rows
    assert grid.shape == (2 * (10 + 30) + 2, 30 + 2 + 30, 3)


def test_panel_grid_bad_input():
    with pytest.raises(InputError, match="at least one"):
        panel_grid([])
    with pytest.raises(InputError, match="uint8"):
        panel_grid([("f", np.zeros((4, 4), np.float32))])
    with pytest.raises(InputError, match="pair"):
        panel_grid([np.zeros((4, 4), np.uint8)])


def test_write_png_atomic_roundtrip(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (20, 30, 3), dtype=np.uint8)
    path = tmp_path / "sub" / "x.png"
    assert write_png(path, img) == path
    np.testing.assert_array_equal(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), img)
    img2 = img[::-1].copy()
    write_png(path, img2)  # overwrite
    np.testing.assert_array_equal(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), img2)
    assert [p.name for p in path.parent.iterdir()] == ["x.png"]  # no temporary left
    d16 = (rng.random((5, 6)) * 5000).astype(np.uint16)
    write_png(tmp_path / "d.png", d16)
    np.testing.assert_array_equal(cv2.imread(str(tmp_path / "d.png"), cv2.IMREAD_UNCHANGED), d16)


def test_write_png_bad_input_leaves_nothing(tmp_path):
    with pytest.raises(InputError, match="uint8 or uint16"):
        write_png(tmp_path / "f.png", np.zeros((4, 4), np.float32))
    with pytest.raises(InputError, match="image"):
        write_png(tmp_path / "f.png", np.zeros((4, 4, 2), np.uint8))
    assert list(tmp_path.iterdir()) == []
