"""OpenEXR depth: one frame per file (per part of a multi-part file), or a folder of EXRs.

The depth channel is ``key`` if given, else the first of ``Z``, ``depth``, ``Depth``, ``D``,
``distance``, ``Y``, ``R`` (also as the last component of a layered name such as
``ViewLayer.Depth.Z``), else the only channel. Half, float or uint channels; a raw value v
means ``v / depth_scale`` metres (default 1000: mm; Blender and most renderers write metres:
use ``depth_scale=1`` / ``--depth-scale 1``). NaN = no measurement. Written as a float32 ``Z``
channel (ZIP compression), in mm × depth_scale / 1000: a ``.exr`` path holds one frame, a folder
(``fmt="exr"``) holds ``000000.exr``, ``000001.exr``, …. Needs the ``openexr`` package
(``pip install 'upsr[io]'``).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from upsr.errors import InputError
from upsr.io._base import VideoInfo, reading, sync_file
from upsr.io._common import (
    c_output_captured,
    check_frame_size,
    frame_files,
    mixed_size,
)
from upsr.io.registry import ReadOptions, require
from upsr.method.validation import as_depth_frame

__all__ = ["DEPTH_CHANNELS", "FrameSink", "frames", "probe", "writes_folder"]

#: Channel names tried in order when no ``key`` is given.
DEPTH_CHANNELS = ("Z", "depth", "Depth", "D", "distance", "Y", "R")


def _exr() -> Any:
    return require("OpenEXR", "reading and writing OpenEXR files")


def _load(file: Path, header_only: bool) -> list[tuple[Any, dict[str, np.ndarray] | None]]:
    """(header, channel pixels or None) of every part, read with the library's output captured.

    Everything the library reads happens inside the capture (pixels included), and any
    complaint it prints makes the file corrupt.
    """
    exr = _exr()
    name = str(file)
    with reading(name):
        with open(file, "rb") as f:
            magic = f.read(4)
        if magic != b"\x76\x2f\x31\x01":
            raise InputError(f"{name}: not an OpenEXR file (bad magic bytes)")
        with c_output_captured() as said:
            try:
                # no worker threads: their complaints would escape the capture
                data = exr.File(
                    name, separate_channels=True, header_only=header_only, num_threads=0
                )
                parts = [
                    (
                        p.header,
                        None
                        if header_only
                        else {n: np.array(c.pixels) for n, c in p.channels.items()},
                    )
                    for p in data.parts
                ]
                del data
                error = None
            except Exception as e:  # any library failure is the file's
                parts, error = [], e
    complaint = " ".join(said).strip()
    if error is not None or not parts or (complaint and not header_only):
        detail = " ".join((complaint + " " + (str(error) if error else "")).split())
        raise InputError(f"{name}: corrupt or truncated OpenEXR file ({detail or 'no parts'})")
    return parts


def _choose(names: list[str], key: str | None, label: str) -> str:
    if key is not None:
        if key not in names:
            raise InputError(f"{label}: no channel {key!r} (channels: {', '.join(names)})")
        return key
    for want in DEPTH_CHANNELS:
        for n in names:
            if n == want or n.rsplit(".", 1)[-1] == want:
                return n
    if len(names) == 1:
        return names[0]
    raise InputError(
        f"{label}: which channel holds depth? channels: {', '.join(names)} "
        f"(choose one with --key / key=)"
    )


def _part_meta(header: Any, key: str | None, label: str) -> tuple[int, int, str]:
    (x0, y0), (x1, y1) = (tuple(int(v) for v in a) for a in header["dataWindow"])
    h, w = y1 - y0 + 1, x1 - x0 + 1
    check_frame_size(label, h, w)
    channels = {c.name: c for c in header["channels"]}
    name = _choose(list(channels), key, label)
    c = channels[name]
    if c.xSampling != 1 or c.ySampling != 1:
        raise InputError(f"{label}: channel {name!r} is subsampled; depth needs every pixel")
    return h, w, name


def probe(path: Path, opts: ReadOptions, fmt: str = "exr") -> VideoInfo:
    """Describe an EXR file or folder of EXRs (headers only)."""
    files = frame_files(path, (".exr",), "EXR")
    total, first_hw = 0, None
    for file in files:
        parts = _load(file, header_only=True)
        for i, (header, _) in enumerate(parts):
            label = f"{file}" if len(parts) == 1 else f"{file} part {i}"
            with reading(label):
                h, w, _ = _part_meta(header, opts.key, label)
            if first_hw is None:
                first_hw = (h, w)
            elif (h, w) != first_hw:
                raise mixed_size(label, (h, w), files[0].name, first_hw)
            total += 1
    assert first_hw is not None
    return VideoInfo(total, first_hw[0], first_hw[1], np.dtype(np.float32), "exr", opts.key)


def frames(
    path: Path,
    opts: ReadOptions,
    fmt: str = "exr",
    start: int = 0,
    stop: int | None = None,
) -> Iterator[np.ndarray]:
    """Frames ``start`` … ``stop - 1`` of an EXR file or folder (float32 mm).

    Files wholly before ``start`` are only counted (their headers read), never decoded.
    """
    files = frame_files(path, (".exr",), "EXR")
    first_hw: tuple[int, int] | None = None
    t0 = 0  # frame number of the first part of the file
    for file in files:
        if stop is not None and t0 >= stop:
            return
        if t0 < start:
            n = len(_load(file, header_only=True))
            if t0 + n <= start:
                t0 += n
                continue
        parts = _load(file, header_only=False)
        for i, (header, pixels) in enumerate(parts):
            if t0 + i < start or (stop is not None and t0 + i >= stop):
                continue
            label = f"{file}" if len(parts) == 1 else f"{file} part {i}"
            with reading(label):
                h, w, name = _part_meta(header, opts.key, label)
                raw = np.asarray(pixels[name])  # type: ignore[index]
            if raw.shape != (h, w) or raw.dtype.kind not in "fu":
                raise InputError(f"{label}: corrupt OpenEXR pixel data for channel {name!r}")
            if first_hw is None:
                first_hw = (h, w)
            elif (h, w) != first_hw:
                raise mixed_size(label, (h, w), files[0].name, first_hw)
            yield as_depth_frame(raw, name=label, mm_per_unit=opts.mm_per_unit)
        t0 += len(parts)
        del parts


def writes_folder(dest: Path) -> bool:
    """An EXR output is a folder of frames unless ``dest`` ends in ``.exr`` (one frame)."""
    return dest.suffix.lower() != ".exr"


class FrameSink:
    """Writes float32 ``Z`` EXR frames: into a folder, or one frame into one file.

    Constructed as every format's sink (:class:`upsr.io._base.FrameSink`): ``temp`` is a
    folder, or the one file of a ``.exr`` destination (``fh`` is closed here: OpenEXR writes by
    name, and a second frame is refused); the written value is mm · depth_scale / 1000.
    """

    def __init__(
        self,
        dest: Path,
        temp: Path,
        fh: BinaryIO | None,
        *,
        shape_px: tuple[int, int],
        depth_scale: float = 1000.0,
        n_frames: int | None = None,
    ) -> None:
        self._exr = _exr()
        if fh is not None:
            fh.close()
        self._temp = temp
        self._dest = dest
        self._scale = np.float32(depth_scale / 1000.0)
        self.is_folder = writes_folder(dest)

    def write(self, frame_mm: np.ndarray, t: int) -> None:
        """Write frame ``t`` (float32 mm, 0 = no measurement)."""
        if not self.is_folder and t > 0:
            raise InputError(
                f"an .exr file holds one frame: write a video of several frames to a folder "
                f"(output name without suffix and --format exr), not {self._dest.name}"
            )
        data = frame_mm if self._scale == 1 else frame_mm * self._scale
        header = {"compression": self._exr.ZIP_COMPRESSION, "type": self._exr.scanlineimage}
        f = self._exr.File(header, {"Z": np.ascontiguousarray(data, dtype=np.float32)})
        dest = self._temp / f"{t:06d}.exr" if self.is_folder else self._temp
        f.write(str(dest))
        if not dest.is_file():  # pragma: no cover - OpenEXR reports failures on stderr only
            raise OSError(f"cannot write {dest}")

    def close(self) -> None:
        """Nothing to finish: every frame is a complete file."""
        if not self.is_folder:
            with contextlib.suppress(OSError):
                sync_file(self._temp)

    def abort(self) -> None:
        """Stop writing (the caller removes the temporary)."""
