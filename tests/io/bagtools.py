"""Write small ROS 1 / ROS 2 / RealSense-like bags with depth images for the tests (rosbags)."""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

_DT = {"16UC1": "u2", "mono16": "u2", "32FC1": "f4", "rgb8": "u1"}
K_DEFAULT = (500.0, 0.0, 3.5, 0.0, 501.0, 2.5, 0.0, 0.0, 1.0)


def _header(ts: Any, stamp: int = 0) -> Any:
    header, time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    t = time(sec=stamp, nanosec=0)
    if "seq" in header.__dataclass_fields__:
        return header(seq=0, stamp=t, frame_id="cam")
    return header(stamp=t, frame_id="cam")


def image(
    ts: Any, depth: np.ndarray, encoding: str, big: bool = False, pad: int = 0, stamp: int = 0
) -> Any:
    """A sensor_msgs/Image of ``depth`` (h, w) in ``encoding``, with ``pad`` bytes per row."""
    h, w = depth.shape[:2]
    raw = np.ascontiguousarray(depth.astype((">" if big else "<") + _DT[encoding]))
    rows = raw.view(np.uint8).reshape(h, -1)
    if pad:
        rows = np.concatenate([rows, np.full((h, pad), 7, np.uint8)], axis=1)
    return ts.types["sensor_msgs/msg/Image"](
        header=_header(ts, stamp),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=int(big),
        step=rows.shape[1],
        data=np.ascontiguousarray(rows).reshape(-1),
    )


def camera_info(
    ts: Any, w: int, h: int, k: Sequence[float], d: Sequence[float] = (0.0,) * 5
) -> Any:
    ci = ts.types["sensor_msgs/msg/CameraInfo"]
    roi = ts.types["sensor_msgs/msg/RegionOfInterest"](
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
    )
    names = ("D", "K", "R", "P") if "K" in ci.__dataclass_fields__ else ("d", "k", "r", "p")
    arrays = (np.asarray(d, float), np.asarray(k, float), np.eye(3).reshape(-1), np.zeros(12))
    return ci(
        header=_header(ts),
        height=h,
        width=w,
        distortion_model="plumb_bob",
        binning_x=0,
        binning_y=0,
        roi=roi,
        **dict(zip(names, arrays, strict=True)),
    )


Extra = tuple[str, str, Callable[[Any], Any]]


def ros1_bag(
    path: Path,
    frames: Sequence[np.ndarray],
    *,
    topic: str = "/camera/depth/image_raw",
    encoding: str = "16UC1",
    big: bool = False,
    pad: int = 0,
    k: Sequence[float] | None = None,
    extra: Sequence[Extra] = (),
) -> Path:
    """A ROS 1 bag with ``frames`` on ``topic`` (+ CameraInfo next to it if ``k``)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path) as w:
        conn = w.add_connection(topic, "sensor_msgs/msg/Image", typestore=ts)
        if k is not None:
            ci = w.add_connection(
                topic.rsplit("/", 1)[0] + "/camera_info", "sensor_msgs/msg/CameraInfo", typestore=ts
            )
            h, wd = frames[0].shape[:2]
            msg = camera_info(ts, wd, h, k)
            w.write(ci, 1, ts.serialize_ros1(msg, "sensor_msgs/msg/CameraInfo"))
        for i, f in enumerate(frames):
            msg = image(ts, f, encoding, big, pad, stamp=i)
            w.write(conn, (i + 1) * 10**8, ts.serialize_ros1(msg, "sensor_msgs/msg/Image"))
        for t, typ, make in extra:
            c = w.add_connection(t, typ, typestore=ts)
            w.write(c, 2, ts.serialize_ros1(make(ts), typ))
    return path


def ros2_bag(
    path: Path,
    frames: Sequence[np.ndarray],
    *,
    topic: str = "/camera/depth/image_raw",
    encoding: str = "32FC1",
    k: Sequence[float] | None = None,
) -> Path:
    """A ROS 2 bag folder (sqlite3) with ``frames`` on ``topic``."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(path, version=9) as w:
        conn = w.add_connection(topic, "sensor_msgs/msg/Image", typestore=ts)
        if k is not None:
            ci = w.add_connection(
                topic.rsplit("/", 1)[0] + "/camera_info", "sensor_msgs/msg/CameraInfo", typestore=ts
            )
            h, wd = frames[0].shape[:2]
            msg = camera_info(ts, wd, h, k)
            w.write(ci, 1, ts.serialize_cdr(msg, "sensor_msgs/msg/CameraInfo"))
        for i, f in enumerate(frames):
            msg = image(ts, f, encoding, stamp=i)
            w.write(conn, (i + 1) * 10**8, ts.serialize_cdr(msg, "sensor_msgs/msg/Image"))
    return path


