"""Depth from ROS bags: ROS 1 ``.bag`` files (RealSense ``.bag`` recordings included) and ROS 2
bag folders (holding ``metadata.yaml``), read with the pure-Python ``rosbags`` package (no ROS
installation; ``pip install 'upsr[io]'``).

Depth topics are ``sensor_msgs/Image`` topics with encoding ``16UC1`` (mm; a RealSense
recording's ``Depth Units`` option, in metres per unit, is applied when present) or ``32FC1``
(metres; NaN and ±inf mean no measurement, ROS REP 117), and ``mono16`` on a topic whose name
contains "depth" (RealSense ``Depth_0`` streams). ``is_bigendian`` and the row ``step``
(padding) are honoured. Without ``topic`` the only depth topic is read; with several, the
error lists them. The intrinsics come from the ``sensor_msgs/CameraInfo`` topic that shares the
longest namespace with the depth topic (``/camera/depth/image_raw`` →
``/camera/depth/camera_info``; RealSense: ``…/Depth_0/info/camera_info``).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from upsr.errors import InputError
from upsr.io._base import VideoInfo, reading
from upsr.io._common import check_frame_size
from upsr.io.registry import ReadOptions, require
from upsr.method.validation import as_depth_frame

__all__ = ["DEPTH_ENCODINGS", "decode_depth_image", "frames", "intrinsics", "probe"]

#: Encodings read as depth: (numpy type code, mm per raw unit).
DEPTH_ENCODINGS: dict[str, tuple[str, float]] = {
    "16uc1": ("u2", 1.0),
    "mono16": ("u2", 1.0),
    "32fc1": ("f4", 1000.0),
}
_IMAGE = "sensor_msgs/msg/Image"
_CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
_COMPRESSED = "sensor_msgs/msg/CompressedImage"


def _bag_path(path: Path) -> Path:
    if path.is_file() and path.suffix.lower() in (".db3", ".mcap"):
        return path.parent  # a storage file of a ROS 2 bag: the bag is its folder
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise InputError(f"{path}: a ROS 2 bag is a folder holding metadata.yaml; none here")
    if path.is_file() and path.suffix.lower() != ".bag":
        raise InputError(f"{path}: ROS 1 bags must be named *.bag")
    return path


@contextlib.contextmanager
def _open(path: Path) -> Iterator[Any]:
    require("rosbags", "reading ROS bags")
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    bag = _bag_path(path)
    with reading(str(path)):
        reader = AnyReader([bag], default_typestore=get_typestore(Stores.LATEST))
        reader.open()
    try:
        yield reader
    finally:
        with contextlib.suppress(Exception):
            reader.close()


def _first(reader: Any, conn: Any) -> Any:
    for c, _, raw in reader.messages(connections=[conn]):
        return reader.deserialize(raw, c.msgtype)
    return None


def _is_depth(topic: str, encoding: str) -> bool:
    enc = encoding.lower()
    return enc in DEPTH_ENCODINGS and (enc != "mono16" or "depth" in topic.lower())


def _depth_connection(reader: Any, topic: str | None, name: str) -> tuple[Any, Any]:
    """(connection, first message) of the depth topic."""
    images = [c for c in reader.connections if c.msgtype == _IMAGE]
    if topic is not None:
        chosen = [c for c in reader.connections if c.topic == topic]
        if not chosen:
            topics = ", ".join(sorted({c.topic for c in images})) or "none"
            raise InputError(f"{name}: no topic {topic!r} (image topics: {topics})")
        if chosen[0].msgtype != _IMAGE:
            raise InputError(
                f"{name}: topic {topic!r} holds {chosen[0].msgtype}, not sensor_msgs/Image"
            )
        images = chosen
    found: list[tuple[Any, Any]] = []
    others: list[str] = []
    seen: set[str] = set()
    for c in images:
        if c.topic in seen:
            continue
        seen.add(c.topic)
        msg = _first(reader, c)
        if msg is None:
            others.append(f"{c.topic} (no messages)")
        elif _is_depth(c.topic, str(msg.encoding)):
            found.append((c, msg))
        else:
            others.append(f"{c.topic} ({msg.encoding})")
    if not found:
        compressed = sorted({c.topic for c in reader.connections if c.msgtype == _COMPRESSED})
        hint = (
            f"; compressed image topics are not supported: {', '.join(compressed)}"
            if compressed
            else ""
        )
        what = f"topic {topic!r} is not" if topic is not None else "no topic is"
        raise InputError(
            f"{name}: {what} a depth image (sensor_msgs/Image with encoding 16UC1, 32FC1, "
            f"or mono16 on a depth topic); image topics: {', '.join(others) or 'none'}{hint}"
        )
    if len(found) > 1:
        names = ", ".join(c.topic for c, _ in found)
        raise InputError(f"{name}: several depth topics ({names}): choose one with --topic")
    return found[0]


def decode_depth_image(
    msg: Any, *, units_mm: float | None = None, name: str = "image"
) -> np.ndarray:
    """A ``sensor_msgs/Image`` depth message → float32 (h, w) depth in mm (0 = none).

    Parameters
    ----------
    msg : sensor_msgs/Image
        Fields ``height``, ``width``, ``encoding``, ``is_bigendian``, ``step``, ``data``.
    units_mm : float, optional
        mm per raw unit of 16-bit encodings (default 1; RealSense: Depth Units × 1000).
    name : str
        For error messages.

    Raises
    ------
    InputError
        Unknown encoding, inconsistent size/step, too little data.
    """
    enc = str(msg.encoding).lower()
    if enc not in DEPTH_ENCODINGS:
        raise InputError(f"{name}: encoding {msg.encoding!r} is not depth (16UC1, 32FC1)")
    code, mm_per_unit = DEPTH_ENCODINGS[enc]
    if code == "u2" and units_mm is not None:
        mm_per_unit = units_mm
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    check_frame_size(name, h, w)
    bpp = np.dtype(code).itemsize
    if step < w * bpp:
        raise InputError(f"{name}: row step {step} < width {w} x {bpp} bytes")
    data = np.asarray(msg.data, dtype=np.uint8).reshape(-1)
    need = (h - 1) * step + w * bpp
    if data.size < need:
        raise InputError(
            f"{name}: truncated image: {w}x{h} with step {step} needs {need} bytes, "
            f"the message holds {data.size}"
        )
    if data.size < h * step:
        data = np.concatenate([data, np.zeros(h * step - data.size, np.uint8)])
    rows = data[: h * step].reshape(h, step)[:, : w * bpp]
    dtype = np.dtype(code).newbyteorder(">" if msg.is_bigendian else "<")
    raw = np.ascontiguousarray(rows).view(dtype).reshape(h, w).astype(np.float32)
    if code == "f4":
        raw[~np.isfinite(raw)] = 0.0  # REP 117: NaN invalid, -inf too close, +inf too far
    if mm_per_unit != 1.0:
        raw *= np.float32(mm_per_unit)
    return raw


def _namespace_score(a: str, b: str) -> int:
    pa, pb = a.strip("/").split("/"), b.strip("/").split("/")
    n = 0
    for x, y in zip(pa, pb, strict=False):
        if x != y:
            break
        n += 1
    return n


def _best_match(reader: Any, depth_topic: str, msgtype: str, suffix: str = "") -> Any:
    conns = [
        c
        for c in reader.connections
        if c.msgtype == msgtype and (not suffix or c.topic.endswith(suffix))
    ]
    if not conns:
        return None
    conns.sort(key=lambda c: (-_namespace_score(c.topic, depth_topic), c.topic))
    best = conns[0]
    if _namespace_score(best.topic, depth_topic) == 0 and len(conns) > 1:
        return None  # ambiguous: none shares a namespace with the depth topic
    return best


def _depth_units_mm(reader: Any, depth_topic: str, name: str) -> float | None:
    """RealSense: mm per raw unit from ``…/option/Depth Units/value`` (std_msgs/Float32)."""
    conn = _best_match(reader, depth_topic, "std_msgs/msg/Float32", "option/Depth Units/value")
    if conn is None:
        return None
    with reading(name):
        msg = _first(reader, conn)
    if msg is None:
        return None
    units = float(msg.data)
    if not (np.isfinite(units) and 0 < units < 1):
        raise InputError(f"{name}: RealSense Depth Units {units!r} m is not a valid unit")
    return units * 1000.0


def probe(path: Path, opts: ReadOptions, fmt: str = "rosbag") -> VideoInfo:
    """Describe the depth topic of a bag (its first message decoded)."""
    name = str(path)
    with _open(path) as reader, reading(name):
        conn, msg = _depth_connection(reader, opts.topic, name)
        frame = decode_depth_image(msg, name=f"{name} {conn.topic} message 0")
        count = sum(c.msgcount for c in reader.connections if c.topic == conn.topic)
    dtype = np.dtype(DEPTH_ENCODINGS[str(msg.encoding).lower()][0])
    return VideoInfo(count, frame.shape[0], frame.shape[1], dtype, "rosbag", topic=conn.topic)


def frames(
    path: Path,
    opts: ReadOptions,
    fmt: str = "rosbag",
    start: int = 0,
    stop: int | None = None,
) -> Iterator[np.ndarray]:
    """Depth frames ``start`` … ``stop - 1`` (float32 mm) of the bag's depth topic, in time
    order. Messages before ``start`` are skipped by index, never deserialised."""
    name = str(path)
    with _open(path) as reader:
        with reading(name):
            conn, _ = _depth_connection(reader, opts.topic, name)
            units = _depth_units_mm(reader, conn.topic, name)
            conns = [c for c in reader.connections if c.topic == conn.topic]
            messages = reader.messages(connections=conns)
            for _ in range(start):
                if next(messages, None) is None:
                    return
        shape = None
        k = start
        while stop is None or k < stop:
            label = f"{name} {conn.topic} message {k}"
            with reading(label):
                item = next(messages, None)
                if item is None:
                    break
                c, _, raw = item
                msg = reader.deserialize(raw, c.msgtype)
                frame = decode_depth_image(msg, units_mm=units, name=label)
            if shape is None:
                shape = frame.shape
            elif frame.shape != shape:
                raise InputError(
                    f"{label}: frame size {frame.shape[1]}x{frame.shape[0]} differs from the "
                    f"first message's {shape[1]}x{shape[0]}"
                )
            yield as_depth_frame(frame, name=label)
            k += 1


def intrinsics(path: Path, opts: ReadOptions, fmt: str = "rosbag") -> Any:
    """The depth camera's intrinsics from its CameraInfo topic, or None.

    Returns
    -------
    upsr.research.synth.render.PinholeCamera or None
        fx, fy, cx, cy from K (ROS pixel coordinates: pixel (i, j) centred at (u, v) = (j, i),
        as in SPEC §1), width and height of the depth images.
    """
    from upsr.geometry.camera import PinholeCamera

    name = str(path)
    with _open(path) as reader, reading(name):
        conn, msg = _depth_connection(reader, opts.topic, name)
        info_conn = _best_match(reader, conn.topic, _CAMERA_INFO)
        if info_conn is None:
            return None
        info = _first(reader, info_conn)
    if info is None:
        return None
    k = np.asarray(getattr(info, "k", getattr(info, "K", None)), dtype=np.float64).reshape(-1)
    h, w = int(msg.height), int(msg.width)
    if k.size != 9 or not np.isfinite(k).all() or k[0] <= 0 or k[4] <= 0:
        return None  # an uncalibrated camera publishes K = 0
    iw, ih = int(info.width), int(info.height)
    if (iw, ih) not in ((0, 0), (w, h)):
        raise InputError(
            f"{name}: camera info {info_conn.topic} is for {iw}x{ih} images, the depth images "
            f"are {w}x{h}"
        )
    return PinholeCamera(float(k[0]), float(k[4]), float(k[2]), float(k[5]), w, h)
