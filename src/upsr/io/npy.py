"""``.npy`` depth videos: one (T, h, w) array of depth in mm, any integer or float dtype.

Read frame by frame with plain reads (no memory map: a file that shrinks while it is read would
kill the process with SIGBUS), a frame range starting at its byte offset; the header is checked
against the file size and the frame byte budget (:func:`upsr.io._base.frame_budget`) before
anything is allocated. A Fortran-order array (time varying fastest: no frame is contiguous) is
read whole when it fits the budget and refused otherwise. Written as float32 mm, streamed: a
fixed-size header is written first and rewritten with the final frame count at the end.
Nothing is ever unpickled (object arrays are refused).
"""

from __future__ import annotations

import math
import os
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import IO, BinaryIO

import numpy as np

from upsr.errors import InputError
from upsr.io._base import (
    VideoInfo,
    check_array_meta,
    check_frame_budget,
    check_input_type,
    frame_budget,
    reading,
)
from upsr.io.registry import ReadOptions
from upsr.method.validation import as_depth_frame

__all__ = ["FrameSink", "frames", "npy_header", "probe", "read_npy_header", "writes_folder"]

#: Size of the header of the .npy files written here (rewritten in place at close).
NPY_HEADER_BYTES = 128


def read_npy_header(f: IO[bytes], name: str) -> tuple[tuple[int, ...], bool, np.dtype]:
    """(shape, fortran order, dtype) of the .npy stream ``f``, checked as a depth video.

    ``f`` is left at the first data byte.
    """
    fmt = np.lib.format
    with reading(name):
        try:
            version = fmt.read_magic(f)
        except ValueError:
            raise InputError(f"{name}: not a .npy file (bad magic bytes)") from None
        if version == (1, 0):
            shape, fortran, dtype = fmt.read_array_header_1_0(f)
        elif version == (2, 0):
            shape, fortran, dtype = fmt.read_array_header_2_0(f)
        else:
            raise InputError(f"{name}: unsupported .npy format version {version}")
    shape = tuple(int(s) for s in shape)
    check_array_meta(name, shape, dtype)
    check_frame_budget(name, shape[1], shape[2], dtype.itemsize + 8)
    if fortran:
        check_fortran(name, shape, dtype)
    return shape, bool(fortran), dtype


def check_fortran(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
    """A Fortran-order array is read whole: refuse it when it exceeds the frame budget."""
    need = math.prod(shape) * dtype.itemsize
    limit = frame_budget()
    if need > limit:
        raise InputError(
            f"{name}: Fortran-order array of {need / 1e9:.3g} GB, read whole, over the "
            f"{limit / 1e9:.3g} GB budget: save it in C order"
        )


def read_exact(f: IO[bytes], n: int, label: str) -> bytes:
    """Exactly ``n`` bytes of ``f`` (InputError ``truncated`` when it ends before)."""
    chunks = []
    left = n
    while left > 0:
        b = f.read(min(left, 1 << 26))
        if not b:
            raise InputError(f"{label}: truncated array data (the file ended early)")
        chunks.append(b)
        left -= len(b)
    return b"".join(chunks)


def probe(path: Path, opts: ReadOptions | None = None, fmt: str = "npy") -> VideoInfo:
    """Describe a ``.npy`` video (header and file size checked)."""
    name = str(path)
    check_input_type(path, folder_ok=False)
    with reading(name), open(path, "rb") as f:
        shape, _, dtype = read_npy_header(f, name)
        offset = f.tell()
        size = os.fstat(f.fileno()).st_size
    need = math.prod(shape) * dtype.itemsize
    if size - offset < need:
        raise InputError(
            f"{name}: truncated .npy file: shape {shape} needs {need} bytes of data, "
            f"the file holds {size - offset}"
        )
    return VideoInfo(shape[0], shape[1], shape[2], dtype, "npy")


def frames(
    path: Path,
    opts: ReadOptions | None = None,
    fmt: str = "npy",
    start: int = 0,
    stop: int | None = None,
) -> Iterator[np.ndarray]:
    """Frames ``start`` … ``stop - 1`` of a ``.npy`` video (float32 mm), read one at a time."""
    name = str(path)
    check_input_type(path, folder_ok=False)
    with reading(name):
        f = open(path, "rb")
    try:
        with reading(name):
            shape, fortran, dtype = read_npy_header(f, name)
            offset = f.tell()
        t_n, h, w = shape
        last = t_n if stop is None else stop
        unit = opts.mm_per_unit if opts is not None else 1.0
        frame_bytes = h * w * dtype.itemsize
        if fortran:  # time varies fastest: read the whole array (within the budget)
            with reading(name):
                data = read_exact(f, frame_bytes * t_n, name)
            video = np.frombuffer(data, dtype).reshape(shape, order="F")
            for t in range(start, last):
                yield as_depth_frame(video[t], name=f"{path.name} frame {t}", mm_per_unit=unit)
            return
        with reading(name):
            f.seek(offset + frame_bytes * start)
        for t in range(start, last):
            with reading(name):
                data = read_exact(f, frame_bytes, f"{name} frame {t}")
            yield as_depth_frame(
                np.frombuffer(data, dtype).reshape(h, w),
                name=f"{path.name} frame {t}",
                mm_per_unit=unit,
            )
    finally:
        f.close()


def npy_header(shape: tuple[int, int, int]) -> bytes:
    """A float32 .npy v1.0 header of exactly ``NPY_HEADER_BYTES`` bytes (rewritable in place)."""
    t, h, w = shape
    d = f"{{'descr': '<f4', 'fortran_order': False, 'shape': ({t:d}, {h:d}, {w:d}), }}"
    pad = NPY_HEADER_BYTES - 10 - len(d) - 1
    if pad < 0:
        raise InputError(f"video shape {shape} too large for a .npy header")
    text = (d + " " * pad + "\n").encode("latin1")
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text


def writes_folder(dest: Path) -> bool:
    """A ``.npy`` output is one file."""
    return False


class FrameSink:
    """Streams float32 mm frames into one ``.npy`` file (see :class:`upsr.io._base.FrameSink`).

    ``depth_scale`` and ``n_frames`` are not used: the array holds mm and the header is
    rewritten with the frames written when the sink is closed.
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
        assert fh is not None, "a .npy output is a file"
        self._temp = temp
        self._fh: BinaryIO | None = fh
        self._shape = shape_px
        self._count = 0
        fh.write(npy_header((0, *shape_px)))

    def write(self, frame_mm: np.ndarray, t: int) -> None:
        """Append frame ``t`` (float32 mm)."""
        assert self._fh is not None
        self._fh.write(np.ascontiguousarray(frame_mm, dtype="<f4").tobytes())
        self._count = t + 1

    def _finish_header(self) -> BinaryIO:
        fh = self._fh
        assert fh is not None
        fh.seek(0)
        fh.write(npy_header((self._count, *self._shape)))
        fh.flush()
        return fh

    def close(self) -> None:
        """Rewrite the header with the final frame count; flush, sync and close."""
        fh = self._finish_header()
        os.fsync(fh.fileno())
        fh.close()
        self._fh = None

    def abort(self) -> None:
        """Close the file (the caller removes it)."""
        if self._fh is not None:
            try:
                self._fh.close()
            except OSError:
                pass
            self._fh = None
