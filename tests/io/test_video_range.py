"""upsr.io.iter_frames(start, stop): every format reads exactly the frames of the range, checked,
and skips what comes before it without decoding it."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from upsr.errors import InputError
from upsr.io import video as io


def _video(t: int = 6, h: int = 5, w: int = 7, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = rng.integers(400, 5000, size=(t, h, w)).astype(np.float32)
    v[:, 0, 0] = 0
    return v


def _npy(d: Path, v: np.ndarray) -> Path:
    np.save(d / "v.npy", v.astype(np.uint16))
    return d / "v.npy"


def _npz(d: Path, v: np.ndarray) -> Path:
    np.savez_compressed(d / "v.npz", other=v[:1], depth=v)
    return d / "v.npz"


def _npz_fortran(d: Path, v: np.ndarray) -> Path:
    np.savez(d / "f.npz", np.asfortranarray(v))
    return d / "f.npz"


def _png(d: Path, v: np.ndarray) -> Path:
    return io.write_video(d / "frames", v)


def _tiff_pages(d: Path, v: np.ndarray) -> Path:
    pytest.importorskip("tifffile")
    return io.write_video(d / "v.tif", v)


def _tiff_folder(d: Path, v: np.ndarray) -> Path:
    pytest.importorskip("tifffile")
    folder = d / "tifs"
    folder.mkdir()
    io.write_video(folder / "a1.tif", v[:2])  # 2 pages, then 1, then the rest
    io.write_video(folder / "a2.tif", v[2:3])
    io.write_video(folder / "a10.tif", v[3:])
    return folder


def _exr(d: Path, v: np.ndarray) -> Path:
    pytest.importorskip("OpenEXR")
    return io.write_video(d / "exrs", v, fmt="exr")


def _pgm(d: Path, v: np.ndarray) -> Path:
    folder = d / "pgms"
    folder.mkdir()
    for t, f in enumerate(v):
        h, w = f.shape
        (folder / f"{t}.pgm").write_bytes(
            f"P5 {w} {h} 65535\n".encode() + f.astype(">u2").tobytes()
        )
    return folder


def _bag(d: Path, v: np.ndarray) -> Path:
    pytest.importorskip("rosbags")
    from tests.io import bagtools

    return bagtools.ros1_bag(d / "rec.bag", v)


MAKERS = {
    "npy": (_npy, None),
    "npz": (_npz, "depth"),
    "npz-fortran": (_npz_fortran, None),
    "png": (_png, None),
    "tiff-pages": (_tiff_pages, None),
    "tiff-folder": (_tiff_folder, None),
    "exr": (_exr, None),
    "pgm": (_pgm, None),
    "rosbag": (_bag, None),
}


@pytest.mark.parametrize("kind", sorted(MAKERS))
@pytest.mark.parametrize(("start", "stop"), [(0, None), (0, 1), (2, 5), (3, None), (5, 6)])
def test_range_is_the_slice_of_the_whole_video(
    tmp_path: Path, kind: str, start: int, stop: int | None
) -> None:
    make, key = MAKERS[kind]
    v = _video()
    path = make(tmp_path, v)
    fmt = "pgm" if kind == "pgm" else None
    whole = io.read_video(path, key=key, fmt=fmt)
    np.testing.assert_array_equal(whole, v)
    part = list(io.iter_frames(path, key=key, fmt=fmt, start=start, stop=stop))
    assert len(part) == len(v[start:stop])
    for got, want in zip(part, whole[start:stop], strict=True):
        assert got.dtype == np.float32
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(
    ("start", "stop", "match"),
    [
        (-1, None, "non-empty range"),
        (6, None, "non-empty range"),
        (2, 2, "non-empty range"),
        (3, 1, "non-empty range"),
        (0, 7, "non-empty range"),
        (1.0, None, "start must be an integer"),
        (True, None, "start must be an integer"),
        (0, "3", "stop must be an integer"),
    ],
)
def test_bad_range(tmp_path: Path, start: object, stop: object, match: str) -> None:
    path = _npy(tmp_path, _video())
    with pytest.raises(InputError, match=match):
        io.iter_frames(path, start=start, stop=stop)  # type: ignore[arg-type]


def test_a_range_may_have_no_depth_a_whole_video_may_not(tmp_path: Path) -> None:
    """A range is part of a video whose depth may lie elsewhere (``upsr batch``'s chunk of a
    camera covered at the end); a whole video without depth is refused."""
    v = _video()
    v[:3] = 0
    path = _npy(tmp_path, v)
    assert len(list(io.iter_frames(path, start=2))) == 4
    empty = list(io.iter_frames(path, stop=3))
    assert len(empty) == 3 and not np.any(empty)
    with pytest.raises(InputError, match="no valid depth in any frame"):
        list(io.iter_frames(_npz(tmp_path, np.zeros_like(v))))


def test_png_frames_before_the_range_are_not_decoded(tmp_path: Path) -> None:
    folder = _png(tmp_path, _video())
    first = folder / "000000.png"
    data = bytearray(first.read_bytes())
    data[-20] ^= 0xFF  # corrupt the image data (the header stays valid: probe passes)
    first.write_bytes(bytes(data))
    assert len(list(io.iter_frames(folder, start=1))) == 5
    with pytest.raises(InputError, match=r"000000\.png"):
        list(io.iter_frames(folder))


def test_npz_frames_before_the_range_are_not_converted(tmp_path: Path, monkeypatch) -> None:
    from upsr.io import npz

    path = _npz(tmp_path, _video())
    seen: list[str] = []
    real = npz.as_depth_frame

    def counting(raw, name, **kwargs):  # type: ignore[no-untyped-def]
        seen.append(name)
        return real(raw, name=name, **kwargs)

    monkeypatch.setattr(npz, "as_depth_frame", counting)
    list(io.iter_frames(path, key="depth", start=4))
    assert seen == ["v.npz[depth] frame 4", "v.npz[depth] frame 5"]


def test_bag_messages_before_the_range_are_not_deserialised(tmp_path: Path, monkeypatch) -> None:
    from upsr.io import rosbag

    path = _bag(tmp_path, _video())
    decoded: list[str] = []
    real = rosbag.decode_depth_image

    def counting(msg, *, units_mm=None, name="image"):  # type: ignore[no-untyped-def]
        decoded.append(name)
        return real(msg, units_mm=units_mm, name=name)

    monkeypatch.setattr(rosbag, "decode_depth_image", counting)
    frames = io.iter_frames(path, start=4)
    decoded.clear()  # the probe decodes message 0
    assert len(list(frames)) == 2
    assert [n.rsplit(" ", 1)[-1] for n in decoded] == ["4", "5"]


def test_png_frame_files_are_read_in_natural_order(tmp_path: Path) -> None:
    v = _video(t=3)
    folder = tmp_path / "nat"
    folder.mkdir()
    for t, name in enumerate(["f2.png", "f10.png", "f1.png"]):
        cv2.imwrite(str(folder / name), v[[1, 2, 0][t]].astype(np.uint16))
    np.testing.assert_array_equal(np.stack(list(io.iter_frames(folder, start=1))), v[1:])
