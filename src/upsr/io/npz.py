"""``.npz`` depth videos: the array named ``key``, by default ``depth`` or the first video.

Frames are decompressed one at a time (a frame range skips the frames before it in the
decompressed stream without converting them). Written as float32 mm under the key ``"depth"``
(ZIP_DEFLATED, ZIP64). Nothing is ever unpickled (object arrays are refused).
"""

from __future__ import annotations

import math
import os
import shutil
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

import numpy as np

from upsr._atomic import new_temp_file, remove
from upsr.errors import InputError, short_list
from upsr.io import npy
from upsr.io._base import VideoInfo, check_input_type, reading
from upsr.io.registry import ReadOptions
from upsr.method.validation import as_depth_frame

__all__ = ["FrameSink", "frames", "probe", "writes_folder"]

_SKIP_BLOCK_BYTES = 1 << 24


def _member(zf: zipfile.ZipFile, key: str | None, name: str) -> tuple[str, str]:
    arrays = [n[:-4] for n in zf.namelist() if n.endswith(".npy")]
    if not arrays:
        raise InputError(f"{name}: the .npz archive holds no arrays")
    if key is None:
        key = _default_key(zf, arrays)
    elif key not in arrays:
        raise InputError(f"{name}: no array named {key[:60]!r} (available: {short_list(arrays)})")
    return key, key + ".npy"


#: Arrays of an archive whose headers :func:`_default_key` reads at most (a hostile archive
#: may hold millions).
_MAX_PROBED_ARRAYS = 64


def _default_key(zf: zipfile.ZipFile, arrays: list[str]) -> str:
    """The array read without ``--key``: ``depth`` (the name upsr writes), else the first
    that holds a depth video (T, h, w) (e.g. beside a ``timestamps`` array), else the first
    (whose error then names its shape)."""
    if "depth" in arrays:
        return "depth"
    for name in arrays[:_MAX_PROBED_ARRAYS]:
        with zf.open(name + ".npy") as f:
            try:
                npy.read_npy_header(f, name)
            except InputError:
                continue
        return name
    return arrays[0]


def probe(path: Path, opts: ReadOptions | None = None, fmt: str = "npz") -> VideoInfo:
    """Describe the array ``opts.key`` (default: the first) of a ``.npz`` (header checked)."""
    key = opts.key if opts is not None else None
    name = str(path)
    check_input_type(path, folder_ok=False)
    with reading(name), zipfile.ZipFile(path) as zf:
        key, member = _member(zf, key, name)
        label = f"{name}[{key}]"
        info = zf.getinfo(member)
        with zf.open(member) as f:
            shape, _, dtype = npy.read_npy_header(f, label)
            offset = f.tell()
        need = math.prod(shape) * dtype.itemsize
        if info.file_size - offset < need:
            raise InputError(
                f"{label}: truncated array: shape {shape} needs {need} bytes of "
                f"data, the archive member holds {info.file_size - offset}"
            )
    return VideoInfo(shape[0], shape[1], shape[2], dtype, "npz", key)


_read_exact = npy.read_exact


def _skip(f: BinaryIO, n: int, label: str) -> None:
    """Read and drop ``n`` bytes of the (decompressed) member."""
    while n > 0:
        step = min(n, _SKIP_BLOCK_BYTES)
        _read_exact(f, step, label)
        n -= step


def frames(
    path: Path,
    opts: ReadOptions | None = None,
    fmt: str = "npz",
    start: int = 0,
    stop: int | None = None,
) -> Iterator[np.ndarray]:
    """Frames ``start`` … ``stop - 1`` of the array ``opts.key`` (float32 mm)."""
    name = str(path)
    check_input_type(path, folder_ok=False)
    with reading(name):
        zf = zipfile.ZipFile(path)
    try:
        with reading(name):
            key, member = _member(zf, opts.key if opts is not None else None, name)
            label = f"{path.name}[{key}]"
            f = zf.open(member)
            shape, fortran, dtype = npy.read_npy_header(f, label)
        t_n, h, w = shape
        last = t_n if stop is None else stop
        unit = opts.mm_per_unit if opts is not None else 1.0
        frame_bytes = h * w * dtype.itemsize
        if fortran:  # time varies fastest: read the whole array (read_npy_header: within budget)
            with reading(name):
                data = _read_exact(f, frame_bytes * t_n, label)
            video = np.frombuffer(data, dtype).reshape(shape, order="F")
            for t in range(start, last):
                yield as_depth_frame(video[t], name=f"{label} frame {t}", mm_per_unit=unit)
            return
        with reading(name):
            _skip(f, frame_bytes * start, label)
        for t in range(start, last):
            with reading(name):
                data = _read_exact(f, frame_bytes, label)
            yield as_depth_frame(
                np.frombuffer(data, dtype).reshape(h, w),
                name=f"{label} frame {t}",
                mm_per_unit=unit,
            )
        if last == t_n:
            with reading(name):
                f.read(1)  # reach the end of the member: zipfile checks its CRC there
    finally:
        zf.close()


def writes_folder(dest: Path) -> bool:
    """A ``.npz`` output is one file."""
    return False


class FrameSink(npy.FrameSink):
    """Streams float32 mm frames as the ``depth`` array of a ``.npz``.

    The frames go to the temporary file as a ``.npy`` stream; :meth:`close` compresses it into
    an archive that replaces the temporary (see :class:`upsr.io._base.FrameSink`).
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
        super().__init__(
            dest, temp, fh, shape_px=shape_px, depth_scale=depth_scale, n_frames=n_frames
        )
        self._dest = dest

    def close(self) -> None:
        """Compress the frames written into the archive that replaces the temporary."""
        fh = self._finish_header()
        fh.seek(0)
        zpath, zfh = new_temp_file(self._dest)
        try:
            with zfh, zipfile.ZipFile(zfh, "w", zipfile.ZIP_DEFLATED) as zf:
                with zf.open("depth.npy", "w", force_zip64=True) as member:
                    shutil.copyfileobj(fh, member, 1 << 20)
            fh.close()
            self._fh = None
            os.replace(zpath, self._temp)
        except BaseException:
            remove(zpath)
            raise
