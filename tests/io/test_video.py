"""Depth video I/O: formats, round trips, validation, safety, atomicity, fuzzing."""

from __future__ import annotations

import contextlib
import io as pyio
import os
import pathlib
import pickle
import shutil
import tempfile
import warnings
import zipfile
from datetime import timedelta
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from upsr.errors import InputError
from upsr.io import video as io

T, H, W = 5, 12, 16


def video(seed: int = 0, t: int = T, h: int = H, w: int = W) -> np.ndarray:
    """Integer-valued mm depths (exact in float32 and in 16-bit PNG)."""
    rng = np.random.default_rng(seed)
    v = rng.integers(400, 5000, size=(t, h, w)).astype(np.float32)
    v[:, 0, 0] = 0  # one invalid pixel per frame
    return v


def write_png(path: Path, img: np.ndarray) -> Path:
    ok, buf = cv2.imencode(".png", img)
    assert ok
    path.write_bytes(buf.tobytes())
    return path


def png_folder(folder: Path, v: np.ndarray, names: list[str] | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    names = names or [f"{i:04d}.png" for i in range(len(v))]
    for name, frame in zip(names, v, strict=False):
        write_png(folder / name, frame.astype(np.uint16))
    return folder


def listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


# ---------------------------------------------------------------------------------------------
# round trips
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["v.npy", "v.npz", "frames", "a/b/v.npy", "a/b/frames"])
def test_round_trip(tmp_path: Path, name: str) -> None:
    v = video()
    out = tmp_path / name
    assert io.write_video(out, v) == out
    info = io.probe(out)
    assert info.shape == v.shape
    assert info.format == {"npy": "npy", "npz": "npz"}.get(out.suffix[1:], "png")
    back = io.read_video(out)
    assert back.dtype == np.float32 and back.shape == v.shape
    np.testing.assert_array_equal(back, v)
    frames = list(io.iter_frames(out))
    assert len(frames) == T and all(f.dtype == np.float32 and f.shape == (H, W) for f in frames)
    # nothing else was left next to the output
    assert [p.name for p in out.parent.iterdir()] == [out.name]


def test_npz_written_with_key_depth_and_readable_by_numpy(tmp_path: Path) -> None:
    v = video()
    io.write_video(tmp_path / "v.npz", v)
    with np.load(tmp_path / "v.npz", allow_pickle=False) as z:
        assert z.files == ["depth"]
        np.testing.assert_array_equal(z["depth"], v)
    np.testing.assert_array_equal(np.load(tmp_path / "v.npz")["depth"], v)


def test_npy_written_is_standard(tmp_path: Path) -> None:
    v = video()
    io.write_video(tmp_path / "v.npy", iter(v))  # unknown length: still streamed
    a = np.load(tmp_path / "v.npy", allow_pickle=False)
    assert a.dtype == np.float32 and a.shape == v.shape
    np.testing.assert_array_equal(a, v)


def test_png_depth_scale_and_values(tmp_path: Path) -> None:
    raw = np.array([[[0, 1, 5000, 65535]]], np.uint16)
    png_folder(tmp_path / "tum", raw)
    mm = io.read_video(tmp_path / "tum", depth_scale=5000)
    np.testing.assert_allclose(mm[0, 0], [0, 0.2, 1000, 13107], rtol=1e-6)
    assert io.read_video(tmp_path / "tum")[0, 0, 2] == 5000  # default: mm
    io.write_video(tmp_path / "out", mm, depth_scale=5000)
    back = cv2.imread(str(tmp_path / "out" / "000000.png"), cv2.IMREAD_UNCHANGED)
    assert back.dtype == np.uint16
    np.testing.assert_array_equal(back, raw[0])


def test_png_writer_clips_with_one_warning_and_keeps_validity(tmp_path: Path) -> None:
    v = np.full((3, 2, 2), 1000, np.float32)
    v[:, 0, 0] = 70000  # does not fit 16 bits in mm
    v[:, 0, 1] = 0.2  # a tiny but valid depth must not become "no measurement"
    v[:, 1, 1] = 0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        io.write_video(tmp_path / "out", v)
    assert len(caught) == 1 and "clipped" in str(caught[0].message)
    back = io.read_video(tmp_path / "out")
    assert (back[:, 0, 0] == 65535).all() and (back[:, 0, 1] == 1).all()
    assert (back[:, 1, 1] == 0).all()


