"""What every depth format shares: :class:`VideoInfo`, the reader/writer protocols and checks.

Each format module of :mod:`upsr.io` (``npy``, ``npz``, ``png``, ``tiff``, ``exr``, ``rosbag``,
``datasets``) implements :class:`FormatReader`; the writable ones (``npy``, ``npz``, ``png``,
``tiff``, ``exr``) also implement :class:`FormatWriter`, whose ``FrameSink`` has the one
constructor signature of :class:`FrameSink`. :mod:`upsr.io.video` dispatches to them through
:mod:`upsr.io.registry`.
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
from collections.abc import Iterator
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO, Protocol

import numpy as np

from upsr.errors import InputError, one_line

if TYPE_CHECKING:
    from upsr.io.registry import ReadOptions

__all__ = [
    "FORMATS",
    "MAX_FRAME_PIXELS",
    "WRITE_FORMATS",
    "FormatReader",
    "FormatWriter",
    "FrameSink",
    "PathLike",
    "VideoInfo",
    "check_array_meta",
    "check_depth_scale",
    "check_fmt",
    "check_frame_budget",
    "check_frame_range",
    "check_input_type",
    "frame_budget",
    "natural_key",
    "reading",
    "set_frame_budget",
    "sync_file",
]

PathLike = str | os.PathLike

#: Container formats understood by the readers (see :mod:`upsr.io.registry`).
FORMATS = ("npy", "npz", "png", "tiff", "exr", "rosbag", "nyu", "pgm", "tum", "sun")
#: Formats the writer can produce.
WRITE_FORMATS = ("npy", "npz", "png", "tiff", "exr", "rosbag")

#: Largest frame accepted (pixels): guards against decompression bombs and absurd headers.
MAX_FRAME_PIXELS = 1 << 28

#: Bytes one frame may need while it is read (its stored bytes, the decoded pixels and the
#: float32 frame), set by :func:`set_frame_budget`; None: :func:`frame_budget`'s default.
_FRAME_BUDGET: int | None = None
#: Most bytes a frame may need by default, whatever the machine has (1 GiB).
DEFAULT_FRAME_BUDGET_MAX = 1 << 30


def set_frame_budget(n_bytes: int | None) -> None:
    """Set the byte budget of one frame being read (None: back to the default).

    The command line sets it from ``--max-memory``; see :func:`frame_budget`.
    """
    global _FRAME_BUDGET
    if n_bytes is not None and (isinstance(n_bytes, bool) or int(n_bytes) < 1):
        raise InputError(f"frame byte budget must be an integer >= 1, got {n_bytes!r}")
    _FRAME_BUDGET = None if n_bytes is None else int(n_bytes)


def frame_budget() -> int:
    """Bytes one frame may need while it is read, before anything is allocated for it.

    Default: a quarter of the memory available now (MemAvailable, RLIMIT_AS and the cgroup
    limit, :func:`upsr.method.resources.available_memory_bytes`), at most 1 GiB and at least
    64 MiB: a header declaring a 16000×16000 frame (a 530 KB PNG "bomb") is refused from the
    header instead of decoding 0.5 GB of pixels and 1 GB of float32 depth.
    """
    if _FRAME_BUDGET is not None:
        return _FRAME_BUDGET
    from upsr.method.resources import available_memory_bytes

    return int(max(64 << 20, min(DEFAULT_FRAME_BUDGET_MAX, available_memory_bytes() // 4)))


def _gb(n: float) -> str:
    return f"{n / 1e9:.2g} GB" if n >= 1e8 else f"{n / 1e6:.2g} MB"


def check_frame_budget(
    name: str, h: int, w: int, bytes_per_px: float, *, budget: int | None = None
) -> None:
    """Refuse frames whose reading would need more than ``budget`` bytes (:func:`frame_budget`).

    ``bytes_per_px``: what reading one pixel allocates (stored sample, decoded copies, the
    float32 frame). Checked from the header, before anything is allocated.
    """
    limit = frame_budget() if budget is None else int(budget)
    need = int(h) * int(w) * float(bytes_per_px)
    if need > limit:
        raise InputError(
            one_line(
                f"{name}: a {w}x{h} frame needs ~{_gb(need)} to read, over the {_gb(limit)} "
                "per-frame limit (--max-memory)"
            )
        )


_FILE_KINDS = (
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
)


def sync_file(path: Path) -> None:
    """Flush a file written by name (a library that closes its own handle) to the disk."""
    with open(path, "rb") as f:
        os.fsync(f.fileno())


def file_kind(mode: int) -> str:
    """What a non-regular, non-folder file of ``st_mode`` is, in words."""
    for test, what in _FILE_KINDS:
        if test(mode):
            return what
    return "not a regular file"


def check_input_type(path: Path, *, folder_ok: bool = True) -> os.stat_result:
    """``os.stat`` of an input, refused unless it is a regular file (or a folder).

    Checked by type before anything opens it: ``/dev/zero`` would be read forever, a FIFO
    with no writer blocks ``open`` for ever, sockets and devices are no depth videos.
    """
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file or folder") from None
    except OSError as e:
        raise InputError(f"{path}: cannot access ({e.strerror or e})") from None
    if stat.S_ISREG(st.st_mode) or (folder_ok and stat.S_ISDIR(st.st_mode)):
        return st
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{path}: is a folder, not a file")
    raise InputError(f"{path}: is {file_kind(st.st_mode)}, not a depth file: refusing to read it")


@dataclass(frozen=True)
class VideoInfo:
    """What :func:`upsr.io.probe` learns about a depth video without reading its frames.

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


