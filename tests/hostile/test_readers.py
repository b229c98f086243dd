"""Hostile inputs to the readers: bombs, special files, Fortran order, truncation, huge
member lists, absurd depths, deeply nested JSON. Each gives one InputError line, up front."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest

from upsr import io
from upsr.errors import InputError
from upsr.io import _base

from .conftest import assert_one_line, npy_header_bytes, png_bomb


def _peak_mb(fn) -> float:
    tracemalloc.start()
    try:
        fn()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak / 2**20


def test_png_bomb_refused_from_header(tmp_path: Path) -> None:
    bomb = png_bomb(tmp_path / "bomb.png", 16000, 16000)
    assert bomb.stat().st_size < 1_000_000

    def read() -> None:
        with pytest.raises(InputError, match="needs ~") as e:
            next(io.iter_frames(bomb))
        assert_one_line(e)

    assert _peak_mb(read) < 50


def test_frame_budget_is_a_parameter(tmp_path: Path) -> None:
    p = png_bomb(tmp_path / "f.png", 64, 64)
    _base.set_frame_budget(1000)
    try:
        with pytest.raises(InputError, match="per-frame limit"):
            io.probe(p)
    finally:
        _base.set_frame_budget(None)
    assert io.probe(p).shape == (1, 64, 64)
    assert 64 << 20 <= _base.frame_budget() <= 1 << 30


def test_npz_member_declaring_huge_frames(tmp_path: Path) -> None:
    p = tmp_path / "bomb.npz"
    with zipfile.ZipFile(p, "w", zipfile.ZIP_DEFLATED) as zf, zf.open("a.npy", "w") as m:
        m.write(npy_header_bytes((2, 16000, 16000), "<f8"))
        for _ in range(64):
            m.write(bytes(1 << 20))
    with pytest.raises(InputError, match="needs ~") as e:
        io.probe(p)
    assert_one_line(e)


def test_npy_header_declaring_huge_shape(tmp_path: Path) -> None:
    p = tmp_path / "bomb.npy"
    p.write_bytes(npy_header_bytes((10**12, 16000, 16000)) + bytes(100))
    with pytest.raises(InputError) as e:
        next(io.iter_frames(p))
    assert_one_line(e)


def test_fortran_npz_refused_when_over_budget(tmp_path: Path) -> None:
    p = tmp_path / "f.npz"
    with zipfile.ZipFile(p, "w", zipfile.ZIP_DEFLATED) as zf, zf.open("a.npy", "w") as m:
        m.write(npy_header_bytes((4000, 480, 640), "<f4", fortran=True))
        for _ in range(8):
            m.write(bytes(1 << 20))

    def read() -> None:
        with pytest.raises(InputError, match="Fortran") as e:
            next(io.iter_frames(p))
        assert_one_line(e)

    assert _peak_mb(read) < 50


def test_fortran_npy_small_read_frame_by_frame(tmp_path: Path) -> None:
    v = np.asfortranarray(np.arange(1, 3 * 4 * 5 + 1, dtype=np.float32).reshape(3, 4, 5))
    np.save(tmp_path / "f.npy", v)
    np.savez(tmp_path / "f.npz", depth=v)
    for name in ("f.npy", "f.npz"):
        np.testing.assert_array_equal(io.read_video(tmp_path / name), v)


@pytest.mark.parametrize("kind", ["fifo", "socket", "chardev"])
def test_special_files_refused_by_type(
    tmp_path: Path, kind: str, request: pytest.FixtureRequest
) -> None:
    if kind == "fifo":
        p = tmp_path / "in.npz"
        os.mkfifo(p)
    elif kind == "socket":
        p = tmp_path / "s.npy"
        s = socket.socket(socket.AF_UNIX)
        s.bind(str(p))
        request.addfinalizer(s.close)
    else:
        p = tmp_path / "zero.npz"
        p.symlink_to("/dev/zero")
    code = (
        "import sys\nfrom upsr import io\nfrom upsr.errors import InputError\n"
        "try:\n    io.probe(sys.argv[1])\nexcept InputError as e:\n    print('IE', e)\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    r = subprocess.run(
        [sys.executable, "-c", code, str(p)], capture_output=True, text=True, timeout=20, env=env
    )
    assert r.stdout.startswith("IE"), (r.stdout, r.stderr[-500:])
    assert "refusing to read" in r.stdout


@pytest.mark.parametrize("suffix", [".png", ".tif", ".exr"])
@pytest.mark.parametrize("kind", ["broken link", "fifo", "device"])
def test_a_folder_frame_that_is_no_regular_file_is_refused(
    tmp_path: Path, suffix: str, kind: str
) -> None:
    """Frames 0, 1, 2 where 1 is a broken link, a pipe or a link to a device: it was skipped
    (2 frames, the second a frame late) without a word."""
    folder = tmp_path / "frames"
    folder.mkdir()
    odd = folder / f"1{suffix}"
    if kind == "broken link":
        odd.symlink_to(folder / "gone")
    elif kind == "fifo":
        os.mkfifo(odd)
    else:
        odd.symlink_to("/dev/zero")
    fmt = {".png": None, ".tif": "tiff", ".exr": "exr"}[suffix]
    with pytest.raises(InputError, match=f"1{suffix}: a frame of this folder is") as e:
        io.probe(folder, fmt=fmt)
    assert_one_line(e)


def test_a_truncated_multi_page_tiff_is_refused(tmp_path: Path, capfd) -> None:
    """Cut in half, a 6-page TIFF read as a 1-frame video (tifffile logged the lost pages on
    stderr and read what it found)."""
    tifffile = pytest.importorskip("tifffile")
    whole = tmp_path / "whole.tif"
    tifffile.imwrite(whole, np.full((6, 40, 48), 1500, np.uint16))
    cut = tmp_path / "cut.tif"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
    with pytest.raises(InputError, match=r"cut\.tif: corrupt or truncated TIFF") as e:
        io.probe(cut)
    assert_one_line(e)
    assert capfd.readouterr().err == ""
    assert io.probe(whole).n_frames == 6


def test_a_truncated_bag_message_names_the_bag_and_the_message(tmp_path: Path) -> None:
    import shutil
    import sqlite3

    bag = tmp_path / "cut.db3"
    shutil.copy(Path(__file__).parents[1] / "io" / "data" / "realsense" / "rs259_1mm.db3", bag)
    with sqlite3.connect(bag) as db:
        db.execute(
            "update messages set data = substr(data, 1, length(data) / 2) where topic_id in "
            "(select id from topics where name like '%Depth%image/data%')"
        )
    with pytest.raises(
        InputError, match=r"cut\.db3 /device_0/.*Depth.* message 0: message trunc"
    ) as e:
        list(io.iter_frames(bag))
    assert_one_line(e)


def test_npy_truncated_while_read_no_sigbus(tmp_path: Path) -> None:
    p = tmp_path / "v.npy"
    np.save(p, np.full((20, 64, 64), 500.0, np.float32))
    frames = io.iter_frames(p)
    next(frames)
    os.truncate(p, 128 + 3 * 64 * 64 * 4)  # the file shrinks while it is read
    with pytest.raises(InputError, match="truncated") as e:
        for _ in frames:
            pass
    assert_one_line(e)


def test_npz_error_listing_many_members_is_one_short_line(tmp_path: Path) -> None:
    p = tmp_path / "many.npz"
    np.savez(p, **{f"member_with_a_long_name_{i:06d}": np.zeros(1) for i in range(3000)})
    with pytest.raises(InputError, match="more") as e:
        io.probe(p, key="nope")
    assert_one_line(e)


@pytest.mark.parametrize("value", [1e38, 3e38, 1e39, 2e6])
def test_absurd_depths_name_the_frame(tmp_path: Path, value: float) -> None:
    v = np.full((3, 8, 6), 1000.0, np.float64)
    v[1, 2, 3] = value
    np.save(tmp_path / "v.npy", v)
    with pytest.raises(InputError, match="frame 1") as e:
        io.read_video(tmp_path / "v.npy")
    assert "1 km" in assert_one_line(e)


def test_deeply_nested_intrinsics_json(tmp_path: Path) -> None:
    from upsr.geometry.intrinsics import load_intrinsics

    p = tmp_path / "v.npy.intrinsics.json"
    p.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(InputError) as e:
        load_intrinsics(p)
    assert_one_line(e)


@pytest.mark.parametrize(
    "text",
    [
        '{"width": 1e400, "height": 96, "fx": 1, "fy": 1, "cx": 0, "cy": 0}',  # inf size
        '{"width": 8, "height": 6, "intrinsic_matrix": [NaN, 0, 0, 0, 1, 0, 0, 0, 1]}',
        '{"width": 8, "height": 6, "intrinsic_matrix": [1, 0, 0]}',
        '{"width": 8, "height": 6, "intrinsic_matrix": 5}',
    ],
)
def test_hostile_intrinsics_json_is_one_line(tmp_path: Path, text: str) -> None:
    from upsr.geometry.intrinsics import load_intrinsics

    p = tmp_path / "cam.json"
    p.write_text(text)
    with pytest.raises(InputError) as e:
        load_intrinsics(p)
    assert_one_line(e)
