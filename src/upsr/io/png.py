"""Folders of 16-bit PNG depth frames (or a single ``.png`` read as a one-frame video).

One 16-bit single-channel (grayscale) PNG per frame, in natural name order (``frame2.png``
before ``frame10.png``). A raw value v means ``v / depth_scale`` metres, i.e.
``v * 1000 / depth_scale`` mm: ``depth_scale=1000`` (the default) for PNGs in mm, ``5000`` for
the TUM RGB-D benchmark. Every file's chunk structure, checksums and compressed data are checked
in Python before OpenCV decodes it, so a corrupt file gives one clear error. Written as
``000000.png``, ``000001.png``, … (raw = round(mm · depth_scale / 1000), clipped to 65535).
"""

from __future__ import annotations

import contextlib
import struct
import warnings
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from upsr.errors import InputError
from upsr.io import _common
from upsr.io._base import (
    MAX_FRAME_PIXELS,
    VideoInfo,
    check_frame_budget,
    check_input_type,
    reading,
    sync_file,
)
from upsr.io.registry import ReadOptions
from upsr.method.validation import as_depth_frame

__all__ = [
    "FrameSink",
    "frame_files",
    "frames",
    "frames_of_files",
    "probe",
    "probe_files",
    "read_frame",
    "writes_folder",
]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_COLOUR = {
    0: "grayscale",
    2: "RGB colour",
    3: "palette colour",
    4: "grayscale+alpha",
    6: "RGBA colour",
}
# Adam7 passes: (x0, y0, dx, dy)
_ADAM7 = (
    (0, 0, 8, 8),
    (4, 0, 8, 8),
    (0, 4, 4, 8),
    (2, 0, 4, 4),
    (0, 2, 2, 4),
    (1, 0, 2, 2),
    (0, 1, 1, 2),
)

_PNG_MAX = 65535
#: Bytes allocated per pixel while one frame is read (see :func:`_png_header`).
_PNG_BYTES_PER_PX = 12


def frame_files(path: Path) -> list[Path]:
    """A ``.png`` file as a one-frame list, or the PNG files of a folder in natural order
    (:func:`upsr.io._common.frame_files`)."""
    return _common.frame_files(path, (".png",), "PNG")


def _png_header(file: Path) -> tuple[int, int, int]:
    """Return (height, width, interlace) of a 16-bit grayscale PNG from its IHDR chunk."""
    name = str(file)
    check_input_type(file, folder_ok=False)
    with reading(name), open(file, "rb") as f:
        head = f.read(33)
    if len(head) < 33 or head[:8] != _PNG_SIGNATURE:
        raise InputError(f"{name}: not a PNG file")
    (length,) = struct.unpack(">I", head[8:12])
    if length != 13 or head[12:16] != b"IHDR":
        raise InputError(f"{name}: corrupt PNG file (no IHDR chunk first)")
    if zlib.crc32(head[12:29]) != struct.unpack(">I", head[29:33])[0]:
        raise InputError(f"{name}: corrupt PNG file (bad IHDR checksum)")
    w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", head[16:29])
    if w == 0 or h == 0:
        raise InputError(f"{name}: corrupt PNG file (empty {w}x{h} image)")
    if colour != 0 or depth != 16:
        kind = _PNG_COLOUR.get(colour, f"colour type {colour}")
        hint = (
            " (an 8-bit image cannot hold depth in mm: is it a visualisation?)"
            if depth <= 8
            else ""
        )
        raise InputError(
            f"{name}: {depth}-bit {kind} PNG: depth frames must be 16-bit "
            f"single-channel (grayscale) PNGs{hint}"
        )
    if w * h > MAX_FRAME_PIXELS:
        raise InputError(f"{name}: frames of {w}x{h} pixels are too large")
    # filtered rows (2 B/px), OpenCV's uint16 image (2), float32 frame and its copy (4 + 4)
    check_frame_budget(name, h, w, _PNG_BYTES_PER_PX)
    return h, w, interlace


def _png_data_size(h: int, w: int, interlace: int) -> int:
    if not interlace:
        return h * (1 + 2 * w)
    size = 0
    for x0, y0, dx, dy in _ADAM7:
        cols = (w - x0 + dx - 1) // dx if w > x0 else 0
        rows = (h - y0 + dy - 1) // dy if h > y0 else 0
        if cols and rows:
            size += rows * (1 + 2 * cols)
    return size


def _check_png_stream(data: bytes, h: int, w: int, interlace: int, name: str) -> None:
    """Validate chunk structure, checksums and the compressed image data of a PNG.

    Done in Python so that a corrupt file gives one clear error instead of libpng messages.
    """
    pos = 8
    idat: list[bytes] = []
    while True:
        if pos + 12 > len(data):
            raise InputError(f"{name}: truncated PNG file")
        length, ctype = struct.unpack(">I4s", data[pos : pos + 8])
        end = pos + 12 + length
        if end > len(data):
            raise InputError(f"{name}: truncated PNG file")
        if (
            zlib.crc32(data[pos + 4 : pos + 8 + length])
            != struct.unpack(">I", data[end - 4 : end])[0]
        ):
            raise InputError(f"{name}: corrupt PNG file (bad checksum in a {ctype!r} chunk)")
        if ctype == b"IDAT":
            idat.append(data[pos + 8 : pos + 8 + length])
        elif ctype == b"IEND":
            break
        pos = end
    expected = _png_data_size(h, w, interlace)
    d = zlib.decompressobj()
    try:
        raw = d.decompress(b"".join(idat), expected + 1)
    except zlib.error as e:
        raise InputError(f"{name}: corrupt PNG image data ({e})") from None
    if len(raw) != expected or not d.eof:
        raise InputError(f"{name}: corrupt PNG image data (wrong amount of pixel data)")
    if not interlace and np.frombuffer(raw, np.uint8)[:: 1 + 2 * w].max() > 4:
        raise InputError(f"{name}: corrupt PNG image data (bad row filter)")


