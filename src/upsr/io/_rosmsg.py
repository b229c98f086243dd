"""Tolerant decoders of the ROS image messages that carry depth, and image_transport's codecs.

Why not only ``rosbags``' deserialiser: librealsense (2.5x, its realsense-file
``sensor_msgs/Image.h``) appends a float32 *depth units* value after ``data`` in the Image records
of its ROS 1 ``.bag`` files, which a strict deserialiser refuses ("message size mismatch"). The
parsers here read the fields of ``sensor_msgs/Image`` and ``sensor_msgs/CompressedImage`` from
ROS 1 or CDR (ROS 2) bytes and ignore what follows them (the RealSense trailer is returned).

``compressedDepth`` (image_transport's ``compressed_depth_image_transport``): ``format`` is
``"<encoding>; compressedDepth [png|rvl]"``, ``data`` a 12-byte header (int32 config enum, float32
depthQuantA, depthQuantB) followed by a 16-bit PNG, or by RVL (uint32 width, height, then the RVL
words). 16UC1 stores the depth itself (mm); 32FC1 stores quantised inverse depth:
``depth_m = depthQuantA / (value - depthQuantB)``, value 0 = no measurement.

``compressed`` (image_transport's ``compressed_image_transport``): ``format`` is
``"<encoding>; <png|jpeg> compressed …"`` (or just ``png``/``jpeg``); only 16-bit single-channel
PNGs can hold depth.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from upsr.errors import InputError

__all__ = [
    "CompressedMsg",
    "ImageMsg",
    "decode_compressed_depth",
    "parse_compressed",
    "parse_image",
    "rvl_decode",
]


@dataclass
class ImageMsg:
    """The fields of a ``sensor_msgs/Image`` (``trailer``: bytes after ``data``)."""

    stamp_ns: int
    height: int
    width: int
    encoding: str
    is_bigendian: int
    step: int
    data: np.ndarray
    trailer: bytes = b""

    @property
    def depth_units_m(self) -> float | None:
        """The RealSense trailer's depth units (m per raw unit), when present and plausible."""
        if len(self.trailer) >= 4:
            (u,) = struct.unpack("<f", self.trailer[:4])
            if np.isfinite(u) and 0 < u < 1:
                return float(u)
        return None


@dataclass
class CompressedMsg:
    """The fields of a ``sensor_msgs/CompressedImage``."""

    stamp_ns: int
    format: str
    data: bytes


class _Buf:
    def __init__(self, raw: bytes, cdr: bool) -> None:
        self.raw = memoryview(raw)
        self.cdr = cdr
        self.pos = 0
        self.end = "<"
        if cdr:
            if len(raw) < 4:
                raise InputError("message shorter than its CDR header")
            self.end = "<" if raw[1] & 1 else ">"
            self.pos = 4

    def _align(self, n: int) -> None:
        if self.cdr:
            off = (self.pos - 4) % n
            if off:
                self.pos += n - off

    def take(self, fmt: str) -> int:
        size = struct.calcsize(fmt)
        self._align(size)
        if self.pos + size > len(self.raw):
            raise InputError("message truncated")
        (v,) = struct.unpack_from(self.end + fmt, self.raw, self.pos)
        self.pos += size
        return int(v)

    def u8(self) -> int:
        if self.pos >= len(self.raw):
            raise InputError("message truncated")
        v = self.raw[self.pos]
        self.pos += 1
        return int(v)

    def bytes_(self) -> bytes:
        n = self.take("I")
        if n < 0 or self.pos + n > len(self.raw):
            raise InputError(f"message truncated (a field of {n} bytes)")
        b = bytes(self.raw[self.pos : self.pos + n])
        self.pos += n
        return b

    def string(self) -> str:
        b = self.bytes_()
        if self.cdr and b.endswith(b"\0"):
            b = b[:-1]
        return b.decode("utf-8", "replace")

    def stamp_ns(self) -> int:
        if not self.cdr:
            self.take("I")  # seq
        sec = self.take("i" if self.cdr else "I")
        nsec = self.take("I")
        self.string()  # frame_id
        return sec * 1_000_000_000 + nsec


def parse_image(raw: bytes, *, cdr: bool) -> ImageMsg:
    """A serialised ``sensor_msgs/Image`` (ROS 1 or CDR), tolerant of trailing bytes."""
    b = _Buf(raw, cdr)
    stamp = b.stamp_ns()
    h, w = b.take("I"), b.take("I")
    enc = b.string()
    big = b.u8()
    step = b.take("I")
    data = b.bytes_()
    trailer = bytes(b.raw[b.pos :])
    if cdr:
        trailer = trailer[(-(b.pos - 4)) % 4 :]  # CDR padding before a float32
    return ImageMsg(stamp, h, w, enc, big, step, np.frombuffer(data, np.uint8), trailer)


