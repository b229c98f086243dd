"""TIFF depth: a multi-page file (one frame per page) or a folder of TIFF files.

Pages must be single-channel, float (16/32/64-bit) or 16/32-bit integer; a raw value v means
``v / depth_scale`` metres (``depth_scale = 1000``, the default: the file holds mm; 1: metres).
8-bit pages are refused (they cannot hold depth; usually a visualisation). NaN = no measurement.
Written as float32 mm × depth_scale / 1000 (default: mm), one zlib-compressed page per frame.
Needs ``tifffile`` (``pip install 'upsr[io]'``).
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from upsr.errors import InputError
from upsr.io._base import VideoInfo, reading, sync_file
from upsr.io._common import check_frame_size, frame_files, mixed_size
from upsr.io.registry import ReadOptions, require
from upsr.method.validation import as_depth_frame

__all__ = ["FrameSink", "frames", "probe", "writes_folder"]

_SUFFIXES = (".tif", ".tiff")
_OK_KINDS = "fui"


def _tifffile() -> Any:
    tf = require("tifffile", "reading and writing TIFF files")
    logging.getLogger("tifffile").setLevel(logging.ERROR)  # its warnings become our errors
    return tf


class _Complaints(logging.Handler):
    """What tifffile logs while a file is read (it logs a truncated file's lost pages, then
    reads the pages it found: a 6-page file cut in half was a 1-frame video)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(re.sub(r"^<[^>]*>\s*", "", record.getMessage()))


@contextlib.contextmanager
def _open(file: Path) -> Iterator[Any]:
    """The TiffFile of ``file``; what tifffile logs meanwhile is an InputError at the end."""
    tf = _tifffile()
    name = str(file)
    log = logging.getLogger("tifffile")
    complaints = _Complaints()
    log.addHandler(complaints)
    propagate, log.propagate = log.propagate, False  # (not printed on stderr as it was)
    try:
        with reading(name):
            tif = tf.TiffFile(file)
        try:
            yield tif
        finally:
            tif.close()
        if complaints.messages:
            raise InputError(f"{name}: corrupt or truncated TIFF ({complaints.messages[0]})")
    finally:
        log.removeHandler(complaints)
        log.propagate = propagate


def _check_page(page: Any, name: str) -> tuple[int, int, np.dtype]:
    shape = tuple(int(s) for s in page.shape)
    dtype = np.dtype(page.dtype) if page.dtype is not None else None
    if len(shape) != 2 or int(getattr(page, "samplesperpixel", 1)) != 1:
        raise InputError(
            f"{name}: TIFF page of shape {shape}: depth frames must be single-channel (h, w)"
        )
    if dtype is None or dtype.kind not in _OK_KINDS or dtype.itemsize < 2:
        hint = " (an 8-bit image cannot hold depth: is it a visualisation?)" if dtype else ""
        raise InputError(
            f"{name}: {dtype}-typed TIFF page: depth must be float or 16/32-bit integer{hint}"
        )
    check_frame_size(name, shape[0], shape[1])
    return shape[0], shape[1], dtype


def _check_data(page: Any, size: int, name: str) -> None:
    offsets = getattr(page, "dataoffsets", ()) or ()
    counts = getattr(page, "databytecounts", ()) or ()
    if not offsets or len(offsets) != len(counts):
        raise InputError(f"{name}: corrupt TIFF page (no image data)")
    end = max(int(o) + int(c) for o, c in zip(offsets, counts, strict=True))
    if end > size:
        raise InputError(f"{name}: truncated TIFF file (image data ends past the end of the file)")


