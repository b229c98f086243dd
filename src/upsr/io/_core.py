"""Depth video input/output, streamed frame by frame.

Three containers are understood, chosen by the path (or forced with ``fmt=``):

``.npy`` (``fmt="npy"``)
    One (T, h, w) array of depth in mm, any integer or float dtype. Read through a memory map
    (``np.load(mmap_mode="r", allow_pickle=False)``): frames are read one at a time.
``.npz`` (``fmt="npz"``)
    The first array of the archive, or the one named ``key``. Frames are decompressed one at a
    time. Written with the key ``"depth"``.
a folder of PNG files (``fmt="png"``)
    One 16-bit single-channel (grayscale) PNG per frame, in natural name order
    (``frame2.png`` before ``frame10.png``). A raw value v means ``v / depth_scale`` metres,
    i.e. ``v * 1000 / depth_scale`` mm: ``depth_scale=1000`` (the default) for PNGs in mm,
    ``5000`` for the TUM RGB-D benchmark. A single ``.png`` file is read as a 1-frame video.
    Written as ``000000.png``, ``000001.png``, ….

``depth_scale`` applies to PNG frames only: ``.npy``/``.npz`` arrays always hold mm.
Depth 0 or NaN means "no measurement" (``SPEC.md`` §1).

More formats are registered in :mod:`upsr.io.registry` and read through the same functions:
``tiff`` (``.tif``/``.tiff``, multi-page or a folder), ``exr`` (``.exr`` or a folder),
``rosbag`` (ROS 1 / RealSense ``.bag``, ROS 2 bag folders with ``metadata.yaml``; ``topic=``),
``nyu`` (``.pgm`` raw Kinect), ``pgm``, ``tum`` and ``sun`` (dataset PNG conventions); ``tiff``
and ``exr`` can also be written. :func:`read_intrinsics` returns the camera intrinsics a format
carries (ROS CameraInfo) or that a ``<path>.intrinsics.json`` file next to it holds.

Safety
------
Nothing is ever unpickled (object arrays are refused). Every problem with an input file —
missing, unreadable, truncated, corrupt, wrong dtype, shape or bit depth, ±inf or negative
depth — raises :class:`~upsr.errors.InputError` with a message naming the file (and the frame).

:class:`VideoWriter` never leaves a partial output: it writes into a hidden temporary file or
folder next to the output and renames it into place only when the whole video has been
written; on an exception (KeyboardInterrupt included) the temporary is removed. Missing parent
folders of the output are created (and removed again if the writing fails).
:func:`check_output_path` refuses an output that would overwrite an input.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import shutil
import struct
import warnings
import weakref
import zipfile
import zlib
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, BinaryIO

import numpy as np
import numpy.typing as npt

from upsr._atomic import (
    AtomicWriter,
    new_temp_dir,
    new_temp_file,
    remove,
    temp_name,
    write_bytes_atomic,
    write_text_atomic,
)
from upsr.errors import InputError
from upsr.method.validation import as_depth_frame

__all__ = [
    "FORMATS",
    "WRITE_FORMATS",
    "VideoInfo",
    "VideoWriter",
    "check_output_path",
    "intrinsics_path",
    "iter_frames",
    "probe",
    "read_intrinsics",
    "read_video",
    "write_bytes_atomic",
    "write_text_atomic",
    "write_video",
]

PathLike = str | os.PathLike

#: Container formats understood by the readers (see :mod:`upsr.io.registry` for all but the first 3).
FORMATS = ("npy", "npz", "png", "tiff", "exr", "rosbag", "nyu", "pgm", "tum", "sun")
#: Formats the writer can produce.
WRITE_FORMATS = ("npy", "npz", "png", "tiff", "exr")
_CORE_FORMATS = ("npy", "npz", "png")

#: Largest frame accepted (pixels): guards against decompression bombs and absurd headers.
MAX_FRAME_PIXELS = 1 << 28

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
_NPY_HEADER_BYTES = 128  # fixed-size header of the .npy files we write (rewritten at close)
_PNG_MAX = 65535


@dataclass(frozen=True)
class VideoInfo:
    """What :func:`probe` learns about a depth video without reading its frames.

    Attributes
    ----------
    n_frames, height, width : int
        T, h, w.
    dtype : numpy.dtype
        Stored element type (``uint16`` for PNG frames).
    format : str
        Container format (one of :data:`FORMATS`).
    key : str or None
        The ``.npz`` member (or EXR channel) read (None for other formats).
    topic : str or None
        The ROS bag topic read (None for other formats).
    """

    n_frames: int
    height: int
    width: int
    dtype: np.dtype
    format: str
    key: str | None = None
    topic: str | None = None

    @property
    def shape(self) -> tuple[int, int, int]:
        """(T, h, w)."""
        return (self.n_frames, self.height, self.width)


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def _check_fmt(fmt: str) -> str:
    f = str(fmt).lower().lstrip(".")
    if f not in FORMATS:
        raise InputError(f"unknown format {fmt!r} (expected one of: {', '.join(FORMATS)})")
    return f


def _check_depth_scale(depth_scale: float) -> float:
    try:
        s = float(depth_scale)
    except (TypeError, ValueError):
        raise InputError(f"depth_scale must be a number, got {depth_scale!r}") from None
    if not (math.isfinite(s) and s > 0):
        raise InputError(
            f"depth_scale must be a finite number > 0 (raw units per metre), got {depth_scale!r}"
        )
    return s


def _natural_key(name: str) -> tuple[Any, ...]:
    # re.split with a capturing group alternates text, digits, text, ...: same types compare
    parts = re.split(r"([0-9]+)", name)
    return (*(int(p) if i % 2 else p.casefold() for i, p in enumerate(parts)), name)


def _input_format(path: Path, fmt: str | None) -> str:
    try:
        exists = path.exists()
        is_dir = path.is_dir()
    except OSError as e:
        raise InputError(f"{path}: cannot access ({e.strerror or e})") from None
    if not exists:
        raise InputError(f"{path}: no such file or folder")
    from upsr.io import registry as formats

    if fmt is not None:
        f = _check_fmt(fmt)
    elif is_dir:
        f = formats.detect_folder(path) or "png"
    else:
        suffix = path.suffix.lower()
        f = suffix[1:] if suffix in (".npy", ".npz", ".png") else formats.detect_file(path)
        if f is None:
            raise InputError(
                f"{path}: unknown input format {path.suffix or '(no suffix)'!r}: "
                f"expected a .npy or .npz file, a folder of 16-bit PNG frames, or another "
                f"format (--input-format / fmt=: {', '.join(FORMATS[3:])})"
            )
    if f in ("npy", "npz") and is_dir:
        raise InputError(f"{path}: is a folder, not a .{f} file")
    return f


def _output_format(path: Path, fmt: str | None) -> str:
    if fmt is not None:
        f = _check_fmt(fmt)
        if f not in WRITE_FORMATS:
            raise InputError(f"cannot write {f} (output formats: {', '.join(WRITE_FORMATS)})")
        return f
    suffix = path.suffix.lower()
    if suffix in (".npy", ".npz"):
        return suffix[1:]
    if suffix in (".tif", ".tiff"):
        return "tiff"
    if suffix == ".exr":
        return "exr"
    if suffix == "" or path.is_dir():
        return "png"
    raise InputError(
        f"{path}: unknown output format {path.suffix!r}: use a .npy, .npz, .tif or .exr file "
        f"or a folder name (no suffix) for 16-bit PNG frames (--format exr: EXR frames)"
    )


def _folder_output(fmt: str, path: Path) -> bool:
    """Whether the output of format ``fmt`` at ``path`` is a folder of frame files."""
    return fmt == "png" or (fmt == "exr" and path.suffix.lower() != ".exr")


@contextlib.contextmanager
def _reading(name: str) -> Iterator[None]:
    """Turn any failure of the parsing libraries into one readable InputError."""
    try:
        yield
    except InputError:
        raise
    except OSError as e:
        raise InputError(f"{name}: cannot read ({e.strerror or e})") from None
    except Exception as e:  # zipfile/zlib/numpy header parsing: all the user's data
        raise InputError(f"{name}: corrupt or unreadable ({type(e).__name__}: {e})") from None


def _check_array_meta(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
    if dtype.hasobject:
        raise InputError(
            f"{name}: object arrays are refused (they would need unpickling); "
            f"save depth as a numeric array"
        )
    if dtype.kind not in "iuf":
        raise InputError(
            f"{name}: depth must be a numeric (integer or float) array, got dtype {dtype}"
        )
    if len(shape) != 3:
        hint = " (a single frame? save it with shape (1, h, w))" if len(shape) == 2 else ""
        raise InputError(
            f"{name}: expected a depth video of shape (T, h, w), got shape {tuple(shape)}{hint}"
        )
    if 0 in shape:
        raise InputError(f"{name}: empty depth video of shape {tuple(shape)}")
    if shape[1] * shape[2] > MAX_FRAME_PIXELS:
        raise InputError(f"{name}: frames of {shape[1]}x{shape[2]} pixels are too large")


def _read_npy_header(f: IO[bytes], name: str) -> tuple[tuple[int, ...], bool, np.dtype]:
    fmt = np.lib.format
    with _reading(name):
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
    _check_array_meta(name, shape, dtype)
    return shape, bool(fortran), dtype


# ---------------------------------------------------------------------------------------------
# .npy
# ---------------------------------------------------------------------------------------------
def _probe_npy(path: Path) -> tuple[VideoInfo, int]:
    name = str(path)
    with _reading(name), open(path, "rb") as f:
        shape, _, dtype = _read_npy_header(f, name)
        offset = f.tell()
        size = os.fstat(f.fileno()).st_size
    need = math.prod(shape) * dtype.itemsize
    if size - offset < need:
        raise InputError(
            f"{name}: truncated .npy file: shape {shape} needs {need} bytes of data, "
            f"the file holds {size - offset}"
        )
    return VideoInfo(shape[0], shape[1], shape[2], dtype, "npy"), offset


def _frames_npy(path: Path) -> Iterator[np.ndarray]:
    name = str(path)
    with _reading(name):
        arr = np.load(path, mmap_mode="r", allow_pickle=False)
    try:
        for t in range(arr.shape[0]):
            with _reading(name):
                raw = np.array(arr[t])
            yield as_depth_frame(raw, name=f"{path.name} frame {t}")
    finally:
        del arr


# ---------------------------------------------------------------------------------------------
# .npz
# ---------------------------------------------------------------------------------------------
def _npz_member(zf: zipfile.ZipFile, key: str | None, name: str) -> tuple[str, str]:
    arrays = [n[:-4] for n in zf.namelist() if n.endswith(".npy")]
    if not arrays:
        raise InputError(f"{name}: the .npz archive holds no arrays")
    if key is None:
        key = arrays[0]
    elif key not in arrays:
        raise InputError(f"{name}: no array named {key!r} (available: {', '.join(arrays)})")
    return key, key + ".npy"


def _probe_npz(path: Path, key: str | None) -> VideoInfo:
    name = str(path)
    with _reading(name), zipfile.ZipFile(path) as zf:
        key, member = _npz_member(zf, key, name)
        label = f"{name}[{key}]"
        info = zf.getinfo(member)
        with zf.open(member) as f:
            shape, _, dtype = _read_npy_header(f, label)
            offset = f.tell()
        need = math.prod(shape) * dtype.itemsize
        if info.file_size - offset < need:
            raise InputError(
                f"{label}: truncated array: shape {shape} needs {need} bytes of "
                f"data, the archive member holds {info.file_size - offset}"
            )
    return VideoInfo(shape[0], shape[1], shape[2], dtype, "npz", key)


def _read_exact(f: BinaryIO, n: int, label: str) -> bytes:
    chunks = []
    left = n
    while left > 0:
        b = f.read(left)
        if not b:
            raise InputError(f"{label}: truncated array data")
        chunks.append(b)
        left -= len(b)
    return b"".join(chunks)


def _frames_npz(path: Path, key: str) -> Iterator[np.ndarray]:
    name = str(path)
    label = f"{path.name}[{key}]"
    with _reading(name):
        zf = zipfile.ZipFile(path)
    try:
        with _reading(name):
            f = zf.open(key + ".npy")
            shape, fortran, dtype = _read_npy_header(f, label)
        t_n, h, w = shape
        frame_bytes = h * w * dtype.itemsize
        if fortran:  # time varies fastest: frames are not contiguous, read the whole array
            with _reading(name):
                data = _read_exact(f, frame_bytes * t_n, label)
            video = np.frombuffer(data, dtype).reshape(shape, order="F")
            for t in range(t_n):
                yield as_depth_frame(video[t], name=f"{label} frame {t}")
            return
        for t in range(t_n):
            with _reading(name):
                data = _read_exact(f, frame_bytes, label)
            yield as_depth_frame(
                np.frombuffer(data, dtype).reshape(h, w), name=f"{label} frame {t}"
            )
        with _reading(name):
            f.read(1)  # reach the end of the member: zipfile checks its CRC there
    finally:
        zf.close()


# ---------------------------------------------------------------------------------------------
# PNG frames
# ---------------------------------------------------------------------------------------------
def _png_files(path: Path) -> list[Path]:
    if path.is_file():
        return [path]
    with _reading(str(path)):
        entries = list(os.scandir(path))
    files = [
        Path(e.path)
        for e in entries
        if e.name.lower().endswith(".png") and not e.name.startswith(".") and e.is_file()
    ]
    if not files:
        subdirs = sorted(e.name for e in entries if e.is_dir() and not e.name.startswith("."))
        hint = f" (subfolders: {', '.join(subdirs[:5])})" if subdirs else ""
        raise InputError(f"{path}: no PNG frames in this folder{hint}")
    files.sort(key=lambda p: _natural_key(p.name))
    return files


def _png_header(file: Path) -> tuple[int, int, int]:
    """Return (height, width, interlace) of a 16-bit grayscale PNG from its IHDR chunk."""
    name = str(file)
    with _reading(name), open(file, "rb") as f:
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


def _read_png(file: Path, shape: tuple[int, int]) -> np.ndarray:
    name = str(file)
    h, w, interlace = _png_header(file)
    if (h, w) != shape:
        raise InputError(
            f"{name}: frame size {w}x{h} differs from the first frame's {shape[1]}x{shape[0]}"
        )
    with _reading(name):
        data = file.read_bytes()
    _check_png_stream(data, h, w, interlace, name)
    with _reading(name), _quiet_opencv() as cv2:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None or img.dtype != np.uint16 or img.shape != (h, w):
        raise InputError(f"{name}: cannot decode the PNG as a 16-bit single-channel image")
    return img


def _probe_png(path: Path) -> tuple[VideoInfo, list[Path]]:
    files = _png_files(path)
    h, w, _ = _png_header(files[0])
    for file in files[1:]:
        hh, ww, _ = _png_header(file)
        if (hh, ww) != (h, w):
            raise InputError(
                f"{file}: frame size {ww}x{hh} differs from the first frame's "
                f"{w}x{h} ({files[0].name})"
            )
    return VideoInfo(len(files), h, w, np.dtype(np.uint16), "png"), files


def _frames_png(
    files: list[Path], shape: tuple[int, int], depth_scale: float
) -> Iterator[np.ndarray]:
    factor = np.float32(1000.0 / depth_scale)
    for file in files:
        frame = as_depth_frame(_read_png(file, shape), name=file.name)
        if depth_scale != 1000.0:
            frame *= factor
        yield frame


# ---------------------------------------------------------------------------------------------
# public readers
# ---------------------------------------------------------------------------------------------
def probe(
    path: PathLike,
    *,
    key: str | None = None,
    fmt: str | None = None,
    topic: str | None = None,
) -> VideoInfo:
    """Describe a depth video cheaply (headers only) and validate its container.

    Parameters
    ----------
    path : str or path-like
        ``.npy`` / ``.npz`` file, folder of 16-bit PNG frames, a single ``.png``, or a file or
        folder of another format of :data:`FORMATS` (see :mod:`upsr.io.registry`).
    key : str, optional
        Array to read from a ``.npz`` (default: the first one); EXR: the channel.
    fmt : str, optional
        Force the format (one of :data:`FORMATS`) instead of guessing it from the path.
    topic : str, optional
        ROS bags: the depth image topic (default: the only one).

    Returns
    -------
    VideoInfo

    Raises
    ------
    InputError
        Missing/unreadable path, unknown format, not a (T, h, w) numeric array, truncated file,
        PNGs of the wrong bit depth or colour type or of different sizes, empty folder, ….
    """
    p = Path(path)
    f = _input_format(p, fmt)
    _check_key_topic(f, key, topic)
    if f not in _CORE_FORMATS:
        from upsr.io import registry as formats

        opts = formats.ReadOptions(key=key, topic=topic)
        return formats.module(f).probe(p, opts, f)  # type: ignore[no-any-return]
    if f == "npy":
        return _probe_npy(p)[0]
    if f == "npz":
        return _probe_npz(p, key)
    return _probe_png(p)[0]


def _check_key_topic(f: str, key: str | None, topic: str | None) -> None:
    if key is not None and f not in ("npz", "exr"):
        raise InputError(f"key={key!r} only applies to .npz input (or an EXR channel), not {f}")
    if topic is not None and f != "rosbag":
        raise InputError(f"topic={topic!r} only applies to ROS bags, not {f}")


def iter_frames(
    path: PathLike,
    *,
    key: str | None = None,
    depth_scale: float = 1000.0,
    fmt: str | None = None,
    topic: str | None = None,
) -> Iterator[np.ndarray]:
    """Read a depth video one frame at a time.

    The container is validated (as by :func:`probe`) when this function is called; the frames
    are read lazily.

    Parameters
    ----------
    path, key, fmt, topic
        As for :func:`probe`.
    depth_scale : float
        PNG, TIFF, EXR and plain PGM frames: raw units per metre (1000: mm, TUM: 5000,
        metres: 1); mm = raw · 1000 / depth_scale. Formats with fixed units ignore it.

    Yields
    ------
    ndarray float32 (h, w)
        Depth in mm, invalid pixels (0 or NaN) set to 0.

    Raises
    ------
    InputError
        As :func:`probe`; while iterating: ±inf or negative depths (naming the frame), corrupt
        data; after the last frame: no valid depth in any frame.
    """
    p = Path(path)
    scale = _check_depth_scale(depth_scale)
    f = _input_format(p, fmt)
    _check_key_topic(f, key, topic)
    if f not in _CORE_FORMATS:
        from upsr.io import registry as formats

        opts = formats.ReadOptions(key=key, depth_scale=scale, topic=topic)
        impl = formats.module(f)
        impl.probe(p, opts, f)  # validate the container before the first frame is asked for
        return _require_valid(impl.frames(p, opts, f), str(p))
    if f == "npy":
        _probe_npy(p)
        frames = _frames_npy(p)
    elif f == "npz":
        info = _probe_npz(p, key)
        frames = _frames_npz(p, info.key)  # type: ignore[arg-type]
    else:
        info, files = _probe_png(p)
        frames = _frames_png(files, (info.height, info.width), scale)
    return _require_valid(frames, str(p))


def _require_valid(frames: Iterator[np.ndarray], name: str) -> Iterator[np.ndarray]:
    any_valid = False
    with contextlib.closing(frames):
        for frame in frames:
            any_valid = any_valid or bool((frame > 0).any())
            yield frame
    if not any_valid:
        raise InputError(f"{name}: no valid depth in any frame (all pixels are 0 or NaN)")


def read_video(
    path: PathLike,
    *,
    key: str | None = None,
    depth_scale: float = 1000.0,
    fmt: str | None = None,
    topic: str | None = None,
) -> np.ndarray:
    """Read a whole depth video: float32 (T, h, w) in mm (see :func:`iter_frames`)."""
    info = probe(path, key=key, fmt=fmt, topic=topic)
    out = np.empty(info.shape, np.float32)
    frames = iter_frames(path, key=key, depth_scale=depth_scale, fmt=fmt, topic=topic)
    t = -1
    for t, frame in enumerate(frames):
        if t >= info.n_frames:
            raise InputError(f"{path}: more frames than the {info.n_frames} announced")
        out[t] = frame
    if t + 1 != info.n_frames:
        raise InputError(f"{path}: {t + 1} frames read, {info.n_frames} announced")
    return out


def intrinsics_path(path: PathLike) -> Path:
    """Where the intrinsics of a video at ``path`` are written: ``<path>.intrinsics.json``."""
    p = Path(path)
    return p.with_name(p.name.rstrip("/") + ".intrinsics.json")


def read_intrinsics(path: PathLike, *, fmt: str | None = None, topic: str | None = None) -> Any:
    """The camera intrinsics of a depth video, when known.

    Looked up in this order: what the format carries (ROS ``CameraInfo``, RealSense bags), then
    a ``<path>.intrinsics.json`` next to the video (as written by ``upsr run``).

    Returns
    -------
    upsr.research.synth.render.PinholeCamera or None
        fx, fy, cx, cy (px; pixel (i, j) centred at (u, v) = (j, i), SPEC §1), width, height.
    """
    p = Path(path)
    f = _input_format(p, fmt)
    _check_key_topic(f, None, topic)
    if f not in _CORE_FORMATS:
        from upsr.io import registry as formats

        impl = formats.module(f)
        if hasattr(impl, "intrinsics"):
            cam = impl.intrinsics(p, formats.ReadOptions(topic=topic), f)
            if cam is not None:
                return cam
    side = intrinsics_path(p)
    if side.is_file():
        from upsr.geometry.intrinsics import load_intrinsics

        return load_intrinsics(side)
    return None


# ---------------------------------------------------------------------------------------------
# output
# ---------------------------------------------------------------------------------------------
def check_output_path(
    input_paths: Iterable[PathLike] | PathLike,
    output_path: PathLike,
    overwrite: bool = False,
    *,
    fmt: str | None = None,
) -> Path:
    """Check that writing ``output_path`` is safe; return it as a :class:`~pathlib.Path`.

    Refused (:class:`~upsr.errors.InputError`):

    - an output that is one of the inputs (same path after resolving symlinks, or the same
      file through a hard link), or a folder that contains an input;
    - an existing output unless ``overwrite``; with ``overwrite``, an existing folder is only
      replaced by PNG output and only if it holds nothing but PNG files, and a folder is never
      replaced by a file or a file by a folder;
    - an output whose nearest existing ancestor is not a writable folder.

    Missing parent folders are allowed: :class:`VideoWriter` creates them.
    """
    out = Path(output_path)
    if isinstance(input_paths, (str, os.PathLike)):
        input_paths = [input_paths]
    out_res = out.resolve()
    for inp in input_paths:
        inp = Path(inp)
        in_res = inp.resolve()
        same = out_res == in_res
        if not same and os.path.exists(out) and os.path.exists(inp):
            with contextlib.suppress(OSError):
                same = os.path.samefile(out, inp)
        if same:
            raise InputError(f"output {out} is the input {inp}: choose another output path")
        if out_res in in_res.parents:
            raise InputError(
                f"output folder {out} contains the input {inp}: choose another output path"
            )
    f = _output_format(out, fmt)
    if os.path.lexists(out):
        if not overwrite:
            raise InputError(
                f"output {out} already exists (use --overwrite / overwrite=True to replace it)"
            )
        is_dir = out.is_dir() and not out.is_symlink()
        if _folder_output(f, out):
            frame_suffix = f".{f}"
            if not is_dir:
                raise InputError(
                    f"output {out} exists and is not a folder: refusing to replace "
                    f"it by a folder of {f.upper()} frames"
                )
            try:
                entries = list(os.scandir(out))
            except OSError as e:
                raise InputError(f"output {out}: cannot list ({e.strerror or e})") from None
            other = [
                e.name
                for e in entries
                if not (e.is_file(follow_symlinks=False) and e.name.lower().endswith(frame_suffix))
            ]
            if other:
                raise InputError(
                    f"refusing to replace folder {out}: it holds other things "
                    f"than {f.upper()} frames (e.g. {other[0]!r})"
                )
        elif is_dir:
            raise InputError(f"output {out} is a folder: refusing to replace it by a .{f} file")
    anc = Path(os.path.abspath(out)).parent
    while not anc.exists() and anc != anc.parent:
        if os.path.lexists(anc):  # dangling symlink
            raise InputError(f"cannot create {out}: {anc} is a broken link")
        anc = anc.parent
    if not anc.is_dir():
        raise InputError(f"cannot create {out}: {anc} is not a folder")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise InputError(f"cannot create {out}: no permission to write in {anc}")
    return out


def _cleanup(temps: list[Path], created_dirs: list[Path]) -> None:
    for p in temps:
        remove(p)
    temps.clear()
    for d in reversed(created_dirs):  # innermost first; only if still empty
        with contextlib.suppress(OSError):
            d.rmdir()
    created_dirs.clear()


def _npy_header(shape: tuple[int, int, int]) -> bytes:
    """A .npy v1.0 header of exactly ``_NPY_HEADER_BYTES`` bytes (rewritable in place)."""
    t, h, w = shape
    d = f"{{'descr': '<f4', 'fortran_order': False, 'shape': ({t:d}, {h:d}, {w:d}), }}"
    pad = _NPY_HEADER_BYTES - 10 - len(d) - 1
    if pad < 0:
        raise InputError(f"video shape {shape} too large for a .npy header")
    text = (d + " " * pad + "\n").encode("latin1")
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text


class VideoWriter(AtomicWriter):
    """Write a depth video frame by frame, atomically.

    Parameters
    ----------
    path : str or path-like
        ``.npy`` (float32 mm), ``.npz`` (float32 mm, key ``"depth"``), ``.tif``/``.tiff``
        (float32, one page per frame), ``.exr`` (one float32 ``Z`` frame), or a folder name
        without suffix (16-bit PNG frames ``000000.png``, …; EXR frames with ``fmt="exr"``).
    n_frames : int, optional
        Expected number of frames: writing more, or closing after fewer, raises InputError.
    fmt : {"npy", "npz", "png", "tiff", "exr"}, optional
        Force the format instead of guessing it from the path.
    depth_scale : float
        PNG: raw units per metre (1000: mm, TUM: 5000); raw = round(mm · depth_scale / 1000).
        Values above 65535 are clipped (with one warning); valid depths never round to 0.
        TIFF and EXR: the float value written is mm · depth_scale / 1000 (1000: mm, 1: m).
    overwrite : bool
        Replace an existing output (see :func:`check_output_path`).

    Use it as a context manager: the output appears at ``path`` only when the block ends
    without an exception; otherwise nothing is left behind. Every format streams to disk (the
    memory used does not grow with the number of frames).

    Examples
    --------
    >>> with VideoWriter("out.npy") as w:  # doctest: +SKIP
    ...     for frame in frames:
    ...         w.write(frame)
    """

    def __init__(
        self,
        path: PathLike,
        *,
        n_frames: int | None = None,
        fmt: str | None = None,
        depth_scale: float = 1000.0,
        overwrite: bool = False,
    ) -> None:
        self.path = Path(path)
        self.format = _output_format(self.path, fmt)
        self.depth_scale = _check_depth_scale(depth_scale)
        if n_frames is not None and (isinstance(n_frames, bool) or int(n_frames) < 1):
            raise InputError(f"n_frames must be >= 1, got {n_frames!r}")
        self.n_frames = None if n_frames is None else int(n_frames)
        self.overwrite = bool(overwrite)
        check_output_path((), self.path, self.overwrite, fmt=self.format)
        self.frames_written = 0
        self._shape: tuple[int, int] | None = None
        self._fh: BinaryIO | None = None
        self._sink: Any = None
        self._temp: Path | None = None
        self._temps: list[Path] = []
        self._created: list[Path] = []
        self._closed = False
        self._warned_clip = False
        self._finalizer = weakref.finalize(self, _cleanup, self._temps, self._created)

    # -- writing -------------------------------------------------------------------------------
    def _open(self) -> None:
        parent = Path(os.path.abspath(self.path)).parent
        missing = []
        d = parent
        while not d.exists():
            missing.append(d)
            d = d.parent
        for d in reversed(missing):
            os.mkdir(d)
            self._created.append(d)
        if self.format in ("tiff", "exr"):
            from upsr.io import exr, tiff

            fh: Any = None
            if _folder_output(self.format, self.path):
                self._temp = new_temp_dir(self.path)
                self._temps.append(self._temp)
            else:
                self._temp, fh = new_temp_file(self.path)
                self._temps.append(self._temp)
                if self.format == "exr":
                    fh.close()  # OpenEXR writes by name
            if self.format == "tiff":
                self._sink = tiff.FrameSink(
                    self._temp, fh, self.depth_scale, self.n_frames, self._shape
                )
            else:
                single = not _folder_output("exr", self.path)
                self._sink = exr.FrameSink(self._temp, self.depth_scale, single)
        elif self.format == "png":
            self._temp = new_temp_dir(self.path)
            self._temps.append(self._temp)
        else:
            self._temp, self._fh = new_temp_file(self.path)
            self._temps.append(self._temp)
            self._fh.write(_npy_header((0, *self._shape)))  # type: ignore[arg-type]

    def write(self, frame: npt.ArrayLike) -> None:
        """Append one (h, w) depth frame in mm (0 or NaN = no measurement)."""
        if self._closed:
            raise ValueError("write to a closed VideoWriter")
        t = self.frames_written
        f = as_depth_frame(frame, name=f"output frame {t}")
        if self.n_frames is not None and t >= self.n_frames:
            raise InputError(f"{self.path}: more than n_frames={self.n_frames} frames written")
        if self._shape is None:
            self._shape = f.shape
            self._open()
        elif f.shape != self._shape:
            raise InputError(
                f"output frame {t}: shape {f.shape} differs from the first frame's {self._shape}"
            )
        if self._sink is not None:
            self._sink.write(f, t)
        elif self.format == "png":
            self._write_png(f, t)
        else:
            assert self._fh is not None
            self._fh.write(np.ascontiguousarray(f, dtype="<f4").tobytes())
        self.frames_written = t + 1

    def _write_png(self, f: np.ndarray, t: int) -> None:
        raw = f * np.float32(self.depth_scale / 1000.0) if self.depth_scale != 1000.0 else f
        raw = np.rint(raw)
        over = raw > _PNG_MAX
        if over.any():
            if not self._warned_clip:
                warnings.warn(
                    f"{self.path}: depths above {_PNG_MAX} raw units "
                    f"({_PNG_MAX * 1000 / self.depth_scale:g} mm) clipped to fit 16-bit "
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
        assert self._temp is not None
        (self._temp / f"{t:06d}.png").write_bytes(buf.tobytes())

    # -- finishing -----------------------------------------------------------------------------
    def close(self) -> None:
        """Finish the video and move it into place (atomically). Idempotent."""
        if self._closed:
            return
        try:
            if self.frames_written == 0:
                raise InputError(f"{self.path}: no frames written")
            if self.n_frames is not None and self.frames_written != self.n_frames:
                raise InputError(
                    f"{self.path}: {self.frames_written} frames written, {self.n_frames} expected"
                )
            assert self._temp is not None
            if self._sink is not None:
                self._sink.close()
                self._sink = None
            if self.format in ("npy", "npz"):
                assert self._fh is not None and self._shape is not None
                self._fh.seek(0)
                self._fh.write(_npy_header((self.frames_written, *self._shape)))
                self._fh.flush()
                if self.format == "npy":
                    os.fsync(self._fh.fileno())
                    self._fh.close()
                else:
                    self._fh.seek(0)
                    zpath, zfh = new_temp_file(self.path)
                    self._temps.append(zpath)
                    with zfh, zipfile.ZipFile(zfh, "w", zipfile.ZIP_DEFLATED) as zf:
                        with zf.open("depth.npy", "w", force_zip64=True) as member:
                            shutil.copyfileobj(self._fh, member, 1 << 20)
                    self._fh.close()
                    remove(self._temp)
                    self._temp = zpath
                self._fh = None
            self._install()
        except BaseException:
            self.abort()
            raise
        self._closed = True
        self._finalizer.detach()

    def _install(self) -> None:
        tmp, dest = self._temp, self.path
        assert tmp is not None
        if os.path.lexists(dest):
            if not self.overwrite:
                raise InputError(
                    f"output {dest} already exists (use --overwrite / overwrite=True to replace it)"
                )
            check_output_path((), dest, True, fmt=self.format)
            if _folder_output(self.format, dest) and not dest.is_symlink():
                trash = temp_name(dest, "old")
                os.replace(dest, trash)
                self._temps.append(trash)
                os.replace(tmp, dest)
                remove(trash)
                self._temps.clear()
                return
        os.replace(tmp, dest)
        self._temps.clear()

    def abort(self) -> None:
        """Discard everything written; nothing appears at the output path. Idempotent."""
        if self._sink is not None:
            with contextlib.suppress(Exception):
                self._sink.abort()
            self._sink = None
        if self._fh is not None:
            with contextlib.suppress(OSError):
                self._fh.close()
            self._fh = None
        _cleanup(self._temps, self._created)
        self._closed = True
        self._finalizer.detach()

    @property
    def closed(self) -> bool:
        """True once :meth:`close` or :meth:`abort` ran."""
        return self._closed


def write_video(
    path: PathLike,
    frames: npt.ArrayLike | Iterable[npt.ArrayLike],
    *,
    fmt: str | None = None,
    depth_scale: float = 1000.0,
    overwrite: bool = False,
) -> Path:
    """Write a (T, h, w) depth video (array or iterable of frames) atomically; return the path.

    See :class:`VideoWriter` for the formats and options.
    """
    if isinstance(frames, np.ndarray):
        if frames.ndim != 3:
            raise InputError(f"expected a depth video of shape (T, h, w), got shape {frames.shape}")
        n: int | None = frames.shape[0]
    else:
        n = len(frames) if isinstance(frames, Sequence) else None
    with VideoWriter(
        path, n_frames=n, fmt=fmt, depth_scale=depth_scale, overwrite=overwrite
    ) as writer:
        for frame in frames:  # type: ignore[union-attr]
            writer.write(frame)
    return writer.path