@contextlib.contextmanager
def _quiet_opencv() -> Iterator[Any]:
    import cv2

    log = getattr(getattr(cv2, "utils", None), "logging", None)
    old = None
    if log is not None:
        with contextlib.suppress(Exception):
            old = log.getLogLevel()
            log.setLogLevel(log.LOG_LEVEL_SILENT)
    try:
        yield cv2
    finally:
        if old is not None:
            with contextlib.suppress(Exception):
                log.setLogLevel(old)


def read_frame(file: Path, shape: tuple[int, int]) -> np.ndarray:
    """The raw uint16 (h, w) pixels of one PNG frame, checked to be of size ``shape``."""
    name = str(file)
    h, w, interlace = _png_header(file)
    if (h, w) != shape:
        raise InputError(
            f"{name}: frame size {w}x{h} differs from the first frame's {shape[1]}x{shape[0]}"
        )
    with reading(name):
        data = file.read_bytes()
    _check_png_stream(data, h, w, interlace, name)
    with reading(name), _quiet_opencv() as cv2:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None or img.dtype != np.uint16 or img.shape != (h, w):
        raise InputError(f"{name}: cannot decode the PNG as a 16-bit single-channel image")
    return img


def probe_files(path: Path) -> tuple[VideoInfo, list[Path]]:
    """Describe a PNG file or folder (every header checked); also return its frame files."""
    files = frame_files(path)
    h, w, _ = _png_header(files[0])
    for file in files[1:]:
        hh, ww, _ = _png_header(file)
        if (hh, ww) != (h, w):
            raise InputError(
                f"{file}: frame size {ww}x{hh} differs from the first frame's "
                f"{w}x{h} ({files[0].name})"
            )
    return VideoInfo(len(files), h, w, np.dtype(np.uint16), "png"), files


def frames_of_files(
    files: list[Path], shape: tuple[int, int], depth_scale: float
) -> Iterator[np.ndarray]:
    """Frames (float32 mm) of PNG files of raw units of 1/``depth_scale`` metres."""
    for file in files:
        raw = read_frame(file, shape)
        yield as_depth_frame(raw, name=file.name, mm_per_unit=1000.0 / depth_scale)


def probe(path: Path, opts: ReadOptions | None = None, fmt: str = "png") -> VideoInfo:
    """Describe a PNG file or folder of PNG frames (headers only)."""
    return probe_files(path)[0]


def frames(
    path: Path,
    opts: ReadOptions | None = None,
    fmt: str = "png",
    start: int = 0,
    stop: int | None = None,
) -> Iterator[np.ndarray]:
    """Frames ``start`` … ``stop - 1`` (float32 mm): only those files are opened."""
    info, files = probe_files(path)
    scale = opts.depth_scale if opts is not None else 1000.0
    return frames_of_files(files[start:stop], (info.height, info.width), scale)


def writes_folder(dest: Path) -> bool:
    """A PNG output is a folder of frames unless ``dest`` ends in ``.png`` (one frame)."""
    return dest.suffix.lower() != ".png"


class FrameSink:
    """Writes 16-bit PNG frames ``000000.png``, … into a folder, or one frame into one
    ``.png`` file (:class:`upsr.io._base.FrameSink`; a second frame is refused).

    raw = round(mm · depth_scale / 1000); values above 65535 are clipped (one warning per
    video) and a measured depth never rounds to 0.
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
        if fh is not None:
            fh.close()
        self._dest = dest
        self._temp = temp
        self._depth_scale = depth_scale
        self._warned_clip = False
        self.is_folder = writes_folder(dest)

    def write(self, frame_mm: np.ndarray, t: int) -> None:
        """Write frame ``t`` (float32 mm, 0 = no measurement) as ``{t:06d}.png``."""
        if not self.is_folder and t > 0:
            raise InputError(
                f"a .png file holds one frame: write a video of several frames to a folder "
                f"(output name without suffix), not {self._dest.name}"
            )
        f = frame_mm
        scale = self._depth_scale
        raw = f * np.float32(scale / 1000.0) if scale != 1000.0 else f
        raw = np.rint(raw)
        over = raw > _PNG_MAX
        if over.any():
            if not self._warned_clip:
                warnings.warn(
                    f"{self._dest}: depths above {_PNG_MAX} raw units "
                    f"({_PNG_MAX * 1000 / scale:g} mm) clipped to fit 16-bit "
                    f"PNG (first in frame {t}; use .npy output or a smaller depth_scale)",
                    stacklevel=3,
                )
                self._warned_clip = True
            raw[over] = _PNG_MAX
        raw[(raw < 1) & (f > 0)] = 1  # a measured depth stays a measurement
        img = raw.astype(np.uint16)
        with _quiet_opencv() as cv2:
            ok, buf = cv2.imencode(".png", img)
        if not ok:
            raise OSError(f"cannot encode frame {t} as PNG")
        dest = self._temp / f"{t:06d}.png" if self.is_folder else self._temp
        dest.write_bytes(buf.tobytes())

    def close(self) -> None:
        """Nothing to finish: every frame is a complete file (one file: flushed to disk)."""
        if not self.is_folder:
            with contextlib.suppress(OSError):
                sync_file(self._temp)

    def abort(self) -> None:
        """Stop writing (the caller removes the temporary folder or file)."""
