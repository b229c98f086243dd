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
import os
import re
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from upsr.errors import InputError
from upsr.io._base import VideoInfo, reading
from upsr.io._common import check_frame_size
from upsr.io._rosmsg import (
    CompressedMsg,
    ImageMsg,
    decode_compressed_depth,
    is_compressed_depth,
    parse_compressed,
    parse_image,
)
from upsr.io.registry import ReadOptions, require
from upsr.method.validation import as_depth_frame

__all__ = [
    "DEPTH_ENCODINGS",
    "FrameSink",
    "decode_depth_image",
    "frames",
    "intrinsics",
    "probe",
    "realsense_units_mm",
    "timestamps",
    "writes_folder",
]

#: Encodings read as depth: (numpy type code, mm per raw unit).
DEPTH_ENCODINGS: dict[str, tuple[str, float]] = {
    "16uc1": ("u2", 1.0),
    "mono16": ("u2", 1.0),
    "32fc1": ("f4", 1000.0),
}
_IMAGE = "sensor_msgs/msg/Image"
_CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
_COMPRESSED = "sensor_msgs/msg/CompressedImage"


_REALSENSE_UNITS = re.compile(r"option/Depth[ _]Units(/value)?$")


def _bag_path(path: Path) -> Path:
    if path.is_file() and path.suffix.lower() in (".db3", ".mcap"):
        if (path.parent / "metadata.yaml").is_file():
            return path.parent  # a storage file of a ROS 2 bag: the bag is its folder
        if path.suffix.lower() == ".mcap":
            raise InputError(f"{path}: an .mcap file is read inside its bag folder (metadata.yaml)")
        return path  # a lone .db3 (librealsense 2.59+): read from its sqlite tables
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise InputError(f"{path}: a ROS 2 bag is a folder holding metadata.yaml; none here")
    if path.is_file() and path.suffix.lower() != ".bag":
        raise InputError(f"{path}: ROS 1 bags must be named *.bag")
    return path


def _is_sqlite(path: Path) -> bool:
    """Whether a file is an SQLite database (a RealSense ``.db3`` recording renamed ``.bag``)."""
    with reading(str(path)), open(path, "rb") as fh:
        return fh.read(16) == b"SQLite format 3\x00"


@contextlib.contextmanager
def _open(path: Path) -> Iterator[Any]:
    require("rosbags", "reading ROS bags")
    bag = _bag_path(path)
    if bag.is_file() and (bag.suffix.lower() == ".db3" or _is_sqlite(bag)):
        from upsr.io._db3 import Db3Reader

        with reading(str(path)):
            reader: Any = Db3Reader(bag)
    else:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        with reading(str(path)):
            reader = AnyReader([bag], default_typestore=get_typestore(Stores.LATEST))
            try:
                reader.open()
            except Exception as e:  # (rosbags: "Bag index looks damaged")
                if "index" not in str(e).lower() or bag.is_dir():
                    raise
                raise InputError(
                    f"{path}: its index is damaged (a recording cut short?): `rosbag reindex` "
                    "repairs it"
                ) from None
    try:
        yield reader
    finally:
        with contextlib.suppress(Exception):
            reader.close()


def _is2(reader: Any) -> bool:
    return bool(getattr(reader, "is2", getattr(reader, "is_ros2", False)))


def _parse(reader: Any, conn: Any, raw: bytes, label: str) -> Any:
    """An Image / CompressedImage parsed tolerantly; other types through rosbags (a corrupt
    message's error names ``label``: the bag, the topic and the message)."""
    try:
        if conn.msgtype == _IMAGE:
            return parse_image(raw, cdr=_is2(reader))
        if conn.msgtype == _COMPRESSED:
            return parse_compressed(raw, cdr=_is2(reader))
        return reader.deserialize(raw, conn.msgtype)
    except InputError as e:
        raise InputError(f"{label}: {e}") from None


def _first(reader: Any, conn: Any) -> Any:
    for c, _, raw in reader.messages(connections=[conn]):
        return _parse(reader, c, raw, f"{_bag_name(reader)} {conn.topic} message 0")
    return None


