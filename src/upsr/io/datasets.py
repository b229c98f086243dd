"""Single-frame depth formats of public RGB-D datasets (a file, or a folder of such files).

``tum`` — TUM RGB-D benchmark
    16-bit PNG, raw / 5000 = metres (5 raw units per mm).
``sun`` — SUN RGB-D
    16-bit PNG whose bits are rotated by 3: mm = ((raw >> 3) | (raw << 13)) & 0xFFFF (the
    SUN RGB-D toolbox's ``read3dPoints.m``; its clamping of depth beyond 8 m is not applied).
``nyu`` — NYU Depth v2 raw Kinect frames (the default for ``.pgm``)
    16-bit binary PGM (P5) of raw Kinect disparity d (11 bit, 2047 = no measurement),
    converted as the NYU toolbox's ``depth_rel2depth_abs.m`` does:
    depth = 351.3 / (1092.5 − d) metres. Depths outside (0, 10] m (d ≥ 1058, where the toolbox
    clamps to 10 m) are no measurement here: clamping would invent depth. The NYU dumps store
    their samples with the bytes swapped (little-endian, against the PGM standard; the
    toolbox's ``get_synched_frames.m`` calls ``swapbytes`` after ``imread``): the byte order
    whose values are all ≤ 2047 is used (swapped first), anything else is refused.
``pgm``
    A 16-bit binary PGM of depth, raw / depth_scale = metres (``depth_scale`` 1000: mm).

8-bit files are refused (they cannot hold depth: usually a visualisation).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from upsr.errors import InputError
from upsr.io import png
from upsr.io._base import VideoInfo, reading
from upsr.io._common import check_frame_size, frame_files, mixed_size
from upsr.io.registry import ReadOptions
from upsr.method.validation import as_depth_frame

__all__ = [
    "NYU_INVALID",
    "NYU_MAX_DEPTH_M",
    "TUM_DEPTH_SCALE",
    "frames",
    "nyu_disparity_to_mm",
    "probe",
    "sun_png_to_mm",
]

#: TUM RGB-D: raw units per metre.
TUM_DEPTH_SCALE = 5000.0
#: NYU raw Kinect: the "no measurement" disparity.
NYU_INVALID = 2047
#: NYU raw Kinect: farther depths (toolbox: clamped) are treated as no measurement.
NYU_MAX_DEPTH_M = 10.0
_NYU_A, _NYU_B = 351.3, 1092.5
_PGM_HEADER_MAX = 4096


def nyu_disparity_to_mm(raw: np.ndarray) -> np.ndarray:
    """NYU Depth v2 raw Kinect disparity → float32 depth in mm (0 = no measurement).

    depth = 351.3 / (1092.5 − raw) m (NYU toolbox); raw = 2047, non-positive depths and depths
    beyond 10 m are 0.
    """
    d = np.asarray(raw, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        m = _NYU_A / (_NYU_B - d)
    ok = (d != NYU_INVALID) & np.isfinite(m) & (m > 0) & (m <= NYU_MAX_DEPTH_M)
    return np.where(ok, m * 1000.0, 0.0).astype(np.float32)


def sun_png_to_mm(raw: np.ndarray) -> np.ndarray:
    """SUN RGB-D depth PNG values → float32 mm: ((raw >> 3) | (raw << 13)) & 0xFFFF."""
    r = np.asarray(raw).astype(np.uint32)
    return (((r >> 3) | (r << 13)) & 0xFFFF).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# PGM
# ---------------------------------------------------------------------------------------------
def _pgm_header(head: bytes, name: str) -> tuple[int, int, int, int]:
    """(height, width, maxval, data offset) of a binary PGM."""
    if head[:2] != b"P5":
        kind = " (ASCII PGM is not supported)" if head[:2] == b"P2" else ""
        raise InputError(f"{name}: not a binary PGM file (P5){kind}")
    values: list[int] = []
    pos = 2
    n = len(head)
    while len(values) < 3:
        while pos < n and head[pos : pos + 1].isspace():
            pos += 1
        if pos < n and head[pos : pos + 1] == b"#":
            while pos < n and head[pos : pos + 1] not in (b"\n", b"\r"):
                pos += 1
            continue
        start = pos
        while pos < n and head[pos : pos + 1].isdigit():
            pos += 1
        if start == pos or pos >= n:
            raise InputError(f"{name}: corrupt or truncated PGM header")
        values.append(int(head[start:pos]))
    if not head[pos : pos + 1].isspace():
        raise InputError(f"{name}: corrupt PGM header")
    w, h, maxval = values
    check_frame_size(name, h, w)
    if not 0 < maxval <= 65535:
        raise InputError(f"{name}: corrupt PGM header (maxval {maxval})")
    return h, w, maxval, pos + 1


def _pgm_meta(file: Path, fmt: str) -> tuple[int, int, int]:
    name = str(file)
    with reading(name), open(file, "rb") as f:
        head = f.read(_PGM_HEADER_MAX)
        size = os.fstat(f.fileno()).st_size
    h, w, maxval, offset = _pgm_header(head, name)
    if maxval < 256:
        raise InputError(
            f"{name}: 8-bit PGM (maxval {maxval}): depth frames must be 16-bit "
            f"(an 8-bit image cannot hold depth: is it a visualisation?)"
        )
    need = h * w * 2
    if size - offset < need:
        raise InputError(
            f"{name}: truncated PGM file: {w}x{h} 16-bit needs {need} bytes of pixel data, "
            f"the file holds {size - offset}"
        )
    return h, w, offset


def _read_pgm(file: Path, fmt: str, expect: tuple[int, int]) -> np.ndarray:
    name = str(file)
    h, w, offset = _pgm_meta(file, fmt)
    if (h, w) != expect:
        raise mixed_size(name, (h, w), "the first frame", expect)
    with reading(name), open(file, "rb") as f:
        f.seek(offset)
        data = f.read(h * w * 2)
    if len(data) != h * w * 2:
        raise InputError(f"{name}: truncated PGM file")
    raw = np.frombuffer(data, ">u2").reshape(h, w)
    if fmt == "nyu":
        swapped = raw.byteswap()
        if int(swapped.max()) <= NYU_INVALID:
            return swapped  # the NYU dumps' byte order
        top = int(raw.max())
        if top > NYU_INVALID:
            raise InputError(
                f"{name}: values above 2047 in either byte order: not raw Kinect disparity "
                f"(NYU format); for a 16-bit PGM of depth use --input-format pgm / fmt='pgm'"
            )
    return raw


# ---------------------------------------------------------------------------------------------
# the format interface
# ---------------------------------------------------------------------------------------------
def _files(path: Path, fmt: str) -> list[Path]:
    if fmt in ("nyu", "pgm"):
        return frame_files(path, (".pgm",), "PGM")
    return png.frame_files(path)


def probe(path: Path, opts: ReadOptions, fmt: str) -> VideoInfo:
    """Describe a file or folder of ``fmt`` ("nyu", "pgm", "tum" or "sun") frames."""
    if fmt in ("tum", "sun"):
        info = png.probe_files(path)[0]
        return VideoInfo(info.n_frames, info.height, info.width, info.dtype, fmt)
    files = _files(path, fmt)
    h, w, _ = _pgm_meta(files[0], fmt)
    for file in files[1:]:
        hh, ww, _ = _pgm_meta(file, fmt)
        if (hh, ww) != (h, w):
            raise mixed_size(str(file), (hh, ww), files[0].name, (h, w))
    return VideoInfo(len(files), h, w, np.dtype(">u2"), fmt)


def frames(
    path: Path, opts: ReadOptions, fmt: str, start: int = 0, stop: int | None = None
) -> Iterator[np.ndarray]:
    """Frames ``start`` … ``stop - 1`` (float32 mm) of a file or folder of ``fmt`` frames.

    Only the files of those frames are read (one frame per file).
    """
    if fmt == "tum":
        info, files = png.probe_files(path)
        yield from png.frames_of_files(
            files[start:stop], (info.height, info.width), TUM_DEPTH_SCALE
        )
        return
    if fmt == "sun":
        info, files = png.probe_files(path)
        for file in files[start:stop]:
            raw = png.read_frame(file, (info.height, info.width))
            yield as_depth_frame(sun_png_to_mm(raw), name=file.name)
        return
    files = _files(path, fmt)
    expect = _pgm_meta(files[0], fmt)[:2]
    for file in files[start:stop]:
        raw = _read_pgm(file, fmt, expect)
        if fmt == "nyu":
            yield as_depth_frame(nyu_disparity_to_mm(raw), name=file.name)
        else:
            yield as_depth_frame(raw, name=file.name, mm_per_unit=opts.mm_per_unit)
