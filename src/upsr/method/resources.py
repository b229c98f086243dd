"""What a run will need (output bytes, peak working memory) and what the machine has.

Pure functions of the video's shape (T, h, w), the scale r, the window N, the workers and the
output format, so that a command can refuse a run up front with one line ("needs ~X GB, Y GB
available; --max-memory to override") instead of being killed by the kernel half-way.

Model
-----
``output_bytes``: T · (r·h) · (r·w) · B, B = 4 bytes per pixel for float32 outputs (``npy``,
``npz`` — an upper bound, the archive is compressed —, ``tiff``, ``exr``) and 2 for 16-bit
``png`` frames, plus a small per-frame overhead (headers; PNG: 4 KiB per file).

``peak_memory_bytes``: the engine (:class:`upsr.method.windowed.UPSR`) keeps about N frames of
state, on three grids: the output grid (O = r²·h·w px: maps, fused image, deblurring buffers),
the flow grid (F = s²·h·w px, s = ``flow_scale`` or its default: upsampled guides, prefiltered
frames, flows) and the input grid (L = h·w px: the frames and the chains of forward-splatted
sample positions). Measured with :mod:`tracemalloc` (numpy allocations) after a warm-up run,
default options, ``workers=0`` unless said, a moving slanted-plane scene:

======================  ==  ==  =======  ==========================
h×w, T                  r   N   s        peak (MB)
======================  ==  ==  =======  ==========================
64×56, 12               2   9   2        9.7
64×56, 12               4   9   4        25.1
128×112, 12             2   9   2        38.8
128×112, 12             4   9   2        48.3
128×112, 12             4   5   2        26.0
128×112, 12, workers 2  4   9   2        62.0
240×320, 14             2   9   2        208.5 (RSS grew by 168 MB)
240×320, 14, workers 2  4   9   2        329.4 (model: 338)
======================  ==  ==  =======  ==========================

The peak of those rows fits ``N · (6.5·O + 35·F + 150·L)`` bytes within 3 %; workers add
about 15 % each (62.0 / 48.3 with 2). At large r the output grid costs more than that: the
resident peak over the process itself (``benchmarks/memory_eval.py``, 7 Dec 2026: dense
frames, T = N, default workers) was 1046 MB at 640×480, r = 8, N = 1 (the rows' model: 376
MB), 2662 at N = 3 (1048), 785 at 320×240, r = 8, N = 5 (460), 4010 at 640×480, r = 16, N = 1
(970): about 48 bytes per output pixel whatever N (deblurring, finishing and speckle buffers
of one frame) and 20–54 more per further window frame. The estimate is
``32 MB + 48·O + (N − 1)·40·O + N · (35·F + 150·L)`` bytes, times ``(1 + 0.15·workers)``,
times a safety factor of 1.25 (allocator slack): 1.45–2.4× the resident peaks of
``benchmarks/memory_eval.py``, 2–6× the tracemalloc rows above (the most at the smallest
sizes, where the fixed 32 MB dominate). The process itself (Python, numpy, OpenCV, numba:
200–350 MB resident) is not counted. -r 150 on 64×56 frames, N = 9: ~5.7 GB; -r 1000: ~250 GB.

``available_memory_bytes``: the least of MemAvailable (``/proc/meminfo``), RLIMIT_AS minus
the address space already used (``ulimit -v``; the whole virtual size counts there) and the
cgroup v2 limit minus its usage. ``free_disk_bytes``: free space of the output's folder (its
nearest existing ancestor).
"""

from __future__ import annotations

import math
import os
import resource
import shutil
from dataclasses import dataclass
from pathlib import Path

from upsr.errors import InputError

__all__ = [
    "Estimate",
    "available_memory_bytes",
    "check_resources",
    "estimate",
    "free_disk_bytes",
    "output_bytes",
    "parse_bytes",
    "peak_memory_bytes",
]