def _file_pages(file: Path) -> tuple[int, int, int, np.dtype]:
    """(n_pages, h, w, dtype) of one file, all pages checked."""
    name = str(file)
    with _open(file) as tif, reading(name):
        size = os.fstat(tif.filehandle.fileno()).st_size if tif.filehandle else 0
        pages = list(tif.pages)
        if not pages:
            raise InputError(f"{name}: the TIFF file has no pages")
        h, w, dtype = _check_page(pages[0], f"{name} page 0")
        for i, page in enumerate(pages):
            label = f"{name} page {i}"
            hh, ww, _ = _check_page(page, label)
            if (hh, ww) != (h, w):
                raise mixed_size(label, (hh, ww), f"{file.name} page 0", (h, w))
            _check_data(page, size, label)
    return len(pages), h, w, dtype


def probe(path: Path, opts: ReadOptions, fmt: str = "tiff") -> VideoInfo:
    """Describe a TIFF file or folder of TIFFs (every page header checked)."""
    files = frame_files(path, _SUFFIXES, "TIFF")
    total, first_hw, dtype = 0, None, None
    for file in files:
        n, h, w, dt = _file_pages(file)
        if first_hw is None:
            first_hw, dtype = (h, w), dt
        elif (h, w) != first_hw:
            raise mixed_size(str(file), (h, w), files[0].name, first_hw)
        total += n
    assert first_hw is not None and dtype is not None
    return VideoInfo(total, first_hw[0], first_hw[1], dtype, "tiff")


def frames(
    path: Path,
    opts: ReadOptions,
    fmt: str = "tiff",
    start: int = 0,
    stop: int | None = None,
) -> Iterator[np.ndarray]:
    """Frames ``start`` … ``stop - 1`` of a TIFF file or folder (float32 mm).

    The pages before ``start`` are not decoded (files wholly before it are only counted).
    """
    files = frame_files(path, _SUFFIXES, "TIFF")
    first_hw: tuple[int, int] | None = None
    t0 = 0  # frame number of the first page of the file
    for file in files:
        if stop is not None and t0 >= stop:
            return
        name = str(file)
        with _open(file) as tif:
            with reading(name):
                n = len(tif.pages)
            last = n if stop is None else min(n, stop - t0)
            for i in range(max(start - t0, 0), last):
                label = f"{name} page {i}"
                with reading(label):
                    page = tif.pages[i]
                    hw = _check_page(page, label)[:2]
                    if first_hw is None:
                        first_hw = hw
                    elif hw != first_hw:
                        raise mixed_size(label, hw, files[0].name, first_hw)
                    raw = page.asarray()
                yield as_depth_frame(raw, name=label, mm_per_unit=opts.mm_per_unit)
        t0 += n


def writes_folder(dest: Path) -> bool:
    """A TIFF output is one multi-page file."""
    return False


class FrameSink:
    """Streams float32 frames as pages of one TIFF file (used by :class:`upsr.io.VideoWriter`).

    Constructed as every format's sink (:class:`upsr.io._base.FrameSink`): ``fh`` is closed
    here (tifffile opens ``temp`` by name); the written value is mm · depth_scale / 1000;
    ``n_frames`` chooses BigTIFF for videos over 2 GB.
    """

    is_folder = False

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
        tf = _tifffile()
        if fh is not None:
            fh.close()
        h, w = shape_px
        big = n_frames is not None and n_frames * h * w * 4 > (1 << 31)
        self._temp = temp
        self._scale = np.float32(depth_scale / 1000.0)
        self._tw = tf.TiffWriter(temp, bigtiff=big)

    def write(self, frame_mm: np.ndarray, t: int) -> None:
        """Append one frame (float32 mm, 0 = no measurement)."""
        data = frame_mm if self._scale == 1 else frame_mm * self._scale
        self._tw.write(
            np.ascontiguousarray(data, dtype=np.float32),
            compression="zlib",
            photometric="minisblack",
            metadata=None,
        )

    def close(self) -> None:
        """Finish the file (flushed and synced)."""
        self._tw.close()
        sync_file(self._temp)

    def abort(self) -> None:
        """Stop writing (the caller removes the temporary)."""
        with contextlib.suppress(Exception):
            self._tw.close()
