"""upsr.io.identity: frame names and timestamps, read and written."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import upsr.io as uio
from tests.io._frames import NAMES, _png_folder, _video
from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.geometry.intrinsics import write_intrinsics
from upsr.io.identity import first_step_back


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
