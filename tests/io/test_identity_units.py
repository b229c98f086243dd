"""Frame identity (names, timestamps), units checks and colour resampling (issue 15)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

import upsr.io as uio
from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.intrinsics import load_intrinsics, write_intrinsics
from upsr.io.identity import first_step_back
from upsr.io.units import DepthUnitWarning

cv2 = pytest.importorskip("cv2")

NAMES = ["1305031102.175304", "1305031102.211214", "1305031102.243211"]


def _png_folder(path: Path, frames: np.ndarray, names: list[str]) -> Path:
    path.mkdir()
    for f, n in zip(frames, names, strict=True):
        cv2.imwrite(str(path / f"{n}.png"), f.astype(np.uint16))
    return path


def _video(t: int = 3) -> np.ndarray:
    return np.stack([np.full((6, 8), 1000.0 + 10 * k, np.float32) for k in range(t)])


def test_png_folder_keeps_frame_names_and_stamps(tmp_path: Path) -> None:
    inp = _png_folder(tmp_path / "depth", _video(), NAMES)
    names = uio.read_frame_names(inp)
    assert names == NAMES
    stamps = uio.read_timestamps(inp)
    assert stamps[0] == 1305031102_175304000
    out = uio.write_video(tmp_path / "out", uio.read_video(inp), frame_names=names)
    assert sorted(p.stem for p in out.iterdir()) == NAMES
    np.testing.assert_array_equal(uio.read_video(out), _video())
    assert uio.read_frame_names(tmp_path / "out.npy" if False else out) == NAMES


def test_exr_folder_keeps_names(tmp_path: Path) -> None:
    pytest.importorskip("OpenEXR")
    out = uio.write_video(tmp_path / "exr", _video(), fmt="exr", frame_names=["a", "b", "c"])
    assert sorted(p.name for p in out.iterdir()) == ["a.exr", "b.exr", "c.exr"]


def test_frame_names_checked(tmp_path: Path) -> None:
    for bad in (["a", "a", "b"], ["a", "../b", "c"], ["a", ".b", "c"], ["a", "b"]):
        with pytest.raises(InputError):
            uio.write_video(tmp_path / "o", _video(), frame_names=bad)
    assert not (tmp_path / "o").exists()
    # names that are also the default ones, shuffled, do not collide
    out = uio.write_video(tmp_path / "p", _video(), frame_names=["000001", "000002", "000000"])
    np.testing.assert_array_equal(uio.read_video(out)[0], _video()[2])


def test_npz_timestamps_round_trip(tmp_path: Path) -> None:
    stamps = np.array([10, 20, 35], np.int64) * 10**6
    out = uio.write_video(tmp_path / "o.npz", _video(), timestamps_ns=stamps)
    np.testing.assert_array_equal(uio.read_timestamps(out), stamps)
    np.testing.assert_array_equal(uio.read_video(out), _video())
    with np.load(out) as z:
        assert z["timestamps"].dtype == np.int64
    assert uio.read_timestamps(uio.write_video(tmp_path / "n.npz", _video())) is None
    # a camera clock that goes back (a reset): kept as recorded (it was refused)
    back = uio.write_video(tmp_path / "b.npz", _video(), timestamps_ns=[30, 40, 10])
    np.testing.assert_array_equal(uio.read_timestamps(back), [30, 40, 10])
    assert first_step_back([30, 40, 10]) == 2 and first_step_back([1, 1, 2]) is None
    with pytest.raises(InputError, match="timestamps"):
        uio.write_video(tmp_path / "c.npz", _video(), timestamps_ns=[1, 2])
    assert not (tmp_path / "c.npz").exists()


def test_intrinsics_json_carries_stamps_names(tmp_path: Path) -> None:
    cam = PinholeCamera(100.0, 101.0, 63.5, 47.5, 128, 96)
    p = write_intrinsics(
        tmp_path / "o.npy.intrinsics.json", cam, timestamps_ns=[5, 6], frame_names=["x", "y"]
    )
    d = json.loads(p.read_text())
    assert d["timestamps_ns"] == [5, 6] and d["frame_names"] == ["x", "y"]
    assert d["intrinsic_matrix"] == [100.0, 0.0, 0.0, 0.0, 101.0, 0.0, 63.5, 47.5, 1.0]
    assert load_intrinsics(p) == cam
    np.save(tmp_path / "o.npy", _video(2))
    np.testing.assert_array_equal(uio.read_timestamps(tmp_path / "o.npy"), [5, 6])


def test_frame_counters_are_not_times_and_the_sidecar_wins(tmp_path: Path) -> None:
    """``000000.png`` (upsr's own folder names) counts frames: no times of 0, 1, 2 s; the
    times upsr wrote beside such a folder are those read back (before: the names won)."""
    counted = _png_folder(tmp_path / "counted", _video(), ["000000", "000001", "000002"])
    assert uio.read_timestamps(counted) is None
    cam = PinholeCamera(100.0, 101.0, 3.5, 2.5, 8, 6)
    write_intrinsics(tmp_path / "counted.intrinsics.json", cam, timestamps_ns=[0, 33, 67])
    np.testing.assert_array_equal(uio.read_timestamps(counted), [0, 33, 67])
    tum = _png_folder(tmp_path / "tum", _video(), NAMES)
    write_intrinsics(tmp_path / "tum.intrinsics.json", cam, timestamps_ns=[1, 2, 3])
    np.testing.assert_array_equal(uio.read_timestamps(tum), [1, 2, 3])


# ---------------------------------------------------------------------------------------------
# units
# ---------------------------------------------------------------------------------------------
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


# ---------------------------------------------------------------------------------------------
# colour
# ---------------------------------------------------------------------------------------------
def test_resample_color_geometry() -> None:
    img = np.zeros((4, 6, 3), np.uint8)
    img[:, :, 1] = np.arange(6, dtype=np.uint8)[None, :] * 40
    out = uio.resample_color(img, (8, 12))
    assert out.shape == (8, 12, 3) and out.dtype == np.uint8
    # SPEC §1: output column j' sits at input x = (j' + 0.5)/2 - 0.5
    j = np.arange(12)
    expect = np.clip((j + 0.5) / 2 - 0.5, 0, 5) * 40
    np.testing.assert_allclose(out[3, :, 1], expect, atol=1)
    grey16 = np.arange(12, dtype=np.uint16).reshape(3, 4) * 1000
    assert uio.resample_color(grey16, (6, 8)).dtype == np.uint16
    assert uio.resample_color(img, (2, 3)).shape == (2, 3, 3)


def test_write_color_folder(tmp_path: Path) -> None:
    src = tmp_path / "rgb"
    src.mkdir()
    for n in NAMES:
        cv2.imwrite(str(src / f"{n}.jpg"), np.full((6, 8, 3), 77, np.uint8))
    out = uio.write_color(src, tmp_path / "o.color", (12, 16), n_frames=3)
    assert sorted(p.name for p in out.iterdir()) == [f"{n}.png" for n in NAMES]
    assert cv2.imread(str(out / f"{NAMES[0]}.png")).shape == (12, 16, 3)
    with pytest.raises(InputError, match="already exists"):
        uio.write_color(src, out, (12, 16))
    with pytest.raises(InputError, match="3 colour image"):
        uio.write_color(src, tmp_path / "p", (12, 16), n_frames=4)
    assert not (tmp_path / "p").exists()
    one = uio.write_color(src / f"{NAMES[1]}.jpg", tmp_path / "q", (3, 4), frame_names=["f"])
    assert [p.name for p in one.iterdir()] == ["f.png"]