class FormatReader(Protocol):
    """A readable format module (``upsr.io.npy``, ``upsr.io.tiff``, …)."""

    def probe(self, path: Path, opts: ReadOptions, fmt: str) -> VideoInfo:
        """Validate the container cheaply (headers only) and describe it."""
        ...

    def frames(
        self, path: Path, opts: ReadOptions, fmt: str, start: int = 0, stop: int | None = None
    ) -> Iterator[np.ndarray]:
        """Frames ``start`` to ``stop - 1`` (float32 (h, w) mm), skipping what comes before
        ``start`` as cheaply as the format allows. The range is checked by the caller."""
        ...


class FrameSink(Protocol):
    """Streams the frames of one output into a temporary file or folder.

    Every writable format's ``FrameSink`` is built as
    ``FrameSink(dest, temp, fh, shape_px=(h, w), depth_scale=…, n_frames=…)``:

    dest : pathlib.Path
        The final output (for messages).
    temp : pathlib.Path
        The temporary file or folder (``writes_folder(dest)``) that :class:`upsr.io.VideoWriter`
        renames to ``dest`` once :meth:`close` returns.
    fh : binary file or None
        An open handle of a temporary file (None for a folder); the sink closes it.
    shape_px : (int, int)
        (h, w) of every frame.
    depth_scale : float
        Raw units per metre of formats storing raw numbers (see :class:`upsr.io.VideoWriter`).
    n_frames : int or None
        Frames announced (None: unknown).
    """

    def write(self, frame_mm: np.ndarray, t: int) -> None:
        """Append frame ``t`` (float32 (h, w) mm, 0 = no measurement)."""
        ...

    def close(self) -> None:
        """Finish the temporary (complete and synced to disk)."""
        ...

    def abort(self) -> None:
        """Stop writing; the caller removes the temporary."""
        ...


class FormatWriter(Protocol):
    """A writable format module."""

    def writes_folder(self, dest: Path) -> bool:
        """Whether the output at ``dest`` is a folder of frame files."""
        ...

    def FrameSink(  # the class of the module, called as a constructor
        self,
        dest: Path,
        temp: Path,
        fh: BinaryIO | None,
        *,
        shape_px: tuple[int, int],
        depth_scale: float,
        n_frames: int | None,
    ) -> FrameSink:
        """Open a sink (see :class:`FrameSink`)."""
        ...


