"""Depth video input/output, streamed frame by frame: the entry points of :mod:`upsr.io`.

:func:`probe`, :func:`iter_frames` (a whole video or a frame range ``start``/``stop``),
:func:`read_video` and :class:`VideoWriter` choose the format by the path (or ``fmt=``) and
dispatch to its module (:mod:`upsr.io.npy`, :mod:`upsr.io.npz`, :mod:`upsr.io.png`,
:mod:`upsr.io.tiff`, :mod:`upsr.io.exr`, :mod:`upsr.io.rosbag`, :mod:`upsr.io.datasets`)
through :mod:`upsr.io.registry`; every module has the reader functions and, when writable,
the ``FrameSink`` of :mod:`upsr.io._base`. The three basic containers:

``.npy`` (``fmt="npy"``)
    One (T, h, w) array of depth in mm, any integer or float dtype. Read through a memory map
    (``np.load(mmap_mode="r", allow_pickle=False)``): frames are read one at a time.
``.npz`` (``fmt="npz"``)
    The array named ``key``; by default ``depth``, else the first that holds a (T, h, w)
    video (e.g. beside ``timestamps``). Frames are decompressed one at a time. Written with
    the key ``"depth"``.
a folder of PNG files (``fmt="png"``)
    One 16-bit single-channel (grayscale) PNG per frame, in natural name order
    (``frame2.png`` before ``frame10.png``). A raw value v means ``v / depth_scale`` metres,
    i.e. ``v * 1000 / depth_scale`` mm: ``depth_scale=1000`` (the default) for PNGs in mm,
    ``5000`` for the TUM RGB-D benchmark. A single ``.png`` file is read as a 1-frame video.
    Written as ``000000.png``, ``000001.png``, …, or one frame to a ``.png`` file.

``depth_scale`` (raw units per metre) applies to PNG, TIFF, EXR and PGM frames and to
``.npy``/``.npz`` input arrays (mm by default; outputs always hold mm).
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
import os
import stat
import weakref
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
import numpy.typing as npt

from upsr._atomic import (
    AtomicWriter,
    new_temp_dir,
    new_temp_file,
    publish,
    remove,
    remove_stale,
    temp_name,
    write_bytes_atomic,
    write_text_atomic,
)
from upsr.errors import InputError
from upsr.io._base import (
    FORMATS,
    WRITE_FORMATS,
    PathLike,
    VideoInfo,
    check_depth_scale,
    check_fmt,
    check_frame_range,
    check_input_type,
)
from upsr.io.paths import check_output_path
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


def _format_module(fmt: str) -> Any:
    """The module implementing ``fmt`` (:mod:`upsr.io.npy`, :mod:`upsr.io.tiff`, …)."""
    from upsr.io import registry

    return registry.module(fmt)


def _input_format(path: Path, fmt: str | None) -> str:
    # by type, before anything opens it (a FIFO with no writer would block open() for ever)
    is_dir = stat.S_ISDIR(check_input_type(path).st_mode)
    from upsr.io import registry as formats

    if fmt is not None:
        f = check_fmt(fmt)
    elif is_dir:
        f = formats.detect_folder(path) or "png"
    else:
        suffix = path.suffix.lower()
        f = suffix[1:] if suffix in (".npy", ".npz", ".png") else formats.detect_file(path)
        if f is None and path.name.lower().endswith(".bag.active"):
            raise InputError(
                f"{path}: a ROS 1 bag still being recorded, or cut short: `rosbag reindex` "
                "repairs it, then name it .bag"
            )
        if f is None:
            raise InputError(
                f"{path}: unknown input format {path.suffix or '(no suffix)'!r} (npy, npz, "
                f"PNG frames, or --input-format {', '.join(FORMATS[3:])})"
            )
    if f in ("npy", "npz") and is_dir:
        raise InputError(f"{path}: is a folder, not a .{f} file")
    return f


def _output_format(path: Path, fmt: str | None) -> str:
    if fmt is not None:
        f = check_fmt(fmt)
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
    if suffix == ".png" or suffix == "" or path.is_dir():
        return "png"
    bag = " (--format rosbag: a ROS 2 bag folder)" if suffix in (".db3", ".bag", ".mcap") else ""
    raise InputError(
        f"{path}: unknown output format {path.suffix!r}: use a .npy, .npz, .tif, .exr or .png "
        f"file or a folder name (no suffix) for 16-bit PNG frames (--format exr: EXR "
        f"frames){bag}"
    )


def _folder_output(fmt: str, path: Path) -> bool:
    """Whether the output of format ``fmt`` at ``path`` is a folder of frame files."""
    return bool(_format_module(fmt).writes_folder(path))


# ---------------------------------------------------------------------------------------------
# readers
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
    from upsr.io.registry import ReadOptions

    p = Path(path)
    f = _input_format(p, fmt)
    _check_key_topic(f, key, topic)
    return _format_module(f).probe(p, ReadOptions(key=key, topic=topic), f)  # type: ignore[no-any-return]


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
    start: int = 0,
    stop: int | None = None,
) -> Iterator[np.ndarray]:
    """Read a depth video, or the frames ``start`` … ``stop - 1`` of it, one frame at a time.

    The container is validated (as by :func:`probe`) when this function is called; the frames
    are read lazily. The frames before ``start`` are skipped as cheaply as the format allows:
    ``.npy`` starts at their byte offset, ``.npz`` drops their decompressed bytes unconverted,
    folders of PNG, PGM, TIFF or EXR frames open only the files of the range (multi-page TIFFs
    and multi-part EXRs only count the pages before it), ROS bags skip messages by index
    without deserialising them.

    Parameters
    ----------
    path, key, fmt, topic
        As for :func:`probe`.
    depth_scale : float
        PNG, TIFF, EXR and plain PGM frames, ``.npy``/``.npz`` arrays: raw units per metre
        (1000: mm, TUM: 5000, metres: 1); mm = raw · 1000 / depth_scale. Formats whose units
        are fixed (ROS bags, ``nyu``, ``tum``, ``sun``) refuse any other value than 1000.
    start : int
        First frame read (0 ≤ start < T).
    stop : int, optional
        One past the last frame read (start < stop ≤ T; default T).

    Yields
    ------
    ndarray float32 (h, w)
        Depth in mm, invalid pixels (0 or NaN) set to 0.

    Raises
    ------
    InputError
        As :func:`probe`; a range that is empty or not inside the video; while iterating:
        ±inf or negative depths (naming the frame), corrupt data; after the last frame of a
        whole video: no valid depth in any of its frames (a range may have none).
    """
    from upsr.io.registry import ReadOptions

    p = Path(path)
    scale = check_depth_scale(depth_scale)
    f = _input_format(p, fmt)
    _check_key_topic(f, key, topic)
    opts = ReadOptions(key=key, depth_scale=scale, topic=topic)
    if scale != 1000.0 and f not in SCALED_FORMATS + ARRAY_FORMATS + ("rosbag",):
        raise InputError(
            f"{p}: a depth scale ({scale:g} units/m) does not apply to {f} input, whose units "
            f"the format fixes"
        )
    impl = _format_module(f)
    info = impl.probe(p, opts, f)  # validate the container before the first frame is asked for
    first, last = check_frame_range(start, stop, info.n_frames, str(p))
    whole = (first, last) == (0, info.n_frames)
    if whole:
        frames = impl.frames(p, opts, f)
    else:
        frames = impl.frames(p, opts, f, start=first, stop=last)
    # (a range without depth is part of a video that may have some elsewhere)
    return _require_valid(frames, str(p)) if whole else frames


#: Formats whose readers turn raw values into mm with the depth scale themselves.
SCALED_FORMATS = ("png", "tiff", "exr", "pgm")
#: Formats of arrays in mm, or in raw units of ``depth_scale`` per metre when it is given.
ARRAY_FORMATS = ("npy", "npz")


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
    upsr.geometry.camera.PinholeCamera or None
        fx, fy, cx, cy (px; pixel (i, j) centred at (u, v) = (j, i), SPEC §1), width, height.
    """
    p = Path(path)
    f = _input_format(p, fmt)
    _check_key_topic(f, None, topic)
    impl = _format_module(f)
    if hasattr(impl, "intrinsics"):
        from upsr.io.registry import ReadOptions

        cam = impl.intrinsics(p, ReadOptions(topic=topic), f)
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
def _cleanup(temps: list[Path], created_dirs: list[Path]) -> None:
    for p in temps:
        remove(p)
    temps.clear()
    for d in reversed(created_dirs):  # innermost first; only if still empty
        with contextlib.suppress(OSError):
            d.rmdir()
    created_dirs.clear()