def test_nan_is_no_measurement_and_empty_middle_frame_is_fine(tmp_path: Path) -> None:
    v = video()
    v[1, 2, 3] = np.nan
    v[2] = 0
    np.save(tmp_path / "v.npy", v)
    back = io.read_video(tmp_path / "v.npy")
    assert back[1, 2, 3] == 0 and (back[2] == 0).all()


@pytest.mark.parametrize("dtype", ["<u2", ">u2", "<f8", ">f4", "<i4", "<f2", "u1"])
@pytest.mark.parametrize("suffix", [".npy", ".npz"])
def test_numeric_dtypes_byte_orders_and_fortran(tmp_path: Path, dtype: str, suffix: str) -> None:
    v = video().clip(0, 255 if dtype == "u1" else None).astype(dtype)
    for order in ("C", "F"):
        a = np.asarray(v, order=order)
        p = tmp_path / f"v{order}{suffix}"
        np.save(p, a) if suffix == ".npy" else np.savez(p, a)
        assert io.probe(p).dtype == np.dtype(dtype)
        np.testing.assert_array_equal(io.read_video(p), v.astype(np.float32))


def test_npz_first_array_or_key(tmp_path: Path) -> None:
    a, b = video(1), video(2)
    np.savez(tmp_path / "v.npz", first=a, second=b)
    np.testing.assert_array_equal(io.read_video(tmp_path / "v.npz"), a)
    np.testing.assert_array_equal(io.read_video(tmp_path / "v.npz", key="second"), b)
    assert io.probe(tmp_path / "v.npz", key="second").key == "second"
    with pytest.raises(InputError, match=r"no array named 'third'.*first, second"):
        io.probe(tmp_path / "v.npz", key="third")
    with pytest.raises(InputError, match=r"only applies to \.npz"):
        io.probe(tmp_path / "v.npz", key="first", fmt="npy")


def test_npz_without_key_reads_depth_else_the_first_video(tmp_path: Path) -> None:
    a, b = video(1), video(2)
    # a camera's times first, then its frames (a user's archive): the video, not the times
    np.savez(tmp_path / "t.npz", timestamps=np.arange(a.shape[0]), frames=a)
    np.testing.assert_array_equal(io.read_video(tmp_path / "t.npz"), a)
    assert io.probe(tmp_path / "t.npz").key == "frames"
    np.savez(tmp_path / "d.npz", first=a, depth=b)  # (the name upsr writes wins)
    np.testing.assert_array_equal(io.read_video(tmp_path / "d.npz"), b)
    np.savez(tmp_path / "none.npz", timestamps=np.arange(3), names=np.zeros((3, 2)))
    with pytest.raises(InputError, match=r"none\.npz\[timestamps\].*shape \(3,\)"):
        io.probe(tmp_path / "none.npz")


def test_arrays_take_a_depth_scale_and_fixed_unit_formats_refuse_one(tmp_path: Path) -> None:
    v = video()
    np.save(tmp_path / "m.npy", v / 1000.0)  # metres
    np.savez(tmp_path / "m.npz", depth=v / 1000.0)
    for name in ("m.npy", "m.npz"):
        got = io.read_video(tmp_path / name, depth_scale=1.0)
        np.testing.assert_allclose(got, v, rtol=1e-6)
        np.testing.assert_array_equal(io.read_video(tmp_path / name), (v / 1000.0).astype("f4"))
    with pytest.raises(InputError, match="does not apply to tum input"):
        list(io.iter_frames(tmp_path / "m.npy", fmt="tum", depth_scale=5000.0))


def test_fmt_override(tmp_path: Path) -> None:
    v = video()
    np.save(tmp_path / "v.npy", v)
    os.rename(tmp_path / "v.npy", tmp_path / "v.dat")
    with pytest.raises(InputError, match="unknown input format"):
        io.probe(tmp_path / "v.dat")
    np.testing.assert_array_equal(io.read_video(tmp_path / "v.dat", fmt="npy"), v)
    with pytest.raises(InputError, match="unknown format"):
        io.probe(tmp_path / "v.dat", fmt="mp4")
    io.write_video(tmp_path / "out.bin", v, fmt="npy")
    np.testing.assert_array_equal(np.load(tmp_path / "out.bin"), v)


