"""The depth file formats of :mod:`upsr.io`: one module per format, registered here.

Every command reads and writes depth through :func:`upsr.io.probe`, :func:`upsr.io.iter_frames`,
:func:`upsr.io.read_video` and :class:`upsr.io.VideoWriter`; those dispatch to the modules of
this package for the formats below (see :data:`REGISTRY`). Each format module provides

``probe(path, opts) -> VideoInfo``
    Validate the container cheaply (headers only) and describe it.
``frames(path, opts, fmt, start=0, stop=None) -> Iterator[ndarray]``
    The frames ``start`` … ``stop - 1``, one at a time, as float32 (h, w) depth in mm
    (0 = no measurement), skipping the earlier frames as cheaply as the format allows.
``intrinsics(path, opts) -> PinholeCamera | None`` (optional)
    The camera intrinsics when the format carries them.
``writes_folder(dest) -> bool`` and ``FrameSink`` (writable formats)
    Whether an output is a folder, and the writer that streams frames into a temporary file
    or folder that :class:`upsr.io.VideoWriter` renames into place when the video is complete
    (one constructor signature for all formats: :class:`upsr.io._base.FrameSink`).

The heavy libraries (tifffile, OpenEXR, rosbags) are optional: ``pip install 'upsr[io]'``.
A format whose library is missing raises :class:`~upsr.errors.InputError` saying what to
install.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

from upsr.errors import InputError

__all__ = [
    "REGISTRY",
    "Format",
    "ReadOptions",
    "detect_file",
    "detect_folder",
    "get",
    "module",
    "require",
]


@dataclass(frozen=True)
class ReadOptions:
    """Options of the readers.

    Attributes
    ----------
    key : str or None
        ``.npz``: the array; EXR: the channel (default: ``Z``, ``depth``, … or the only one).
    depth_scale : float
        Raw units per metre of formats that store raw numbers (PNG, TIFF, EXR, plain PGM,
        npy/npz arrays):
        mm = raw · 1000 / depth_scale. 1000 (the default): the files hold mm; 1: metres.
        Ignored by formats whose units are fixed (TUM, NYU, SUN RGB-D, ROS bags).
    topic : str or None
        ROS bags: the depth image topic (default: the only depth topic).
    """

    key: str | None = None
    depth_scale: float = 1000.0
    topic: str | None = None

    @property
    def mm_per_unit(self) -> float:
        """The raw unit in mm, 1000 / ``depth_scale`` (the readers' ``as_depth_frame``)."""
        return 1000.0 / self.depth_scale


@dataclass(frozen=True)
class Format:
    """A registered depth format.

    Attributes
    ----------
    name : str
        What ``fmt=`` / ``--input-format`` / ``--format`` call it.
    description : str
        One line for help texts.
    suffixes : tuple of str
        File suffixes (lower case, with the dot) that select it by default.
    module : str
        Submodule of :mod:`upsr.io.registry` implementing it.
    writable : bool
        Has a ``FrameSink`` (can be an output).
    folder : bool
        A folder of such files (natural name order) is a video.
    """

    name: str
    description: str
    suffixes: tuple[str, ...]
    module: str
    writable: bool = False
    folder: bool = True


#: Every format, by name (the order of the help texts).
REGISTRY: dict[str, Format] = {
    f.name: f
    for f in (
        Format(
            "npy",
            "NumPy .npy, one (T, h, w) array of depth in mm or raw/depth-scale = m (any dtype)",
            (".npy",),
            "npy",
            writable=True,
            folder=False,
        ),
        Format(
            "npz",
            "NumPy .npz, the array depth, else the first video (or --key), as .npy",
            (".npz",),
            "npz",
            writable=True,
            folder=False,
        ),
        Format(
            "png",
            "16-bit grayscale PNG frames (raw/depth-scale = m), a folder or one file",
            (".png",),
            "png",
            writable=True,
        ),
        Format(
            "tiff",
            "TIFF, one frame per page (float or 16-bit integer; raw/depth-scale = m), "
            "or a folder of TIFFs",
            (".tif", ".tiff"),
            "tiff",
            writable=True,
        ),
        Format(
            "exr",
            "OpenEXR, one frame per file (channel Z/depth/…; raw/depth-scale = m), "
            "or a folder of EXRs",
            (".exr",),
            "exr",
            writable=True,
        ),
        Format(
            "rosbag",
            "ROS 1 .bag (RealSense .bag included), ROS 2 bag folder or RealSense .db3: a depth "
            "image topic (16UC1 mm, 32FC1 m; compressedDepth / 16-bit PNG compressed); "
            "written as a ROS 2 bag folder (32FC1 m + CameraInfo)",
            (".bag", ".db3"),
            "rosbag",
            writable=True,
            folder=False,
        ),
        Format(
            "nyu",
            "NYU Depth v2 raw Kinect disparity, 16-bit big-endian PGM (depth = 351.3 / "
            "(1092.5 - raw) m)",
            (".pgm",),
            "datasets",
        ),
        Format("pgm", "16-bit PGM of depth (raw/depth-scale = m)", (), "datasets"),
        Format("tum", "TUM RGB-D 16-bit PNG (raw / 5000 = m)", (), "datasets"),
        Format("sun", "SUN RGB-D 16-bit PNG (bits rotated by 3, mm)", (), "datasets"),
    )
}

_EXTRAS = {"tifffile": "io", "OpenEXR": "io", "rosbags": "io", "plyfile": "io"}
_PACKAGES = {"OpenEXR": "openexr"}


def require(module_name: str, what: str) -> ModuleType:
    """Import an optional dependency or raise an InputError saying how to install it.

    Parameters
    ----------
    module_name : str
        Module to import (``"tifffile"``, ``"OpenEXR"``, ``"rosbags"``, ``"plyfile"``).
    what : str
        What needs it, for the message (``"reading TIFF files"``).
    """
    try:
        return importlib.import_module(module_name)
    except ImportError:
        package = _PACKAGES.get(module_name, module_name)
        extra = _EXTRAS.get(module_name, "all")
        raise InputError(
            f"{what} needs the optional package {package!r}: pip install 'upsr[{extra}]'"
        ) from None


def get(name: str) -> Format:
    """The registered format called ``name`` (KeyError if none)."""
    return REGISTRY[name]


def module(name: str) -> Any:
    """The implementation module of the registered format ``name``."""
    return importlib.import_module(f"upsr.io.{REGISTRY[name].module}")


def detect_file(path: Path) -> str | None:
    """Format of a file from its suffix (None: not one of this package's).

    A ``.db3`` file is a ROS 2 bag (its folder's when it holds ``metadata.yaml``, else the file
    alone, as librealsense 2.59+ records); an ``.mcap`` file inside a ROS 2 bag folder is the
    bag.
    """
    suffix = path.suffix.lower()
    if suffix == ".mcap" and (path.parent / "metadata.yaml").is_file():
        return "rosbag"
    for f in REGISTRY.values():
        if suffix in f.suffixes:
            return f.name
    return None


def _files(folder: Path) -> Iterator[str]:
    with os.scandir(folder) as it:
        for e in it:
            if not e.name.startswith(".") and e.is_file():
                yield e.name


def detect_folder(folder: Path) -> str | None:
    """Format of a folder: a ROS 2 bag (``metadata.yaml``) or frames of one format.

    Returns None for a folder holding PNG files or no frames of a format of this package (the
    PNG reader of :mod:`upsr.io` then reads it or explains what is wrong).

    Raises
    ------
    InputError
        The folder mixes frames of several formats.
    """
    if (folder / "metadata.yaml").is_file():
        return "rosbag"
    try:
        names = list(_files(folder))
    except OSError as e:
        raise InputError(f"{folder}: cannot list ({e.strerror or e})") from None
    found: dict[str, str] = {}
    for n in names:
        suffix = os.path.splitext(n)[1].lower()  # (the name as it is, for the message)
        if suffix == ".png":
            found.setdefault("png", n)
            continue
        for f in REGISTRY.values():
            if f.folder and suffix in f.suffixes:
                found.setdefault(f.name, n)
    if len(found) > 1:
        kinds = ", ".join(f"{k} ({v})" for k, v in sorted(found.items()))
        raise InputError(
            f"{folder}: the folder mixes frames of several formats: {kinds}; "
            f"keep one kind of depth frame per folder"
        )
    if not found or "png" in found:
        return None
    return next(iter(found))