class VideoWriter(AtomicWriter):
    """Write a depth video frame by frame, atomically.

    Parameters
    ----------
    path : str or path-like
        ``.npy`` (float32 mm), ``.npz`` (float32 mm, key ``"depth"``), ``.tif``/``.tiff``
        (float32, one page per frame), ``.exr`` (one float32 ``Z`` frame), ``.png`` (one
        16-bit frame), or a folder name without suffix (16-bit PNG frames ``000000.png``, …;
        EXR frames with ``fmt="exr"``; a ROS 2 bag with ``fmt="rosbag"``).
    n_frames : int, optional
        Expected number of frames: writing more, or closing after fewer, raises InputError.
    fmt : {"npy", "npz", "png", "tiff", "exr", "rosbag"}, optional
        Force the format instead of guessing it from the path.
    depth_scale : float
        PNG: raw units per metre (1000: mm, TUM: 5000); raw = round(mm · depth_scale / 1000).
        Values above 65535 are clipped (with one warning); valid depths never round to 0.
        TIFF and EXR: the float value written is mm · depth_scale / 1000 (1000: mm, 1: m).
    overwrite : bool
        Replace an existing output (see :func:`check_output_path`).
    frame_names : sequence of str, optional
        PNG/EXR folder outputs: the frames' file names without suffix (e.g. the input's, from
        :func:`upsr.io.read_frame_names`) instead of ``000000``, …; ignored by file outputs.
    timestamps_ns : sequence of int, optional
        Frame times (ns): ``.npz`` outputs store them as ``timestamps``; ROS bags stamp their
        messages with them; other formats ignore them. Or give each frame's with
        :meth:`write` (a live stream, whose times are known as the frames come), not both.
    camera : PinholeCamera, optional
        ROS bag outputs: the output camera, written as ``sensor_msgs/CameraInfo``.

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
        frame_names: Sequence[str] | None = None,
        timestamps_ns: Sequence[int] | np.ndarray | None = None,
        camera: Any = None,
    ) -> None:
        from upsr.io.identity import check_frame_names, check_timestamps

        self.frame_names = None if frame_names is None else check_frame_names(frame_names, n_frames)
        self.timestamps_ns = None if timestamps_ns is None else check_timestamps(timestamps_ns)
        self.camera = camera
        self.path = Path(path)
        self.format = _output_format(self.path, fmt)
        self.depth_scale = check_depth_scale(depth_scale)
        if n_frames is not None and (isinstance(n_frames, bool) or int(n_frames) < 1):
            raise InputError(f"n_frames must be >= 1, got {n_frames!r}")
        self.n_frames = None if n_frames is None else int(n_frames)
        self.overwrite = bool(overwrite)
        check_output_path((), self.path, self.overwrite, fmt=self.format)
        self.frames_written = 0
        self._stamps: list[int] | None = None  # (the frames' own, given to write)
        self._shape: tuple[int, int] | None = None
        self._sink: Any = None
        self._temp: Path | None = None
        self._temps: list[Path] = []
        self._created: list[Path] = []
        self._sidecars: list[tuple[Path, Path]] = []
        self._closed = False
        self._finalizer = weakref.finalize(self, _cleanup, self._temps, self._created)

    # -- writing -------------------------------------------------------------------------------
    def _open(self, shape_px: tuple[int, int]) -> None:
        """Create the missing parent folders and the temporary; open the format's sink."""
        parent = Path(os.path.abspath(self.path)).parent
        missing = []
        d = parent
        while not d.exists():
            missing.append(d)
            d = d.parent
        for d in reversed(missing):
            os.mkdir(d)
            self._created.append(d)
        impl = _format_module(self.format)
        remove_stale(self.path)  # .part files and folders of dead writers (SIGKILL)
        fh: BinaryIO | None = None
        if impl.writes_folder(self.path):
            self._temp = new_temp_dir(self.path)
        else:
            self._temp, fh = new_temp_file(self.path)  # type: ignore[assignment]
        self._temps.append(self._temp)
        try:
            self._sink = impl.FrameSink(
                self.path,
                self._temp,
                fh,
                shape_px=shape_px,
                depth_scale=self.depth_scale,
                n_frames=self.n_frames,
            )
        except BaseException:
            if fh is not None:
                with contextlib.suppress(OSError):
                    fh.close()
            raise
        if hasattr(self._sink, "set_meta"):  # ROS bags: stamps and CameraInfo
            self._sink.set_meta(timestamps_ns=self.timestamps_ns, camera=self.camera)

    def write(self, frame: npt.ArrayLike, timestamp_ns: int | None = None) -> None:
        """Append one (h, w) depth frame in mm (0 or NaN = no measurement); with
        ``timestamp_ns``, its time (every frame's then, as recorded; not with the
        writer's ``timestamps_ns``)."""
        if self._closed:
            raise ValueError("write to a closed VideoWriter")
        t = self.frames_written
        f = as_depth_frame(frame, name=f"output frame {t}")
        self._check_stamp(t, timestamp_ns)
        if self.n_frames is not None and t >= self.n_frames:
            raise InputError(f"{self.path}: more than n_frames={self.n_frames} frames written")
        if self._shape is None:
            self._shape = f.shape
            self._open(f.shape)
        elif f.shape != self._shape:
            raise InputError(
                f"output frame {t}: shape {f.shape} differs from the first frame's {self._shape}"
            )
        if timestamp_ns is not None and self.format == "rosbag":  # (stamped with the frame)
            self._sink.write(f, t, stamp_ns=int(timestamp_ns))
        else:
            self._sink.write(f, t)
        self.frames_written = t + 1

    def _check_stamp(self, t: int, stamp: int | None) -> None:
        """A frame's own timestamp: given for every frame or none (kept as given, a clock
        that goes back included)."""
        given = self._stamps is not None
        if stamp is not None and self.timestamps_ns is not None:
            raise InputError(f"{self.path}: timestamps given to the writer and to frame {t}")
        if t > 0 and (stamp is not None) != given:
            had = "no timestamp (the first had)" if given else "a timestamp (the first none)"
            raise InputError(f"{self.path}: frame {t} has {had}")
        if stamp is None:
            return
        stamp = int(stamp)
        if self._stamps is None:
            self._stamps = []
        self._stamps.append(stamp)

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
            assert self._temp is not None and self._sink is not None
            self._sink.close()
            self._sink = None
            from upsr.io.identity import finish_output

            finish_output(
                self.format,
                self._temp,
                self.frames_written,
                frame_names=self.frame_names,
                timestamps_ns=self.timestamps_ns if self._stamps is None else self._stamps,
            )
            self._install()
        except BaseException:
            self.abort()
            raise
        self._closed = True
        self._finalizer.detach()

    def add_sidecar(self, path: PathLike, data: bytes | str) -> None:
        """Publish ``data`` at ``path`` together with the video (e.g. ``OUTPUT.intrinsics.json``).

        Written to a temporary now (a full disk fails here, before the video is complete) and
        moved into place just before the video, replacing an older sidecar: when the video is
        visible its sidecars are too; if the video cannot be published they are removed again.
        """
        if self._closed:
            raise ValueError("add_sidecar on a closed VideoWriter")
        dest = Path(path)
        raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
        dest.parent.mkdir(parents=True, exist_ok=True)
        tmp, fh = new_temp_file(dest, "tmp")
        self._temps.append(tmp)
        with fh:
            fh.write(raw)
            fh.flush()
            os.fsync(fh.fileno())
        self._sidecars.append((tmp, dest))

    def _install(self) -> None:
        tmp, dest = self._temp, self.path
        assert tmp is not None
        if not self.overwrite and os.path.lexists(dest):  # before touching its sidecars
            raise InputError(
                f"output {dest} already exists (use --overwrite / overwrite=True to replace it)"
            )
        published: list[Path] = []
        try:
            for side_tmp, side in self._sidecars:  # sidecars first: the video marks completion
                os.replace(side_tmp, side)
                published.append(side)
            self._install_video(tmp, dest)
        except InputError:  # another writer published this output meanwhile: its sidecars
            raise
        except BaseException:
            for side in published:
                remove(side)
            raise
        self._temps.clear()

    def _install_video(self, tmp: Path, dest: Path) -> None:
        exists_msg = (
            f"output {dest} already exists (use --overwrite / overwrite=True to replace it)"
        )
        if not self.overwrite:
            try:  # no-replace: of two writers finishing the same output, one fails here
                publish(tmp, dest, replace=False)
            except FileExistsError:
                raise InputError(exists_msg) from None
            return
        if os.path.lexists(dest):
            check_output_path((), dest, True, fmt=self.format)
            if _folder_output(self.format, dest) and not dest.is_symlink():
                trash = temp_name(dest, "old")
                os.replace(dest, trash)
                self._temps.append(trash)
                os.replace(tmp, dest)
                remove(trash)
                return
        publish(tmp, dest, replace=True)

    def abort(self) -> None:
        """Discard everything written; nothing appears at the output path. Idempotent."""
        if self._sink is not None:
            with contextlib.suppress(Exception):
                self._sink.abort()
            self._sink = None
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
    **meta: Any,
) -> Path:
    """Write a (T, h, w) depth video (array or iterable of frames) atomically; return the path.

    See :class:`VideoWriter` for the formats and options (``meta``: ``frame_names``,
    ``timestamps_ns``, ``camera``).
    """
    if isinstance(frames, np.ndarray):
        if frames.ndim != 3:
            raise InputError(f"expected a depth video of shape (T, h, w), got shape {frames.shape}")
        n: int | None = frames.shape[0]
    else:
        n = len(frames) if isinstance(frames, Sequence) else None
    with VideoWriter(
        path, n_frames=n, fmt=fmt, depth_scale=depth_scale, overwrite=overwrite, **meta
    ) as writer:
        for frame in frames:  # type: ignore[union-attr]
            writer.write(frame)
    return writer.path
