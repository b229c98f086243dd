"""upsr.io.units: depth scales, plausible depth ranges, TUM and SUN RGB-D detection, output
capacity."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import upsr.io as uio
from tests.io._frames import NAMES, _png_folder
from upsr.errors import InputError
from upsr.io.units import DepthUnitWarning


def test_resolve_depth_scales() -> None:
    assert uio.resolve_depth_scales() == (1000.0, 1000.0)
    assert uio.resolve_depth_scales(depth_scale=1) == (1.0, 1000.0)  # input only
    assert uio.resolve_depth_scales(input_depth_scale=5000, output_depth_scale=1) == (5000.0, 1.0)
    with pytest.raises(InputError, match="disagree"):
        uio.resolve_depth_scales(depth_scale=1, input_depth_scale=1000)
    with pytest.raises(InputError):
        uio.resolve_depth_scales(output_depth_scale=0)
    # km to nm: beyond, a float32 TIFF/EXR output was all inf (1e40) or all 0 (1e-50)
    assert uio.resolve_depth_scales(input_depth_scale=1e-3, output_depth_scale=1e9) == (1e-3, 1e9)
    for bad in (1e40, 1e-50, float("nan"), float("inf")):
        with pytest.raises(InputError, match=r"0\.001\.\.1e\+09 raw units per metre"):
            uio.resolve_depth_scales(output_depth_scale=bad)


def test_depth_range_metres_read_as_mm() -> None:
    metres = np.full((10, 10), 2.6, np.float32)  # metres taken as mm
    with pytest.warns(DepthUnitWarning, match="input-depth-scale 1"):
        r = uio.check_depth_range(metres, name="x.png")
    assert r.outside == 1.0
    with pytest.raises(InputError, match="50–100000 mm"):
        uio.check_depth_range(metres, action="refuse")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ok = uio.check_depth_range(np.full((4, 4), 1500.0), sensor="realsense")
    assert ok.message is None and ok.median_mm == 1500
    far = uio.check_depth_range(np.full((4, 4), 150_000.0), action="ignore")
    assert "0.1 mm (--input-depth-scale 10000)" in far.message
    with pytest.raises(InputError, match="unknown sensor"):
        uio.check_depth_range(metres, sensor="sonar")


def test_depth_range_mm_read_as_metres_is_told_mm() -> None:
    mm = np.full((10, 10), 1860.0, np.float32)  # raw mm given --input-depth-scale 1
    r = uio.check_depth_range(mm * 1000, depth_scale=1.0, action="ignore")
    assert "look like mm (--input-depth-scale 1000)" in r.message  # (not cm: 18.6 m)
    r = uio.check_depth_range(mm * 1000, action="ignore")  # (at 1000 mm is the reading)
    assert "mm (--input-depth-scale 1000)" not in r.message


@pytest.mark.parametrize("suffix", [".npy", ".npz", "tif"])
def test_metres_are_read_as_the_same_mm(tmp_path: Path, suffix: str) -> None:
    """Metres (float64) times 1000 rounded once: 2.021 m is 2021 mm, as the same depth in mm
    reads (the float32 product 2020.9999 was another input: outputs differed by up to 17 mm)."""
    mm = np.array([[[2021, 1999, 3333, 0], [4097, 1013, 2179, 65535]]], np.uint16)
    metres = mm / 1000.0
    path = tmp_path / f"m{suffix}"
    if suffix == ".npy":
        np.save(path, metres)
    elif suffix == ".npz":
        np.savez(path, depth=metres)
    else:
        import tifffile

        path.mkdir()
        tifffile.imwrite(path / "000.tif", metres[0])
    np.testing.assert_array_equal(uio.read_video(path, depth_scale=1), mm.astype(np.float32))
    units = tmp_path / "units.npy"  # 0.1 mm units (10000 per metre)
    raw = mm.astype(np.int64) * 10 + 3 * (mm > 0)
    np.save(units, raw)
    np.testing.assert_array_equal(
        uio.read_video(units, depth_scale=10000), (raw * 0.1).astype(np.float32)
    )


def test_detect_tum_scale(tmp_path: Path) -> None:
    y, x = np.mgrid[0:6, 0:8]
    tum_raw = (5000 * (1.0 + 0.3 * x + 0.1 * y)).astype(np.uint16)  # 1–3.4 m at 5000/m
    folder = _png_folder(tmp_path / "depth", np.stack([tum_raw] * 3), NAMES)
    msg = uio.detect_tum_scale(folder, tum_raw)
    assert msg is not None and "--input-format tum" in msg and "TUM timestamp names" in msg
    plain = _png_folder(tmp_path / "plain", np.stack([tum_raw] * 3), ["a", "b", "c"])
    assert uio.detect_tum_scale(plain, tum_raw) is None  # plausible as mm, no TUM names
    assert uio.detect_tum_scale(plain, (tum_raw // 5).astype(np.uint16)) is None
    far = np.full((4, 4), 30000, np.uint16)
    assert "the values" in uio.detect_tum_scale(plain, far)
    # a desk 0.8-1.9 m away (raw 4000-9500, below the far range) in a TUM sequence's layout
    # (timestamp names, depth.txt beside): read as mm without a word, 5 times too deep
    desk = (4000 + 800 * x).astype(np.uint16)
    assert uio.detect_tum_scale(folder, desk) is None  # the names alone: could be mm
    (tmp_path / "depth.txt").write_text("# depth maps\n")
    msg = uio.detect_tum_scale(folder, desk)
    assert msg is not None and "TUM timestamp names" in msg


def test_detect_sun_packing() -> None:
    y, x = np.mgrid[0:12, 0:16]
    mm = (1000 + 37 * x + 11 * y).astype(np.uint16)  # 1.0–1.7 m, not multiples of 8
    packed = ((mm.astype(np.uint32) << 3) | (mm >> 13)).astype(np.uint16)  # SUN RGB-D
    msg = uio.detect_sun_packing("d.png", packed)
    assert msg is not None and msg.startswith("d.png: use --input-format sun")
    assert "median 1.34 m unpacked" in msg
    assert uio.detect_sun_packing("d.png", mm) is None  # plain mm
    assert uio.detect_sun_packing("d.png", packed[:5, :5]) is None  # too few values
    assert uio.detect_sun_packing("d.png", packed * 0 + 8) is None  # 1 mm unpacked: no camera
    assert uio.detect_sun_packing("d.png", packed * 0 + 8 * 1500) is None  # constant: unknown
    noisy = packed.copy()
    noisy[::2] += 1  # half of them no multiple of 8
    assert uio.detect_sun_packing("d.png", noisy) is None


def test_check_output_capacity(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"single \.exr file holds one frame"):
        uio.check_output_capacity(tmp_path / "x.exr", 3)
    uio.check_output_capacity(tmp_path / "x.exr", 1)
    uio.check_output_capacity(tmp_path / "frames", 3, fmt="exr")
    uio.check_output_capacity(tmp_path / "pngs", 3, max_depth_mm=60_000)
    with pytest.raises(InputError, match="output-depth-scale 655"):
        uio.check_output_capacity(tmp_path / "pngs", 3, max_depth_mm=10_000, depth_scale=10_000)
    uio.check_output_capacity(tmp_path / "x.npy", 5, max_depth_mm=1e9)
    # whole metres in a 16-bit PNG: the depth rounded away (a float format keeps it)
    with pytest.raises(InputError, match="steps of 1000 mm: use 100 or more"):
        uio.check_output_capacity(tmp_path / "pngs", 3, depth_scale=1.0)
    uio.check_output_capacity(tmp_path / "pngs", 3, depth_scale=100.0)  # (cm)
    uio.check_output_capacity(tmp_path / "x.tif", 3, depth_scale=1.0)