def check_fmt(fmt: str) -> str:
    """``fmt`` normalised (lower case, no dot); InputError if not one of :data:`FORMATS`."""
    f = str(fmt).lower().lstrip(".")
    if f not in FORMATS:
        raise InputError(f"unknown format {fmt!r} (expected one of: {', '.join(FORMATS)})")
    return f


#: Raw units per metre a depth scale may be: km (0.001) to nm (1e9). Beyond, a float32 TIFF
#: or EXR output was all inf (1e40) or all 0 (1e-50), and an input all "no depth".
DEPTH_SCALE_RANGE = (1e-3, 1e9)


def check_depth_scale(depth_scale: float, name: str = "depth_scale") -> float:
    """``depth_scale`` (raw units per metre) as a float within :data:`DEPTH_SCALE_RANGE`,
    else InputError naming it ``name`` (the option the user gave)."""
    try:
        s = float(depth_scale)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {depth_scale!r}") from None
    lo, hi = DEPTH_SCALE_RANGE
    if not lo <= s <= hi:  # (NaN too)
        raise InputError(
            f"{name} must be {lo:g}..{hi:g} raw units per metre (1000 = mm, 1 = metres), "
            f"got {depth_scale!r}"
        )
    return s


def check_frame_range(start: Any, stop: Any, n_frames: int, name: str) -> tuple[int, int]:
    """``(start, stop)`` of a frame range of a video of ``n_frames`` frames, checked.

    Parameters
    ----------
    start : int
        First frame read, ``0 <= start < n_frames``.
    stop : int or None
        One past the last frame read, ``start < stop <= n_frames``; None: ``n_frames``.
    n_frames : int
        T, frames of the video.
    name : str
        The video, for messages.

    Raises
    ------
    InputError
        Not integers, or an empty range or one beyond the video.
    """
    for label, v in (("start", start), ("stop", stop)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, np.integer))):
            raise InputError(f"{label} must be an integer frame index, got {v!r}")
    first = int(start)
    last = n_frames if stop is None else int(stop)
    if first < 0 or last > n_frames or first >= last:
        raise InputError(
            f"{name}: frames [{first}, {last}) are not a non-empty range of the "
            f"{n_frames} frame(s) of the video (0 <= start < stop <= {n_frames})"
        )
    return first, last


def natural_key(name: str) -> tuple[Any, ...]:
    """Sort key of file names in natural order (``frame2`` before ``frame10``), numbers with
    a fraction by their value (times in seconds: ``1700000000.0333333`` before
    ``1700000000.1``, whatever the number of decimals)."""
    # re.split with a capturing group alternates text, number, text, ...: same types compare
    parts = re.split(r"([0-9]+(?:\.[0-9]+)?)", name)
    return (*(Decimal(p) if i % 2 else p.casefold() for i, p in enumerate(parts)), name)


@contextlib.contextmanager
def reading(name: str) -> Iterator[None]:
    """Turn any failure of the parsing libraries into one readable InputError."""
    try:
        yield
    except InputError:
        raise
    except OSError as e:
        raise InputError(one_line(f"{name}: cannot read ({e.strerror or e})")) from None
    except MemoryError:
        raise InputError(f"{name}: too large to read in the memory available") from None
    except Exception as e:  # zipfile/zlib/numpy header parsing: all the user's data
        if "imagecodecs" in str(e):  # (tifffile: a compressed TIFF without the codecs)
            raise InputError(
                f"{name}: compressed with a codec that needs the imagecodecs package (pip "
                "install imagecodecs; the [io] extra has it)"
            ) from None
        raise InputError(
            one_line(f"{name}: corrupt or unreadable ({type(e).__name__}: {e})")
        ) from None


def check_array_meta(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
    """Refuse arrays that are not a non-empty numeric (T, h, w) video of sane frame size."""
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