def _bag_name(reader: Any) -> str:
    """The bag's path as its reader knows it (for error messages)."""
    paths = getattr(reader, "paths", None) or [getattr(reader, "path", "bag")]
    return str(paths[0])


def _is_depth(topic: str, msg: Any) -> bool:
    if isinstance(msg, CompressedMsg):
        return is_compressed_depth(msg.format)
    enc = str(msg.encoding).lower()
    return enc in DEPTH_ENCODINGS and (enc != "mono16" or "depth" in topic.lower())


def _describe(msg: Any) -> str:
    return msg.format if isinstance(msg, CompressedMsg) else str(msg.encoding)


def _depth_connection(reader: Any, topic: str | None, name: str) -> tuple[Any, Any]:
    """(connection, first message) of the depth topic."""
    images = [c for c in reader.connections if c.msgtype in (_IMAGE, _COMPRESSED)]
    if topic is not None:
        chosen = [c for c in reader.connections if c.topic == topic]
        if not chosen:
            topics = ", ".join(sorted({c.topic for c in images})) or "none"
            raise InputError(f"{name}: no topic {topic!r} (image topics: {topics})")
        if chosen[0].msgtype not in (_IMAGE, _COMPRESSED):
            raise InputError(
                f"{name}: topic {topic!r} holds {chosen[0].msgtype}, not sensor_msgs/Image "
                f"or sensor_msgs/CompressedImage"
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
        elif _is_depth(c.topic, msg):
            found.append((c, msg))
        else:
            others.append(f"{c.topic} ({_describe(msg)})")
    if not images:
        raise InputError(f"{name}: no image topic in it (an empty recording?)")
    if not found:
        what = f"topic {topic!r} is not" if topic is not None else "no topic is"
        raise InputError(
            f"{name}: {what} a depth image (sensor_msgs/Image with encoding 16UC1, 32FC1, "
            f"or mono16 on a depth topic; sensor_msgs/CompressedImage compressedDepth or "
            f"16-bit PNG); image topics: {', '.join(others) or 'none'}"
        )
    if len(found) > 1:
        # (the advice and the names before the bag's path: a long line is cut in its middle)
        names = ", ".join(c.topic for c, _ in found)
        raise InputError(
            f"{Path(name).name}: several depth topics, choose one with --topic: {names}"
        )
    return found[0]


def _decode(msg: Any, units_mm: float | None, name: str) -> np.ndarray:
    """A parsed depth message → float32 (h, w) mm."""
    if isinstance(msg, CompressedMsg):
        frame = decode_compressed_depth(msg, name)
        if msg.format.split(";")[0].strip().lower() != "32fc1" and units_mm is not None:
            frame *= np.float32(units_mm)
        return frame
    units = msg.depth_units_m if isinstance(msg, ImageMsg) else None
    return decode_depth_image(msg, units_mm=units * 1000.0 if units else units_mm, name=name)


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


def _camera_info_of(reader: Any, depth_topic: str) -> Any:
    """The CameraInfo connection of the depth topic's own camera: in its namespace
    (``/cam/depth/camera_info`` for ``/cam/depth/image_rect_raw``; RealSense's
    ``…/Depth_0/info/camera_info``), the deepest; None where there is none (a sibling
    camera's, ``/cam/color/camera_info``, was taken for the depth's)."""

    def namespace(topic: str) -> str:
        ns = topic.rstrip("/").rsplit("/", 1)[0]
        return ns[: -len("/info")] if ns.endswith("/info") else ns

    conns = [
        c
        for c in reader.connections
        if c.msgtype == _CAMERA_INFO and (depth_topic + "/").startswith(namespace(c.topic) + "/")
    ]
    conns.sort(key=lambda c: (-_namespace_score(c.topic, depth_topic), c.topic))
    return conns[0] if conns else None


def _depth_units_mm(reader: Any, depth_topic: str, name: str) -> float | None:
    """RealSense: mm per raw unit from its Depth Units option.

    The option topic is spelled ``…/option/Depth Units/value`` (librealsense < 2.5x),
    ``…/option/Depth_Units/value`` (2.5x) or ``…/option/Depth_Units`` ; its message is a
    std_msgs/Float32 (ROS 1 ``.bag``) or a std_msgs/String holding the number (``.db3``).
    """
    conns = [
        c
        for c in reader.connections
        if c.msgtype in ("std_msgs/msg/Float32", "std_msgs/msg/Float64", "std_msgs/msg/String")
        and _REALSENSE_UNITS.search(c.topic)
    ]
    if not conns:
        return None
    conns.sort(key=lambda c: (-_namespace_score(c.topic, depth_topic), c.topic))
    with reading(name):
        msg = _first(reader, conns[0])
    if msg is None:
        return None
    try:
        units = (
            float(str(msg.data).strip().split()[0])
            if isinstance(msg.data, str)
            else float(msg.data)
        )
    except (ValueError, IndexError):
        raise InputError(f"{name}: RealSense Depth Units {msg.data!r} is not a number") from None
    return realsense_units_mm(units, name)


def realsense_units_mm(units_m: float, name: str = "RealSense") -> float:
    """mm per raw unit of a RealSense Depth Units option (metres per unit).

    The value the camera was set to, whichever way it was stored: the SDK holds it as a
    float32 (0.0001 m reads 9.99999974738e-05), a ``.db3`` recording as text ("0.000100"), a
    ``.bag`` as a Float32. Rounded to 6 significant digits they agree, and so do the frames
    read from a recording and from the SDK playing it (a raw 6000 at 0.1 mm is 600.0 mm, not
    599.99994: thresholds of the method decide on such differences).

    Raises
    ------
    InputError
        Not a finite unit in (0, 1) m.
    """
    units = float(units_m)
    if not (np.isfinite(units) and 0 < units < 1):
        raise InputError(f"{name}: RealSense Depth Units {units_m!r} m is not a valid unit")
    return float(f"{units * 1000.0:.6g}")


def probe(path: Path, opts: ReadOptions, fmt: str = "rosbag") -> VideoInfo:
    """Describe the depth topic of a bag (its first message decoded)."""
    name = str(path)
    with _open(path) as reader, reading(name):
        conn, msg = _depth_connection(reader, opts.topic, name)
        frame = _decode(msg, None, f"{name} {conn.topic} message 0")
        count = sum(c.msgcount for c in reader.connections if c.topic == conn.topic)
    if isinstance(msg, CompressedMsg):
        enc = msg.format.split(";")[0].strip().lower()
        dtype = np.dtype("f4" if enc == "32fc1" else "u2")
    else:
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
            conn, first = _depth_connection(reader, opts.topic, name)
            units = _depth_units_mm(reader, conn.topic, name)
            # (RealSense .db3: each frame's own units, where its metadata gives them)
            meta = _realsense_meta(reader, conn.topic) or {}
            if opts.depth_scale != 1000.0:
                units = _given_units_mm(first, opts, units is not None or bool(meta), name)
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
                c, t, raw = item
                own = _meta_value(meta.get(t), "depth_units")
                frame_units = units if own is None else realsense_units_mm(own, label)
                frame = _decode(_parse(reader, c, raw, label), frame_units, label)
            if shape is None:
                shape = frame.shape
            elif frame.shape != shape:
                raise InputError(
                    f"{label}: frame size {frame.shape[1]}x{frame.shape[0]} differs from the "
                    f"first message's {shape[1]}x{shape[0]}"
                )
            yield as_depth_frame(frame, name=label)
            k += 1


def timestamps(path: Path, opts: ReadOptions, fmt: str = "rosbag") -> np.ndarray:
    """int64 (T,) time of every depth frame, ns.

    The header stamp of each depth message; RealSense recordings whose header stamps are not
    the frame times (``.db3`` of librealsense 2.59 holds the time since the recording began)
    take the ``timestamp=`` (ms) of each frame's ``…/image/metadata`` message (the one logged
    with it), which is what the SDK's playback reports (a frame without one: its header stamp
    on that clock, the median offset of the others); messages whose header stamps are all 0
    take the bag's receive times.
    """
    name = str(path)
    with _open(path) as reader, reading(name):
        conn, _ = _depth_connection(reader, opts.topic, name)
        conns = [c for c in reader.connections if c.topic == conn.topic]
        header, received = [], []
        for c, t, raw in reader.messages(connections=conns):
            header.append(_parse(reader, c, raw, f"{name} {conn.topic}").stamp_ns)
            received.append(t)
        meta = _realsense_meta(reader, conn.topic) or {}
    own = [_meta_value(meta.get(t), "timestamp") for t in received]
    known = [k for k, v in enumerate(own) if v is not None]
    if known:
        stamps = np.asarray([round(v * 1e6) if v is not None else 0 for v in own], np.int64)
        offset = int(np.median([stamps[k] - header[k] for k in known]))
        return np.where([v is None for v in own], np.asarray(header) + offset, stamps)
    if header and not any(header):
        return np.asarray(received, np.int64)
    return np.asarray(header, np.int64)


def check_given_scale(path: Path, opts: ReadOptions) -> None:
    """Refuse a depth scale given for this bag's depth topic (even 1000) where it would not
    be applied (:func:`_given_units_mm`)."""
    name = str(path)
    with _open(path) as reader, reading(name):
        conn, first = _depth_connection(reader, opts.topic, name)
        realsense = _depth_units_mm(reader, conn.topic, name) is not None
        _given_units_mm(first, opts, realsense or bool(_realsense_meta(reader, conn.topic)), name)


def _given_units_mm(msg: Any, opts: ReadOptions, realsense: bool, name: str) -> float:
    """mm per raw unit of a depth scale given for a bag: 16-bit depth recorded by a driver
    that publishes the camera's raw units rather than REP 118's mm (realsense-ros with a
    D405's 0.1 mm); refused for a RealSense recording (its frames carry their units) and for
    float depth (metres, REP 117)."""
    what = f"a depth scale ({opts.depth_scale:g} units/m) does not apply to"
    if realsense:
        raise InputError(f"{name}: {what} a RealSense recording, which carries its units")
    enc = msg.format.split(";")[0] if isinstance(msg, CompressedMsg) else msg.encoding
    if str(enc).strip().lower() == "32fc1":
        raise InputError(f"{name}: {what} 32FC1 depth, in metres (REP 117)")
    return opts.mm_per_unit


def _realsense_meta(reader: Any, depth_topic: str) -> dict[int, str] | None:
    """A RealSense ``.db3``'s ``…/image/metadata`` texts by log time (a frame's is logged with
    it), or None (none, or ROS 1 RealSense bags: KeyValue metadata, header stamps the times)."""
    m = re.match(r"(.*/Depth_\d+)/image/", depth_topic)
    if m is None:
        return None
    topic = m.group(1) + "/image/metadata"
    conns = [
        c for c in reader.connections if c.topic == topic and c.msgtype == "std_msgs/msg/String"
    ]
    if not conns:
        return None
    return {
        t: str(reader.deserialize(raw, c.msgtype).data)
        for c, t, raw in reader.messages(connections=conns)
    }


def _meta_value(text: str | None, key: str) -> float | None:
    """The number ``key=`` of a RealSense metadata text, or None."""
    found = None if text is None else re.search(rf"(?:^|;){key}=([0-9.eE+-]+)", text)
    try:
        return None if found is None else float(found.group(1))
    except ValueError:
        return None


def _warn_distortion(model: Any, coeffs: Any) -> None:
    """A warning where the camera's lens distortion (non-zero coefficients) is dropped: upsr's
    intrinsics (and ``OUTPUT.intrinsics.json``) are a pinhole's."""
    try:
        values = [float(c) for c in coeffs if str(c).strip()]
    except (TypeError, ValueError):
        values = []
    if any(v != 0.0 for v in values):
        warnings.warn(
            f"the depth camera's lens distortion ({model or 'a model'}, {len(values)} "
            "coefficients) is not modelled: its intrinsics are taken as a pinhole's",
            stacklevel=2,
        )


def _camera_from_string(text: str, w: int, h: int) -> Any:
    """librealsense 2.59's ``…/Depth_0/camera_info`` String: ``width=..;fx=..;ppx=..``."""
    from upsr.geometry.camera import PinholeCamera

    kv = dict(p.split("=", 1) for p in text.split(";") if "=" in p)
    _warn_distortion(kv.get("model", ""), kv.get("coeffs", "").split(","))
    try:
        return PinholeCamera(
            float(kv["fx"]), float(kv["fy"]), float(kv["ppx"]), float(kv["ppy"]), w, h
        )
    except (KeyError, ValueError, InputError):
        return None


def intrinsics(path: Path, opts: ReadOptions, fmt: str = "rosbag") -> Any:
    """The depth camera's intrinsics from its CameraInfo topic, or None.

    Returns
    -------
    upsr.geometry.camera.PinholeCamera or None
        fx, fy, cx, cy from K (ROS pixel coordinates: pixel (i, j) centred at (u, v) = (j, i),
        as in SPEC §1), width and height of the depth images. RealSense ``.db3`` recordings
        without a CameraInfo: their ``…/Depth_0/camera_info`` string (fx, fy, ppx, ppy).
    """
    from upsr.geometry.camera import PinholeCamera

    name = str(path)
    with _open(path) as reader, reading(name):
        conn, msg = _depth_connection(reader, opts.topic, name)
        frame = _decode(msg, None, name)
        h, w = frame.shape
        info_conn = _camera_info_of(reader, conn.topic)
        info = None if info_conn is None else _first(reader, info_conn)
        if info is None:
            m = re.match(r"(.*/Depth_\d+)/", conn.topic)
            if m is None:
                return None
            strs = [
                c
                for c in reader.connections
                if c.topic == m.group(1) + "/camera_info" and c.msgtype == "std_msgs/msg/String"
            ]
            text = _first(reader, strs[0]) if strs else None
            return None if text is None else _camera_from_string(str(text.data), w, h)
    k = np.asarray(getattr(info, "k", getattr(info, "K", None)), dtype=np.float64).reshape(-1)
    if k.size != 9 or not np.isfinite(k).all() or k[0] <= 0 or k[4] <= 0:
        return None  # an uncalibrated camera publishes K = 0
    iw, ih = int(info.width), int(info.height)
    if (iw, ih) not in ((0, 0), (w, h)):
        raise InputError(
            f"{name}: camera info {info_conn.topic} is for {iw}x{ih} images, the depth images "
            f"are {w}x{h}: give the depth camera's --intrinsics FX,FY,CX,CY"
        )
    _warn_distortion(
        getattr(info, "distortion_model", ""), getattr(info, "d", getattr(info, "D", []))
    )
    return PinholeCamera(float(k[0]), float(k[4]), float(k[2]), float(k[5]), w, h)


# ---------------------------------------------------------------------------------------------
# writing: a ROS 2 bag folder (sqlite3) of sensor_msgs/Image 32FC1 + sensor_msgs/CameraInfo
# ---------------------------------------------------------------------------------------------
#: Topics of the bags written (the depth in metres, REP 117: NaN = no measurement).
OUTPUT_TOPIC = "/camera/depth/image_raw"
OUTPUT_INFO_TOPIC = "/camera/depth/camera_info"
#: Frame period used when no timestamps are given (30 fps), ns.
DEFAULT_PERIOD_NS = 33_333_333


def writes_folder(dest: Path) -> bool:
    """A ROS 2 bag is a folder (``metadata.yaml`` + one ``.db3``)."""
    return True


class FrameSink:
    """Stream frames into a ROS 2 bag folder (``rosbags`` writer, sqlite3 storage).

    Depth is written as ``sensor_msgs/Image`` ``32FC1`` (metres; NaN where there is no
    measurement, REP 117) on :data:`OUTPUT_TOPIC`, stamped with the input's timestamps when
    :meth:`set_meta` gave them (else 30 fps from 0); with a camera, a ``sensor_msgs/CameraInfo``
    (K, P, size; no distortion) on :data:`OUTPUT_INFO_TOPIC` with every frame.
    """

    def __init__(
        self,
        dest: Path,
        temp: Path,
        fh: BinaryIO | None,
        *,
        shape_px: tuple[int, int],
        depth_scale: float,
        n_frames: int | None,
    ) -> None:
        require("rosbags", "writing ROS bags")
        from rosbags.rosbag2 import Writer
        from rosbags.typesys import Stores, get_typestore

        self.dest, self.temp, self.shape = dest, temp, shape_px
        self._ts = get_typestore(Stores.ROS2_HUMBLE)
        self._inner = temp / "bag"
        self._writer = Writer(self._inner, version=8)
        self._writer.open()
        self._stamps: Sequence[int] | None = None
        self._logged = -1  # the last message's log time (ns)
        self._camera: Any = None
        self._frame_id = "camera_depth_optical_frame"
        self._conn = self._writer.add_connection(
            OUTPUT_TOPIC, "sensor_msgs/msg/Image", typestore=self._ts
        )
        self._info_conn: Any = None

    def set_meta(
        self,
        *,
        timestamps_ns: Sequence[int] | None = None,
        camera: Any = None,
        frame_names: Sequence[str] | None = None,
    ) -> None:
        """Stamps (ns, one per frame) and the output camera (a PinholeCamera) of the bag."""
        self._stamps = None if timestamps_ns is None else [int(t) for t in timestamps_ns]
        self._camera = camera
        if camera is not None and self._info_conn is None:
            self._info_conn = self._writer.add_connection(
                OUTPUT_INFO_TOPIC, "sensor_msgs/msg/CameraInfo", typestore=self._ts
            )

    def _header(self, stamp: int) -> Any:
        t = self._ts.types["builtin_interfaces/msg/Time"](
            sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000
        )
        return self._ts.types["std_msgs/msg/Header"](stamp=t, frame_id=self._frame_id)

    def write(self, frame_mm: np.ndarray, t: int, stamp_ns: int | None = None) -> None:
        """Append frame ``t`` (float32 mm, 0 = no measurement), stamped ``stamp_ns`` where
        given."""
        if stamp_ns is not None:
            stamp = int(stamp_ns)
        elif self._stamps is not None:
            if t >= len(self._stamps):
                raise InputError(f"{self.dest}: frame {t} has no timestamp")
            stamp = self._stamps[t]
        else:
            stamp = t * DEFAULT_PERIOD_NS
        h, w = self.shape
        m = (np.asarray(frame_mm, np.float32) / np.float32(1000.0)).astype("<f4")
        m[~(m > 0)] = np.nan
        msg = self._ts.types["sensor_msgs/msg/Image"](
            header=self._header(stamp),
            height=h,
            width=w,
            encoding="32FC1",
            is_bigendian=0,
            step=4 * w,
            data=np.ascontiguousarray(m).view(np.uint8).reshape(-1),
        )
        # the headers keep the frame's time as recorded; the bag's log times rise (a camera
        # clock reset: 1 ns after the last), so that a player keeps the frames' order
        self._logged = logged = max(stamp, self._logged + 1)
        self._writer.write(self._conn, logged, self._ts.serialize_cdr(msg, "sensor_msgs/msg/Image"))
        if self._info_conn is not None:
            info = camera_info_message(self._ts, self._camera, self._header(stamp))
            self._writer.write(
                self._info_conn, logged, self._ts.serialize_cdr(info, "sensor_msgs/msg/CameraInfo")
            )

    def close(self) -> None:
        """Finish the bag and move its files into the output folder."""
        self._writer.close()
        for entry in os.listdir(self._inner):
            os.replace(self._inner / entry, self.temp / entry)
        os.rmdir(self._inner)

    def abort(self) -> None:
        """Stop writing (the caller removes the temporary folder)."""
        with contextlib.suppress(Exception):
            self._writer.close()


def camera_info_message(ts: Any, camera: Any, header: Any) -> Any:
    """A ``sensor_msgs/CameraInfo`` (ROS 2) of a PinholeCamera: K, P = [K | 0], no distortion."""
    k = np.asarray(camera.K, np.float64).reshape(3, 3)
    p = np.concatenate([k, np.zeros((3, 1))], axis=1).reshape(-1)
    roi = ts.types["sensor_msgs/msg/RegionOfInterest"](
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
    )
    return ts.types["sensor_msgs/msg/CameraInfo"](
        header=header,
        height=int(camera.height),
        width=int(camera.width),
        distortion_model="plumb_bob",
        d=np.zeros(5),
        k=k.reshape(-1),
        r=np.eye(3).reshape(-1),
        p=p,
        binning_x=0,
        binning_y=0,
        roi=roi,
    )