def test_png_natural_order_and_single_file(tmp_path: Path) -> None:
    v = np.arange(1, 12, dtype=np.float32)[:, None, None] * np.ones((1, 2, 3), np.float32)
    names = [f"frame{i}.png" for i in range(1, 12)]  # frame10 sorts after frame9
    folder = png_folder(tmp_path / "f", v, names)
    (folder / "notes.txt").write_text("ignored")
    (folder / ".hidden.png").write_bytes(b"ignored")
    np.testing.assert_array_equal(io.read_video(folder), v)
    one = io.read_video(folder / "frame3.png")
    assert one.shape == (1, 2, 3) and (one == 3).all()


def test_probe_is_cheap_for_big_npy(tmp_path: Path) -> None:
    p = tmp_path / "big.npy"
    a = np.lib.format.open_memmap(p, mode="w+", dtype=np.uint16, shape=(2000, 240, 320))
    del a
    info = io.probe(p)
    assert info.shape == (2000, 240, 320)
    first = next(io.iter_frames(p))  # memory-mapped: reading one frame does not read 300 MB
    assert first.shape == (240, 320)


# ---------------------------------------------------------------------------------------------
# bad inputs
# ---------------------------------------------------------------------------------------------
def _consume(path: Path, **kw: object) -> np.ndarray:
    io.probe(path, **{k: v for k, v in kw.items() if k in ("key", "fmt")})  # type: ignore[arg-type]
    return io.read_video(path, **kw)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("array", "match"),
    [
        (np.ones((4, 5), np.float32), r"shape \(T, h, w\).*single frame"),
        (np.ones((2, 3, 4, 5), np.float32), r"shape \(T, h, w\)"),
        (np.ones((3, 4, 5), np.complex64), "numeric"),
        (np.ones((3, 4, 5), bool), "numeric"),
        (np.full((3, 4, 5), "a"), "numeric"),
        (np.ones((3, 4, 5), "datetime64[s]"), "numeric"),
        (np.zeros((0, 4, 5), np.float32), "empty"),
        (np.zeros((3, 0, 5), np.float32), "empty"),
        (np.zeros((3, 4, 5), [("a", "<f4")]), "numeric"),
    ],
)
@pytest.mark.parametrize("suffix", [".npy", ".npz"])
def test_bad_arrays(tmp_path: Path, array: np.ndarray, match: str, suffix: str) -> None:
    p = tmp_path / f"bad{suffix}"
    np.save(p, array) if suffix == ".npy" else np.savez(p, array)
    with pytest.raises(InputError, match=match):
        io.probe(p)
    with pytest.raises(InputError, match=match):
        io.iter_frames(p)  # validated when called, before any frame is read


@pytest.mark.parametrize(
    ("index", "value", "match"),
    [
        ((2, 1, 1), np.inf, r"frame 2: .*inf"),
        ((3, 0, 2), -np.inf, r"frame 3: .*inf"),
        ((1, 4, 4), -5.0, r"frame 1: .*negative"),
    ],
)
@pytest.mark.parametrize("suffix", [".npy", ".npz"])
def test_bad_depth_values_name_the_frame(
    tmp_path: Path, index: tuple[int, int, int], value: float, match: str, suffix: str
) -> None:
    v = video()
    v[index] = value
    p = tmp_path / f"v{suffix}"
    np.save(p, v) if suffix == ".npy" else np.savez(p, v)
    with pytest.raises(InputError, match=match):
        io.read_video(p)


@pytest.mark.parametrize("fill", [0.0, np.nan])
def test_all_invalid_video(tmp_path: Path, fill: float) -> None:
    np.save(tmp_path / "v.npy", np.full((3, 4, 5), fill, np.float32))
    frames = io.iter_frames(tmp_path / "v.npy")
    with pytest.raises(InputError, match="no valid depth"):
        list(frames)


def _evil_object_array(marker: Path) -> np.ndarray:
    class Evil:
        def __reduce__(self) -> tuple[object, tuple[object, ...]]:
            return (pathlib.Path.touch, (marker,))

    a = np.empty((2, 2, 2), object)
    a[...] = Evil()
    return a


@pytest.mark.parametrize("suffix", [".npy", ".npz"])
def test_object_arrays_are_never_unpickled(tmp_path: Path, suffix: str) -> None:
    marker = tmp_path / "pwned"
    p = tmp_path / f"evil{suffix}"
    a = _evil_object_array(marker)
    if suffix == ".npy":
        np.save(p, a, allow_pickle=True)
    else:
        np.savez(p, a)
    # sanity: the payload does work when unpickled
    loaded = np.load(p, allow_pickle=True)
    _ = loaded if suffix == ".npy" else loaded["arr_0"]
    assert marker.exists()
    marker.unlink()
    with pytest.raises(InputError, match="object arrays"):
        io.probe(p)
    with pytest.raises(InputError, match="object arrays"):
        io.read_video(p)
    assert not marker.exists()