def realsense_bag(path: Path, frames: Sequence[np.ndarray], units_m: float = 0.0001) -> Path:
    """A RealSense-like ROS 1 bag: mono16 Depth_0 stream, Depth Units option, camera info."""
    f32 = "std_msgs/msg/Float32"
    sensor = "/device_0/sensor_0"
    ros1_bag(
        path,
        frames,
        topic=f"{sensor}/Depth_0/image/data",
        encoding="mono16",
        extra=[
            (f"{sensor}/option/Depth Units/value", f32, lambda ts: ts.types[f32](data=units_m)),
            (
                f"{sensor}/Depth_0/info/camera_info",
                "sensor_msgs/msg/CameraInfo",
                lambda ts: camera_info(ts, frames[0].shape[1], frames[0].shape[0], K_DEFAULT),
            ),
        ],
    )
    return path


# compressedDepth messages as compressed_depth_image_transport writes them
def rvl_encode(values: np.ndarray) -> bytes:
    """uint16 values → RVL bytes (the encoder of compressed_depth_image_transport)."""
    v = np.asarray(values, np.uint16).reshape(-1).tolist()
    nibbles: list[int] = []

    def vle(value: int) -> None:
        while True:
            nib = value & 0x7
            value >>= 3
            if value:
                nib |= 0x8
            nibbles.append(nib)
            if not value:
                return

    i, n, previous = 0, len(v), 0
    while i < n:
        j = i
        while j < n and v[j] == 0:
            j += 1
        vle(j - i)
        i = j
        while j < n and v[j] != 0:
            j += 1
        vle(j - i)
        for x in v[i:j]:
            delta = x - previous
            vle(((delta << 1) ^ (delta >> 31)) & 0xFFFFFFFF)
            previous = x
        i = j
    nibbles += [0] * (-len(nibbles) % 8)
    words = [
        sum(nibbles[w + k] << (4 * (7 - k)) for k in range(8)) for w in range(0, len(nibbles), 8)
    ]
    return np.asarray(words, "<u4").tobytes()


def _imencode_png(img: np.ndarray) -> bytes:
    import cv2

    ok, buf = cv2.imencode(".png", img)
    if not ok:  # pragma: no cover
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def encode_compressed_depth(
    depth: np.ndarray,
    encoding: str = "16UC1",
    codec: str = "png",
    depth_max_m: float = 10.0,
    depth_quantization: float = 100.0,
) -> tuple[str, bytes]:
    """(format, data) of a compressedDepth message, as compressed_depth_image_transport writes.

    16UC1: ``depth`` is uint16 (mm). 32FC1: ``depth`` is float metres, quantised as inverse
    depth with depthQuantA = depth_quantization · (depth_quantization + 1), depthQuantB =
    1 − depthQuantA / depth_max_m.
    """
    if encoding.upper() == "32FC1":
        qa = depth_quantization * (depth_quantization + 1.0)
        qb = 1.0 - qa / depth_max_m
        d = np.asarray(depth, np.float64)
        good = np.isfinite(d) & (d > 0) & (d < depth_max_m)
        raw = np.zeros(d.shape, np.uint16)
        raw[good] = np.clip(qa / d[good] + qb, 0, 65535).astype(np.uint16)
    else:
        qa = qb = 0.0
        raw = np.asarray(depth, np.uint16)
    header = struct.pack("<iff", 0, qa, qb)
    if codec == "rvl":
        h, w = raw.shape
        body = struct.pack("<II", w, h) + rvl_encode(raw)
    else:
        body = _imencode_png(raw)
    return f"{encoding}; compressedDepth {codec}", header + body


def realsense_ros2_bag(
    path: Path,
    frames: Sequence[np.ndarray],
    *,
    option_units: str,
    metadata: Sequence[str | None],
    header_ms: Sequence[float],
) -> Path:
    """A ROS 2 bag laid out as librealsense 2.59 records (16UC1 Depth_0 images, a Depth_Units
    option as text, each frame's ``…/image/metadata`` text logged with it; None: none)."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    s, root = "std_msgs/msg/String", "/device_0/sensor_0"
    with Writer(path, version=9) as w:
        option = w.add_connection(f"{root}/option/Depth_Units/value", s, typestore=ts)
        w.write(option, 1, ts.serialize_cdr(ts.types[s](data=option_units), s))
        img = w.add_connection(f"{root}/Depth_0/image/data", "sensor_msgs/msg/Image", typestore=ts)
        meta = w.add_connection(f"{root}/Depth_0/image/metadata", s, typestore=ts)
        for i, (f, text, ms) in enumerate(zip(frames, metadata, header_ms, strict=True)):
            t = (i + 1) * 10**8
            msg = image(ts, f, "16UC1")
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(round(ms * 1e6), 10**9)
            w.write(img, t, ts.serialize_cdr(msg, "sensor_msgs/msg/Image"))
            if text is not None:
                w.write(meta, t, ts.serialize_cdr(ts.types[s](data=text), s))
    return path
