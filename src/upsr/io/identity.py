"""Frame identity: the names and timestamps that pair each depth frame with its colour frame.

Readers
    :func:`read_timestamps` (int64 ns per frame, or None) and :func:`read_frame_names` (the file
    stems of a folder input, natural order, or None).
Writers
    :class:`upsr.io.VideoWriter` takes ``frame_names=`` (PNG/EXR folder outputs keep them:
    ``NAME.png`` instead of ``000000.png``), ``timestamps_ns=`` (``.npz`` outputs get a
    ``timestamps`` int64 array in ns, ROS bags stamp their messages) and ``camera=`` (ROS bags
    write a ``sensor_msgs/CameraInfo``); :func:`finish_output` is what it runs on the complete
    temporary before moving it into place. ``OUTPUT.intrinsics.json`` carries the timestamps
    too (:func:`upsr.geometry.intrinsics.write_intrinsics` ``timestamps_ns=``).

Where timestamps come from
    ROS bags: the depth messages' header stamps (RealSense: the SDK's frame times);
    ``.npz``: its ``timestamps`` array (ns, int); otherwise a ``<path>.intrinsics.json``
    beside the input holding ``timestamps_ns`` (what upsr writes beside its outputs where the
    intrinsics are known); otherwise, for folders, the frame names when they are all times in
    seconds with a fraction (TUM RGB-D ``1305031102.175304.png``; plain numbers such as
    ``000000.png`` count frames, they are not times).
"""

from __future__ import annotations

import json
import os
import re
import zipfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from upsr.errors import InputError
from upsr.io._base import PathLike, sync_file

__all__ = [
    "check_frame_names",
    "check_timestamps",
    "finish_output",
    "first_step_back",
    "read_frame_names",
    "read_timestamps",
]

_FOLDER_SUFFIX = {"png": ".png", "exr": ".exr"}
#: A frame name that is a time in seconds (TUM RGB-D's ``1305031102.175304``): a decimal point
#: and a fraction; a plain number (``000000``, upsr's own folder names) counts frames.
_SECONDS = re.compile(r"^[0-9]+\.[0-9]+$")


def _fmt(path: Path, fmt: str | None) -> str:
    from upsr.io.video import _input_format

    return _input_format(path, fmt)


def read_frame_names(path: PathLike, *, fmt: str | None = None) -> list[str] | None:
    """The frame names (file stems, natural order) of a folder input; None for other inputs.

    Examples: a folder ``rgbd/`` of ``1305031102.175304.png``, … gives
    ``["1305031102.175304", …]``.
    """
    p = Path(path)
    f = _fmt(p, fmt)
    if not p.is_dir() or f == "rosbag":
        return None
    from upsr.io import registry
    from upsr.io._common import frame_files

    if f in ("png", "tum", "sun"):
        from upsr.io.png import frame_files as png_files

        files = png_files(p)
    else:
        files = frame_files(p, registry.get(f).suffixes, f.upper())
    return [x.stem for x in files]


def read_timestamps(
    path: PathLike, *, fmt: str | None = None, topic: str | None = None, key: str | None = None
) -> np.ndarray | None:
    """int64 (T,) frame times in ns, or None when the input carries none (see module doc)."""
    from upsr.io.registry import ReadOptions, module

    p = Path(path)
    f = _fmt(p, fmt)
    out: np.ndarray | None = None
    if f == "rosbag":
        out = module("rosbag").timestamps(p, ReadOptions(topic=topic), f)
    elif f == "npz":
        out = _npz_timestamps(p)
    if out is None:
        out = _sidecar_timestamps(p)
    if out is None and p.is_dir():
        names = read_frame_names(p, fmt=f) or []
        if names and all(_SECONDS.match(n) for n in names):
            out = np.asarray([_seconds_to_ns(n) for n in names], np.int64)
    return out


