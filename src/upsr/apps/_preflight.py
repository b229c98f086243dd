"""The checks ``upsr run`` and ``upsr batch`` make before any processing.

:func:`memory_limit`
    ``--max-memory SIZE`` in bytes (None: what the machine has), and the per-frame read budget
    of :mod:`upsr.io` set to a quarter of it.
:func:`check_run_resources`
    The peak memory and output size of a run (:func:`upsr.method.resources.check_resources`):
    ``-r 150`` on 64×56 frames is refused with one line before anything big is allocated.
:func:`check_units`
    The first frame's depth against the sensor's plausible range, and TUM-scaled PNGs read as
    mm (:mod:`upsr.io.units`).
:func:`kernel_note`
    One line on stderr while numba compiles the kernels on first use (a cold cache).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from upsr.errors import InputError

__all__ = [
    "KERNEL_NOTE",
    "check_run_resources",
    "check_scale_applies",
    "check_sidecar",
    "check_units",
    "engine_workers",
    "kernel_cache_warm",
    "kernel_note",
    "memory_limit",
    "read_options",
    "removed_on_failure",
]

KERNEL_NOTE = "upsr: compiling kernels on first use (once, ~1–2 min)…"
_STATE = {"noted": False}


def memory_limit(max_memory: str | None) -> int | None:
    """``--max-memory`` in bytes (None: not given); sets the per-frame read budget to n // 4."""
    from upsr.io._base import set_frame_budget
    from upsr.method.resources import parse_bytes

    if max_memory is None:
        set_frame_budget(None)
        return None
    n = parse_bytes(max_memory)
    set_frame_budget(max(1, n // 4))
    return n


def max_workers() -> int:
    """The largest ``--workers`` of ``upsr run`` and ``upsr batch``: each worker holds frames
    of its own, so many more than the cores only costs memory."""
    return max(64, 2 * (os.cpu_count() or 1))


def engine_workers(workers: int | None) -> int:
    """The threads :class:`upsr.method.windowed.UPSR` uses for ``workers`` (None: its default)."""
    from upsr.method._parallel import WINDOWED_WORKERS, resolve_workers

    return resolve_workers(workers, WINDOWED_WORKERS)


def check_run_resources(
    shape: tuple[int, int, int],
    cfg: Any,
    *,
    workers: int,
    out_fmt: str,
    output: Path | None,
    max_memory: int | None,
) -> None:
    """Refuse a run whose estimated memory (or output size) exceeds what is available."""
    from upsr.method.resources import check_resources

    check_resources(
        shape,
        cfg.scale,
        cfg.n_frames,
        workers=workers,
        fmt=out_fmt,
        output=output,
        max_memory=max_memory,
        flow_scale=cfg.flow_scale,
    )


def check_units(
    path: Path,
    frame0_mm: Any,
    *,
    in_fmt: str,
    sensor: str,
    strict: bool,
    scale_given: bool,
    depth_scale: float,
) -> None:
    """SUN RGB-D or TUM PNGs read as mm (refused), then the plausible depth range (warned, or
    refused).

    ``in_fmt``: the input's resolved format; ``scale_given``: an input depth scale was given
    (then the SUN and TUM checks are skipped: the user chose the unit).
    """
    from upsr.io import units

    if in_fmt == "png" and not scale_given:
        from upsr.io.identity import read_frame_names

        names = read_frame_names(path, fmt=in_fmt) if path.is_dir() else [path.stem]
        # at the default 1000 units per metre the raw PNG values are the mm values (SUN's
        # packed values fit TUM's range too: its test first)
        message = units.detect_sun_packing(path, frame0_mm) or units.detect_tum_scale(
            path, frame0_mm, frame_names=names
        )
        if message is not None:
            raise InputError(message)
    units.check_depth_range(
        frame0_mm,
        sensor=sensor,
        depth_scale=depth_scale,
        name=str(path),
        action="refuse" if strict else "warn",
    )


def kernel_cache_warm() -> bool:
    """Whether numba's cache holds the method's kernels (``fusion`` is the one every run uses)."""
    import importlib.util

    spec = importlib.util.find_spec("upsr.method")
    if spec is None or not spec.submodule_search_locations:  # pragma: no cover
        return True
    folder = Path(next(iter(spec.submodule_search_locations)))
    if any((folder / "__pycache__").glob("fusion.*.nbi")):
        return True
    cache_dir = os.environ.get("NUMBA_CACHE_DIR")
    return bool(cache_dir) and any(Path(cache_dir).rglob("fusion.*.nbi"))


def kernel_note(quiet: bool = False) -> None:
    """Print :data:`KERNEL_NOTE` on stderr (once per process) when the kernel cache is cold."""
    if quiet or _STATE["noted"] or kernel_cache_warm():
        return
    _STATE["noted"] = True
    print(KERNEL_NOTE, file=sys.stderr, flush=True)


#: Frames :func:`frames_until_depth` reads at most to find one with depth.
UNITS_LOOKAHEAD_FRAMES = 30


def frames_until_depth(source: Iterator[Any]) -> list[Any]:
    """The frames of ``source`` up to the first with depth (the last one of the list), at
    most :data:`UNITS_LOOKAHEAD_FRAMES`: its units are checked (a camera's first frames are
    often empty); the caller processes them before the rest of ``source``."""
    read = [next(source)]
    while not (read[-1] > 0).any() and len(read) < UNITS_LOOKAHEAD_FRAMES:
        frame = next(source, None)
        if frame is None:
            break
        read.append(frame)
    return read


def check_first_frame(
    input_path: Path,
    frame0: Any,
    output: Path,
    n_frames: int,
    *,
    in_fmt: str,
    out_fmt: str,
    units_options: tuple[str, bool],
    scale_given: bool,
    scales: tuple[float, float],
) -> None:
    """Before any processing (``upsr run``, each recording of ``upsr batch``): the units of
    ``frame0``, the first frame with depth (``--sensor``, ``--strict-units``, SUN or TUM PNGs
    read as mm), whether the output format can hold ``n_frames`` frames, and whether a PNG
    output can hold that frame's depth at the output scale (``scales``: input, output raw
    units per metre)."""
    from upsr.io import units

    sensor, strict = units_options
    check_units(
        input_path,
        frame0,
        in_fmt=in_fmt,
        sensor=sensor,
        strict=strict,
        scale_given=scale_given,
        depth_scale=scales[0],
    )
    max_depth_mm = None  # (only a PNG output has a depth limit)
    if out_fmt == "png" and (frame0 > 0).any():
        max_depth_mm = float(frame0[frame0 > 0].max())
    units.check_output_capacity(
        output, n_frames, fmt=out_fmt, max_depth_mm=max_depth_mm, depth_scale=scales[1]
    )


def check_scale_applies(
    inputs: Sequence[Path],
    in_fmt: str | None,
    given: bool,
    topic: str | None = None,
    scale: float = 1000.0,
) -> None:
    """An input depth scale given on the command line, even 1000, is refused for an input
    whose format fixes its units (``nyu``, ``tum``, ``sun``): it would be ignored (a ROS bag's
    reader decides: 16-bit depth takes it, a RealSense recording or metres refuse it)."""
    if not given:
        return
    from upsr.io.registry import ReadOptions
    from upsr.io.video import ARRAY_FORMATS, SCALED_FORMATS, _input_format

    for path in inputs:
        f = _input_format(Path(path), in_fmt)
        if f == "rosbag":
            from upsr.io.rosbag import check_given_scale

            check_given_scale(Path(path), ReadOptions(topic=topic, depth_scale=scale))
        elif f not in SCALED_FORMATS + ARRAY_FORMATS:
            raise InputError(
                f"{path}: --input-depth-scale does not apply to {f} input, whose units the "
                f"format fixes"
            )


def read_options(
    key: str | None, topic: str | None, in_fmt: str | None, depth_scale: float | None,
    inputs: Sequence[Path],
) -> dict[str, Any]:  # fmt: skip
    """The keyword arguments of :func:`upsr.io.iter_frames` for the read options of
    ``inputs``; a depth scale given (not None) is checked by :func:`check_scale_applies`."""
    scale = 1000.0 if depth_scale is None else depth_scale
    check_scale_applies(inputs, in_fmt, depth_scale is not None, topic, scale)
    return {"key": key, "topic": topic, "fmt": in_fmt, "depth_scale": scale}


def check_sidecar(path: Path, overwrite: bool, inputs: Sequence[Path | str | None]) -> None:
    """``OUTPUT.intrinsics.json``, before any processing: a name the file system takes, not
    one of the inputs (an ``--intrinsics`` file named so was written over), and an existing
    one replaced only with ``--overwrite`` (it was replaced silently)."""
    from upsr._atomic import NAME_MAX

    if len(path.name.encode("utf-8", "surrogateescape")) > NAME_MAX:
        raise InputError(
            f"{path.name[:40]}…: the name of the intrinsics file beside the output is longer "
            f"than {NAME_MAX} bytes: give the output a shorter name"
        )
    if not os.path.lexists(path):
        return
    for inp in inputs:
        if inp is not None and os.path.exists(inp) and os.path.samefile(inp, path):
            raise InputError(f"{path}: the output's intrinsics file would replace the input {inp}")
    if not overwrite:
        raise InputError(f"{path} already exists (use --overwrite to replace it)")


@contextlib.contextmanager
def removed_on_failure(folder: Path) -> Iterator[None]:
    """An output folder the command creates is removed again if the command fails (``upsr
    experiment`` on a bad ``--data``, ``upsr demo`` on a full disk left it behind, empty or
    with part of its files); a folder that existed is left as it is."""
    existed = os.path.lexists(folder)
    try:
        yield
    except BaseException:
        if not existed:
            shutil.rmtree(folder, ignore_errors=True)
        raise