def parse_compressed(raw: bytes, *, cdr: bool) -> CompressedMsg:
    """A serialised ``sensor_msgs/CompressedImage`` (ROS 1 or CDR)."""
    b = _Buf(raw, cdr)
    stamp = b.stamp_ns()
    fmt = b.string()
    return CompressedMsg(stamp, fmt, b.bytes_())


# ---------------------------------------------------------------------------------------------
# RVL (Wilson 2017, "Fast lossless depth image compression"), as compressed_depth_image_transport
# ---------------------------------------------------------------------------------------------
def rvl_decode(data: bytes, n_pixels: int) -> np.ndarray:
    """RVL bytes (little-endian int32 words) → uint16 array of ``n_pixels`` values."""
    words = np.frombuffer(data[: len(data) // 4 * 4], "<u4").tolist()
    out = np.zeros(n_pixels, np.uint16)
    it = iter(words)

    def nibble_stream():
        for word in it:
            for k in range(7, -1, -1):
                yield (word >> (4 * k)) & 0xF

    ns = nibble_stream()

    def vle() -> int:
        value, shift = 0, 0
        while True:
            nib = next(ns, None)
            if nib is None:
                raise InputError("RVL stream truncated")
            value |= (nib & 0x7) << shift
            shift += 3
            if not nib & 0x8:
                return value

    k, previous = 0, 0
    while k < n_pixels:
        zeros = vle()
        k += zeros
        nonzeros = vle()
        if k + nonzeros > n_pixels:
            raise InputError("RVL stream holds more pixels than the image")
        for _ in range(nonzeros):
            positive = vle()
            previous += (positive >> 1) ^ -(positive & 1)
            out[k] = previous & 0xFFFF
            k += 1
    return out


# ---------------------------------------------------------------------------------------------
# compressedDepth / compressed
# ---------------------------------------------------------------------------------------------
def _imdecode(data: bytes, name: str) -> np.ndarray:
    import cv2

    from upsr.io._common import check_frame_size

    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:  # size before decoding (bombs)
        w, h = struct.unpack(">II", data[16:24])
        check_frame_size(name, h, w)
    if not data:
        raise InputError(f"{name}: empty compressed image")
    try:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    except cv2.error:
        img = None
    if img is None:
        raise InputError(f"{name}: the compressed image cannot be decoded")
    return img


def is_compressed_depth(fmt: str) -> bool:
    """Whether a CompressedImage ``format`` string announces depth."""
    f = fmt.lower()
    enc = f.split(";")[0].strip()
    return "compresseddepth" in f or (enc in ("16uc1", "mono16") and "png" in f)


def decode_compressed_depth(msg: CompressedMsg, name: str = "image") -> np.ndarray:
    """A compressed depth image → float32 (h, w) depth in mm (0 = none, before any
    RealSense depth-units factor: 16-bit depth is returned in raw units)."""
    fmt = msg.format.lower()
    enc = fmt.split(";")[0].strip()
    data = msg.data
    if "compresseddepth" in fmt:
        if len(data) < 12:
            raise InputError(f"{name}: compressedDepth data shorter than its 12-byte header")
        _, qa, qb = struct.unpack_from("<iff", data, 0)
        body = data[12:]
        if "rvl" in fmt:
            if len(body) < 8:
                raise InputError(f"{name}: RVL data without its size")
            w, h = struct.unpack_from("<II", body, 0)
            from upsr.io._common import check_frame_size

            check_frame_size(name, h, w)
            raw = rvl_decode(body[8:], w * h).reshape(h, w)
        else:
            raw = _imdecode(body, name)
        if raw.dtype != np.uint16 or raw.ndim != 2:
            raise InputError(f"{name}: compressedDepth image is not 16-bit single-channel")
        if enc == "32fc1":
            v = raw.astype(np.float64)
            with np.errstate(divide="ignore", invalid="ignore"):
                m = np.where(raw > 0, qa / (v - qb), 0.0)
            m[~np.isfinite(m) | (m < 0)] = 0.0
            return (m * 1000.0).astype(np.float32)
        if enc not in ("16uc1", "mono16"):
            raise InputError(f"{name}: compressedDepth of encoding {enc!r} (16UC1, 32FC1 read)")
        return raw.astype(np.float32)
    img = _imdecode(data, name)
    if img.dtype != np.uint16 or img.ndim != 2:
        raise InputError(
            f"{name}: compressed image ({msg.format!r}) is {img.dtype} with "
            f"{1 if img.ndim == 2 else img.shape[2]} channel(s), not 16-bit depth"
        )
    return img.astype(np.float32)