def test_truncated_npy(tmp_path: Path) -> None:
    np.save(tmp_path / "v.npy", video())
    data = (tmp_path / "v.npy").read_bytes()
    for cut in (0, 5, 60, 200, len(data) - 1):
        (tmp_path / "t.npy").write_bytes(data[:cut])
        with pytest.raises(InputError):
            _consume(tmp_path / "t.npy")
    (tmp_path / "t.npy").write_bytes(data[:-1])
    with pytest.raises(InputError, match="truncated"):
        io.probe(tmp_path / "t.npy")


def test_corrupt_npz(tmp_path: Path) -> None:
    np.savez_compressed(tmp_path / "v.npz", depth=video())
    data = (tmp_path / "v.npz").read_bytes()
    for cut in (0, 10, len(data) // 2, len(data) - 30):
        (tmp_path / "t.npz").write_bytes(data[:cut])
        with pytest.raises(InputError):
            _consume(tmp_path / "t.npz")
    bad = bytearray(data)
    for i in range(60, 120):  # inside the compressed member
        bad[i] ^= 0xA5
    (tmp_path / "t.npz").write_bytes(bytes(bad))
    with pytest.raises(InputError):
        _consume(tmp_path / "t.npz")
    with zipfile.ZipFile(tmp_path / "empty.npz", "w"):
        pass
    with pytest.raises(InputError, match="no arrays"):
        io.probe(tmp_path / "empty.npz")


def test_missing_and_unreadable_inputs(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        io.probe(tmp_path / "nothere.npy")
    with pytest.raises(InputError, match="no such file"):
        io.iter_frames(tmp_path / "nothere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no PNG frames"):
        io.probe(tmp_path / "empty")
    (tmp_path / "tum" / "depth").mkdir(parents=True)
    with pytest.raises(
        InputError, match=r"give a subfolder \(depth\), or all to upsr batch .*/\*$"
    ):
        io.probe(tmp_path / "tum")
    (tmp_path / "recs").mkdir()  # a folder of recordings: it said "no PNG frames" only
    for name in ("a.npy", "b.npy"):
        np.save(tmp_path / "recs" / name, np.ones((2, 3, 4), np.float32))
    with pytest.raises(InputError, match=r"holds recordings \(a\.npy, b\.npy\).*recs/\*\.npy$"):
        io.probe(tmp_path / "recs")
    (tmp_path / "d.npy").mkdir()  # a folder is a folder of PNG frames, whatever its name
    with pytest.raises(InputError, match="no PNG frames"):
        io.probe(tmp_path / "d.npy")
    with pytest.raises(InputError, match="is a folder"):
        io.probe(tmp_path / "d.npy", fmt="npy")
    if os.geteuid() != 0:  # root reads anything
        p = tmp_path / "locked.npy"
        np.save(p, video())
        p.chmod(0)
        with pytest.raises(InputError, match="cannot read"):
            io.probe(p)


def test_png_wrong_bit_depth_and_colour(tmp_path: Path) -> None:
    cases = {
        "gray8": np.full((4, 5), 100, np.uint8),
        "rgb8": np.full((4, 5, 3), 100, np.uint8),
        "rgb16": np.full((4, 5, 3), 1000, np.uint16),
        "rgba16": np.full((4, 5, 4), 1000, np.uint16),
    }
    for name, img in cases.items():
        folder = tmp_path / name
        folder.mkdir()
        write_png(folder / "0.png", img)
        msg = "8-bit" if img.dtype == np.uint8 else "16-bit"
        with pytest.raises(InputError, match=f"{msg}.*16-bit single-channel"):
            io.probe(folder)


def test_png_mixed_sizes_name_the_file(tmp_path: Path) -> None:
    folder = png_folder(tmp_path / "f", video(t=3))
    write_png(folder / "0003.png", np.ones((H + 1, W), np.uint16))
    write_png(folder / "0004.png", np.ones((H, W + 1), np.uint16))
    with pytest.raises(InputError, match=r"0003\.png: frame size 16x13 differs .*0000\.png"):
        io.probe(folder)


def test_corrupt_and_truncated_png(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    folder = png_folder(tmp_path / "f", video(t=3))
    good = (folder / "0001.png").read_bytes()
    cases = {
        "truncated": good[: len(good) // 2],
        "no_iend": good[:-12],
        "header_only": good[:33],
        "text": b"hello, not a png",
        "empty": b"",
    }
    flipped = bytearray(good)
    flipped[60] ^= 0xFF  # inside IDAT
    cases["flipped"] = bytes(flipped)
    capfd.readouterr()
    for _name, data in cases.items():
        (folder / "0001.png").write_bytes(data)
        with pytest.raises(InputError, match=r"0001\.png"):
            _consume(folder)
    # one clear error, no libpng/OpenCV chatter on the terminal
    captured = capfd.readouterr()
    assert captured.err == "" and captured.out == ""


# ---------------------------------------------------------------------------------------------
# fuzzing: random bytes and mutated files never raise anything but InputError, never hang
# ---------------------------------------------------------------------------------------------
def _fuzz_check(data: bytes, suffix: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        if suffix == "/":  # a PNG folder with one random frame after a valid one
            folder = png_folder(Path(d) / "f", video(t=1, h=3, w=4))
            (folder / "0001.png").write_bytes(data)
            path = folder
        else:
            path = Path(d) / f"x{suffix}"
            path.write_bytes(data)
        try:
            out = _consume(path)
        except InputError:
            return
        assert out.dtype == np.float32 and out.ndim == 3


FUZZ = settings(
    max_examples=150, deadline=timedelta(seconds=5), suppress_health_check=[HealthCheck.too_slow]
)


def _valid_bytes(suffix: str) -> bytes:
    v = video(t=2, h=3, w=4)
    buf = pyio.BytesIO()
    if suffix == ".npy":
        np.save(buf, v)
    elif suffix == ".npz":
        np.savez_compressed(buf, depth=v)
    else:
        _ok, enc = cv2.imencode(".png", v[0].astype(np.uint16))
        return enc.tobytes()
    return buf.getvalue()


@FUZZ
@given(data=st.binary(max_size=600), suffix=st.sampled_from([".npy", ".npz", ".png", "/"]))
def test_fuzz_random_bytes(data: bytes, suffix: str) -> None:
    _fuzz_check(data, suffix)


@FUZZ
@given(data=st.binary(max_size=300), suffix=st.sampled_from([".npy", ".npz", ".png"]))
def test_fuzz_random_bytes_with_valid_magic(data: bytes, suffix: str) -> None:
    magic = {".npy": b"\x93NUMPY\x01\x00", ".npz": b"PK\x03\x04", ".png": b"\x89PNG\r\n\x1a\n"}
    _fuzz_check(magic[suffix] + data, suffix)


@FUZZ
@given(
    suffix=st.sampled_from([".npy", ".npz", ".png", "/"]),
    flips=st.lists(st.tuples(st.integers(0, 10_000), st.integers(1, 255)), max_size=6),
    cut=st.one_of(st.none(), st.integers(0, 10_000)),
)
def test_fuzz_mutated_valid_files(
    suffix: str, flips: list[tuple[int, int]], cut: int | None
) -> None:
    data = bytearray(_valid_bytes(".png" if suffix == "/" else suffix))
    for pos, mask in flips:
        data[pos % len(data)] ^= mask
    if cut is not None:
        data = data[: cut % (len(data) + 1)]
    _fuzz_check(bytes(data), suffix)


@FUZZ
@given(
    shape=st.lists(st.integers(0, 2**40), min_size=0, max_size=4),
    descr=st.sampled_from(["<f4", "|O", "<c8", "|b1", "<U3", ">i8", "|V4"]),
    fortran=st.booleans(),
    extra=st.binary(max_size=64),
)
def test_fuzz_npy_headers(shape: list[int], descr: str, fortran: bool, extra: bytes) -> None:
    header = {"descr": descr, "fortran_order": fortran, "shape": tuple(shape)}
    buf = pyio.BytesIO()
    np.lib.format.write_array_header_1_0(buf, header)
    _fuzz_check(buf.getvalue() + extra, ".npy")


# ---------------------------------------------------------------------------------------------
# writer: atomicity and safety
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["out.npy", "out.npz", "out", "new/sub/out.npy", "new/out"])
@pytest.mark.parametrize("exc", [RuntimeError, KeyboardInterrupt])
def test_exception_mid_write_leaves_nothing(
    tmp_path: Path, name: str, exc: type[BaseException]
) -> None:
    v = video()
    before = listing(tmp_path)
    with pytest.raises(exc), io.VideoWriter(tmp_path / name, n_frames=T) as w:
        w.write(v[0])
        w.write(v[1])
        assert listing(tmp_path) != before  # something is being written (hidden temporary)
        raise exc()
    assert listing(tmp_path) == before  # nothing left, created parent folders removed too
    assert w.closed


@pytest.mark.parametrize("name", ["out.npy", "out.npz", "out"])
def test_failed_overwrite_keeps_old_output(tmp_path: Path, name: str) -> None:
    old, new = video(1), video(2)
    io.write_video(tmp_path / name, old)
    with pytest.raises(RuntimeError), io.VideoWriter(tmp_path / name, overwrite=True) as w:
        w.write(new[0])
        raise RuntimeError
    np.testing.assert_array_equal(io.read_video(tmp_path / name), old)
    io.write_video(tmp_path / name, new[:2], overwrite=True)
    np.testing.assert_array_equal(io.read_video(tmp_path / name), new[:2])
    expected = [name] + ([f"{name}/{i:06d}.png" for i in range(2)] if name == "out" else [])
    assert listing(tmp_path) == sorted(expected)


def test_writer_frame_count_and_shape_checks(tmp_path: Path) -> None:
    v = video()
    with (
        pytest.raises(InputError, match="2 frames written, 5 expected"),
        io.VideoWriter(tmp_path / "a.npy", n_frames=T) as w,
    ):
        w.write(v[0])
        w.write(v[1])
    with (
        pytest.raises(InputError, match="more than"),
        io.VideoWriter(tmp_path / "a.npy", n_frames=1) as w,
    ):
        w.write(v[0])
        w.write(v[1])
    with pytest.raises(InputError, match="differs"), io.VideoWriter(tmp_path / "a.npy") as w:
        w.write(v[0])
        w.write(v[0, :5])
    with pytest.raises(InputError, match="no frames"), io.VideoWriter(tmp_path / "a.npy"):
        pass
    with pytest.raises(InputError, match="negative"), io.VideoWriter(tmp_path / "a.npy") as w:
        w.write(-v[0])
    with pytest.raises(InputError, match="unknown output format"):
        io.VideoWriter(tmp_path / "a.mp4")
    with pytest.raises(InputError, match="--format rosbag: a ROS 2 bag folder"):
        io.VideoWriter(tmp_path / "a.db3")
    with pytest.raises(InputError, match="depth_scale"):
        io.VideoWriter(tmp_path / "a", depth_scale=0)
    assert listing(tmp_path) == []


def test_writer_without_with_block(tmp_path: Path) -> None:
    w = io.VideoWriter(tmp_path / "a.npy")
    w.write(video()[0])
    w.close()
    w.close()  # idempotent
    assert io.probe(tmp_path / "a.npy").n_frames == 1
    with pytest.raises(ValueError, match="closed"):
        w.write(video()[0])
    w2 = io.VideoWriter(tmp_path / "b.npy")
    w2.write(video()[0])
    del w2  # garbage-collected without close: the temporary goes away
    import gc

    gc.collect()
    assert listing(tmp_path) == ["a.npy"]


def test_output_permissions_follow_umask(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        io.write_video(tmp_path / "a.npy", video())
        io.write_video(tmp_path / "f", video())
    finally:
        os.umask(old)
    assert (tmp_path / "a.npy").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "f").stat().st_mode & 0o777 == 0o755


def test_check_output_path(tmp_path: Path) -> None:
    inp = tmp_path / "data" / "in.npy"
    inp.parent.mkdir()
    np.save(inp, video())
    frames = png_folder(tmp_path / "frames", video())
    (tmp_path / "dir.npy").mkdir()

    out = tmp_path / "x" / "y" / "out.npy"
    assert io.check_output_path([inp], out) == out
    assert not (tmp_path / "x").exists()  # only checked: the writer creates the parents
    io.check_output_path(inp, inp.with_name("other.npy"))
    io.check_output_path([inp], frames, overwrite=True)  # a folder of PNGs only: replaceable

    refused = [
        ([inp], inp, "is the input"),
        (inp, tmp_path / "data" / ".." / "data" / "in.npy", "is the input"),
        ([inp], tmp_path / "data", "contains the input"),
        ([inp], tmp_path, "contains the input"),
        ([frames], frames, "is the input"),
        ([frames / "0001.png"], frames, "contains the input"),
        ([], tmp_path / "data", "other things than PNG"),
        ([], tmp_path / "dir.npy", "is a folder"),
    ]
    for inputs, output, match in refused:
        with pytest.raises(InputError, match=match):
            io.check_output_path(inputs, output, overwrite=True)
    with pytest.raises(InputError, match="already exists"):
        io.check_output_path([], frames)
    with pytest.raises(InputError, match="not a folder"):
        io.check_output_path([], inp, True, fmt="png")
    # symlink and hard link to the input
    (tmp_path / "link.npy").symlink_to(inp)
    with pytest.raises(InputError, match="is the input"):
        io.check_output_path([inp], tmp_path / "link.npy", True)
    os.link(inp, tmp_path / "hard.npy")
    with pytest.raises(InputError, match="is the input"):
        io.check_output_path([inp], tmp_path / "hard.npy", True)
    # a parent that is a file
    with pytest.raises(InputError, match="not a folder"):
        io.check_output_path([], inp / "out.npy")


def test_writer_refuses_existing_output_before_writing(tmp_path: Path) -> None:
    io.write_video(tmp_path / "a.npy", video())
    data = (tmp_path / "a.npy").read_bytes()
    with pytest.raises(InputError, match="already exists"):
        io.VideoWriter(tmp_path / "a.npy")
    assert (tmp_path / "a.npy").read_bytes() == data


def test_write_video_rejects_bad_shapes(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"\(T, h, w\)"):
        io.write_video(tmp_path / "a.npy", np.ones((4, 5), np.float32))
    with pytest.raises(InputError):
        io.write_video(tmp_path / "a.npy", np.ones((0, 4, 5), np.float32))
    assert listing(tmp_path) == []


def test_pickle_module_not_used_by_reader(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Belt and braces: reading never reaches pickle.loads / Unpickler."""

    def boom(*a: object, **k: object) -> None:
        raise AssertionError("unpickling attempted")

    monkeypatch.setattr(pickle, "loads", boom)
    monkeypatch.setattr(pickle, "load", boom)
    for suffix in (".npy", ".npz"):
        p = tmp_path / f"evil{suffix}"
        a = np.empty((2, 2, 2), object)
        with contextlib.suppress(Exception):
            np.save(p, a, allow_pickle=True) if suffix == ".npy" else np.savez(p, a)
        with pytest.raises(InputError):
            io.read_video(p)


def test_writer_stamps_each_frame_it_is_given(tmp_path: Path) -> None:
    """write(frame, timestamp_ns): a live stream's times, known as the frames come."""
    from upsr.io import read_timestamps

    v = np.full((3, 4, 5), 1000.0, np.float32)
    stamps = [1_000_000_000 + 33_000_000 * k for k in range(3)]
    for name, fmt in (("a.npz", None), ("bag", "rosbag")):
        with io.VideoWriter(tmp_path / name, fmt=fmt) as w:
            for frame, stamp in zip(v, stamps, strict=True):
                w.write(frame, timestamp_ns=stamp)
        np.testing.assert_array_equal(read_timestamps(tmp_path / name), stamps)
    # a clock that goes back: the times as recorded; the bag's log times keep the frame order
    back = [10, 5, 20]
    for name, fmt in (("back.npz", None), ("back_bag", "rosbag")):
        with io.VideoWriter(tmp_path / name, fmt=fmt) as w:
            for frame, stamp in zip(v, back, strict=True):
                w.write(frame, timestamp_ns=stamp)
        np.testing.assert_array_equal(read_timestamps(tmp_path / name), back)
        (tmp_path / name).unlink() if fmt is None else shutil.rmtree(tmp_path / name)
    for bad, message in (
        ([None, 5, 6], "frame 1 has a timestamp"),
        ([5, None, 6], "frame 1 has no timestamp"),
    ):
        with pytest.raises(InputError, match=message), io.VideoWriter(tmp_path / "b.npz") as w:
            for frame, stamp in zip(v, bad, strict=True):
                w.write(frame, timestamp_ns=stamp)
    with pytest.raises(InputError, match="given to the writer and to frame 0"):
        with io.VideoWriter(tmp_path / "c.npz", timestamps_ns=[1, 2, 3]) as w:
            w.write(v[0], timestamp_ns=5)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npz", "bag"]