#: Bytes per output pixel of each output format.
_BYTES_PER_PX = {"npy": 4, "npz": 4, "tiff": 4, "exr": 4, "png": 2}
#: Per-frame overhead of each output format (headers, one file per frame).
_FRAME_OVERHEAD = {"npy": 0, "npz": 64, "tiff": 512, "exr": 2048, "png": 4096}
#: Peak model (see the module docstring): bytes per output pixel of one frame's buffers, per
#: output pixel of each further window frame, and per window frame and flow-grid and input
#: pixel.
_PER_OUTPUT_PX_ONCE = 48.0
_PER_OUTPUT_PX = 40.0
_PER_FLOW_PX = 35.0
_PER_INPUT_PX = 150.0
#: Extra share of the peak per worker thread.
_PER_WORKER = 0.15
#: Fixed part of the peak (bytes).
_BASE_BYTES = 32 << 20
#: What the measurements do not see (OpenCV buffers, allocator slack).
_SAFETY = 1.25


def _read_meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _vm_size() -> int:
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 0


def _cgroup_available() -> int | None:
    try:
        with open("/proc/self/cgroup", encoding="ascii") as f:
            rel = next((ln.split(":", 2)[2].strip() for ln in f if ln.startswith("0::")), None)
        if rel is None:
            return None
        base = Path("/sys/fs/cgroup") / rel.lstrip("/")
        limit = (base / "memory.max").read_text().strip()
        if limit == "max":
            return None
        return max(int(limit) - int((base / "memory.current").read_text().strip()), 0)
    except (OSError, ValueError, StopIteration):
        return None


def available_memory_bytes() -> int:
    """Memory this process can still use (bytes): MemAvailable, RLIMIT_AS, cgroup limit."""
    candidates = []
    avail = _read_meminfo_available()
    if avail is not None:
        candidates.append(avail)
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        candidates.append(max(soft - _vm_size(), 0))
    cg = _cgroup_available()
    if cg is not None:
        candidates.append(cg)
    if not candidates:
        return 1 << 62
    return int(min(candidates))


def free_disk_bytes(path: str | os.PathLike[str]) -> int:
    """Free bytes of the file system where ``path`` (or its nearest existing ancestor) lies."""
    p = Path(os.path.abspath(path))
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return int(shutil.disk_usage(p).free)
    except OSError:
        return 1 << 62


def _ints(shape: tuple[int, int, int], scale: int) -> tuple[int, int, int, int]:
    try:
        t, h, w = (int(v) for v in shape)
        r = int(scale)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"shape {shape!r} and scale {scale!r} must be integers") from None
    if min(t, h, w, r) < 1:
        raise InputError(f"shape {shape!r} and scale {scale!r} must be >= 1")
    return t, h, w, r


def output_bytes(shape: tuple[int, int, int], scale: int, fmt: str = "npy") -> int:
    """Bytes of the output of a (T, h, w) video super-resolved by ``scale`` in format ``fmt``."""
    t, h, w, r = _ints(shape, scale)
    f = str(fmt).lower().lstrip(".")
    bpp = _BYTES_PER_PX.get(f, 4)
    return t * (r * h) * (r * w) * bpp + t * _FRAME_OVERHEAD.get(f, 0) + 4096


def peak_memory_bytes(
    shape: tuple[int, int, int],
    scale: int,
    n_frames: int = 9,
    workers: int = 0,
    flow_scale: int | None = None,
) -> int:
    """Peak working memory (bytes) of super-resolving a (T, h, w) video (model above).

    ``flow_scale``: s of the flow grid; None: the default of :class:`UPSRConfig`.
    """
    from upsr.method.config import FLOW_GRID_MIN_WIDTH_PX

    _, h, w, r = _ints(shape, scale)
    n = max(1, int(n_frames))
    k = max(0, int(workers))
    if flow_scale is None:
        s = min(r, max(2, math.ceil(FLOW_GRID_MIN_WIDTH_PX / w)))
    else:
        s = max(1, min(r, int(flow_scale)))
    lo = h * w
    out_px = r * r * lo
    per_window = (
        _PER_OUTPUT_PX_ONCE * out_px
        + (n - 1) * _PER_OUTPUT_PX * out_px
        + n * (_PER_FLOW_PX * s * s * lo + _PER_INPUT_PX * lo)
    )
    return int(_SAFETY * (_BASE_BYTES + per_window * (1 + _PER_WORKER * k)))