def _sidecar_timestamps(path: Path) -> np.ndarray | None:
    """The ``timestamps_ns`` of ``<path>.intrinsics.json`` (what upsr wrote beside an output
    of a video that had them), or None."""
    from upsr.io.video import intrinsics_path

    side = intrinsics_path(path)
    if not side.is_file():
        return None
    try:
        d = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if isinstance(d, dict) and isinstance(d.get("timestamps_ns"), list):
        return np.asarray(d["timestamps_ns"], np.int64)
    return None


def _seconds_to_ns(text: str) -> int:
    whole, _, frac = text.partition(".")
    return int(whole) * 1_000_000_000 + int((frac + "000000000")[:9])


def _npz_timestamps(path: Path) -> np.ndarray | None:
    from upsr.io._base import reading

    with reading(str(path)), zipfile.ZipFile(path) as zf:
        if "timestamps.npy" not in zf.namelist():
            return None
        if zf.getinfo("timestamps.npy").file_size > 1 << 30:
            raise InputError(f"{path}: timestamps array too large")
        with zf.open("timestamps.npy") as fh:
            ts = np.lib.format.read_array(fh, allow_pickle=False)
    if ts.ndim != 1 or ts.dtype.kind not in "iu":
        raise InputError(f"{path}: 'timestamps' must be a 1-D integer array of ns, got {ts.dtype}")
    return ts.astype(np.int64)


def check_frame_names(names: Sequence[str], n_frames: int | None = None) -> list[str]:
    """Frame names usable as file names: unique, no folders, not hidden, ``n_frames`` of them."""
    out = [str(n) for n in names]
    for n in out:
        if not n or n.startswith(".") or "/" in n or "\\" in n or "\0" in n or n in ("..",):
            raise InputError(f"frame name {n!r} cannot be a file name")
    if len(set(out)) != len(out):
        raise InputError("frame names repeat: each output frame needs its own name")
    if n_frames is not None and len(out) != n_frames:
        raise InputError(f"{len(out)} frame names for {n_frames} frames")
    return out


def check_timestamps(stamps: Sequence[int] | np.ndarray, n_frames: int | None = None) -> np.ndarray:
    """int64 ns, one per frame, as recorded (a camera's clock may go back: a reset;
    :func:`first_step_back` finds where)."""
    ts = np.asarray(stamps)
    if ts.ndim != 1 or (ts.size and ts.dtype.kind not in "iu"):
        raise InputError("timestamps must be a 1-D sequence of integer ns")
    ts = ts.astype(np.int64)
    if n_frames is not None and ts.size != n_frames:
        raise InputError(f"{ts.size} timestamps for {n_frames} frames")
    return ts


def first_step_back(stamps: Sequence[int] | np.ndarray | None) -> int | None:
    """The first frame whose timestamp is earlier than its predecessor's, or None."""
    if stamps is None or len(stamps) < 2:
        return None
    back = np.flatnonzero(np.diff(np.asarray(stamps, np.int64)) < 0)
    return int(back[0]) + 1 if back.size else None


def finish_output(
    fmt: str,
    temp: Path,
    n_frames: int,
    *,
    frame_names: Sequence[str] | None = None,
    timestamps_ns: Sequence[int] | np.ndarray | None = None,
) -> None:
    """On a complete temporary output: name folder frames, add ``timestamps`` to a ``.npz``."""
    if frame_names is not None and fmt in _FOLDER_SUFFIX and temp.is_dir():
        names = check_frame_names(frame_names, n_frames)
        suffix = _FOLDER_SUFFIX[fmt]
        for t in range(len(names)):  # via hidden names: a new name may be an old 000000
            os.replace(temp / f"{t:06d}{suffix}", temp / f".{t:06d}.tmp")
        for t, name in enumerate(names):
            os.replace(temp / f".{t:06d}.tmp", temp / f"{name}{suffix}")
    if timestamps_ns is not None and fmt == "npz":
        ts = check_timestamps(timestamps_ns, n_frames)
        with zipfile.ZipFile(temp, "a", zipfile.ZIP_DEFLATED) as zf:
            with zf.open("timestamps.npy", "w") as member:
                np.lib.format.write_array(member, ts, allow_pickle=False)
        sync_file(temp)