@dataclass(frozen=True)
class Estimate:
    """What a run needs and what is available (bytes)."""

    output_bytes: int
    peak_memory_bytes: int
    memory_available: int
    disk_available: int | None


def estimate(
    shape: tuple[int, int, int],
    scale: int,
    n_frames: int = 9,
    *,
    workers: int = 0,
    fmt: str = "npy",
    output: str | os.PathLike[str] | None = None,
    flow_scale: int | None = None,
) -> Estimate:
    """The :class:`Estimate` of a run (nothing checked)."""
    return Estimate(
        output_bytes(shape, scale, fmt),
        peak_memory_bytes(shape, scale, n_frames, workers, flow_scale),
        available_memory_bytes(),
        None if output is None else free_disk_bytes(output),
    )


def _gb(n: float) -> str:
    return f"{n / 1e9:.3g} GB"


def parse_bytes(text: str | int | float) -> int:
    """``"4G"``, ``"512M"``, ``"2.5GB"``, ``1e9`` → bytes (for ``--max-memory``); InputError.

    Examples
    --------
    >>> parse_bytes("4G"), parse_bytes("512M"), parse_bytes(1e9)
    (4294967296, 536870912, 1000000000)
    """
    if isinstance(text, bool):
        raise InputError(f"--max-memory must be a size such as 4G, got {text!r}")
    s = str(text).strip().upper().removesuffix("B").removesuffix("I")
    mult = 1
    for suffix, m in (("K", 1 << 10), ("M", 1 << 20), ("G", 1 << 30), ("T", 1 << 40)):
        if s.endswith(suffix):
            s, mult = s[:-1], m
            break
    try:
        v = float(s) * mult
    except (ValueError, OverflowError):
        raise InputError(f"--max-memory must be a size such as 4G or 512M, got {text!r}") from None
    if not (math.isfinite(v) and v >= 1):
        raise InputError(f"--max-memory must be a size >= 1 byte, got {text!r}")
    return int(min(v, 1 << 62))


def check_resources(
    shape: tuple[int, int, int],
    scale: int,
    n_frames: int = 9,
    *,
    workers: int = 0,
    fmt: str = "npy",
    output: str | os.PathLike[str] | None = None,
    max_memory: int | None = None,
    flow_scale: int | None = None,
) -> Estimate:
    """Refuse a run that needs more memory (or disk) than available; return its estimate.

    Parameters
    ----------
    shape, scale, n_frames, workers, fmt, flow_scale
        The input video (T, h, w), r, N, the engine's workers, the output format and s.
    output : path, optional
        The output: its folder's free space is compared with :func:`output_bytes`.
    max_memory : int, optional
        Memory (bytes) the run may use instead of :func:`available_memory_bytes`
        (``--max-memory``); the disk check is then skipped too.

    Raises
    ------
    InputError
        One line: ``needs ~X GB of memory, Y GB available; --max-memory to override``.
    """
    est = estimate(
        shape, scale, n_frames, workers=workers, fmt=fmt, output=output, flow_scale=flow_scale
    )
    t, h, w, r = _ints(shape, scale)
    what = f"{t} frames {w}x{h} at r={r}, N={n_frames}"
    mem = est.memory_available if max_memory is None else int(max_memory)
    if est.peak_memory_bytes > mem:
        raise InputError(
            f"{what} needs ~{_gb(est.peak_memory_bytes)} of memory, {_gb(mem)} available; "
            f"--max-memory to override"
        )
    if max_memory is None and est.disk_available is not None:
        if est.output_bytes > est.disk_available:
            raise InputError(
                f"{what}: the output needs ~{_gb(est.output_bytes)} of disk, "
                f"{_gb(est.disk_available)} free at {output}; --max-memory to override"
            )
    return est
