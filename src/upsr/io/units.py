"""Depth units: the checks the command line runs before any processing.

:func:`resolve_depth_scales`
    Input and output depth scales kept apart (raw units per metre): ``--depth-scale`` is the
    input's (the old spelling), ``--input-depth-scale`` / ``--output-depth-scale`` name each.
:func:`check_depth_range`
    The depth of the first frame(s), after scaling, against the plausible range of the sensor
    (default 50 mm – 100 m): values far outside mean a wrong unit (metres read as mm, TUM's
    1/5000 m read as mm, …); the message says which scale would fit.
:func:`detect_tum_scale`
    A folder of PNGs read as plain mm PNGs whose values and names look like TUM RGB-D (5000
    units per metre): the message says to use ``--input-format tum``.
:func:`check_output_capacity`
    Whether an output can hold the video (a single ``.exr`` holds one frame; 16-bit PNG tops
    out at 65535 raw units), checked before processing.
"""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from upsr.errors import InputError
from upsr.io._base import PathLike, check_depth_scale

__all__ = [
    "MIN_PNG_DEPTH_SCALE",
    "SENSOR_RANGES_MM",
    "DepthRange",
    "DepthUnitWarning",
    "check_depth_range",
    "check_output_capacity",
    "detect_sun_packing",
    "detect_tum_scale",
    "resolve_depth_scales",
]

#: Plausible depth (mm) of each sensor: (nearest, farthest) a valid pixel can have.
SENSOR_RANGES_MM: dict[str, tuple[float, float]] = {
    "default": (50.0, 100_000.0),
    "realsense": (50.0, 65_535.0),  # D4xx: ~0.1 m minimum-Z at low resolution, 16-bit units
    "kinect": (300.0, 12_000.0),  # Kinect v1 / Xtion (NYU, TUM)
    "kinect2": (300.0, 12_000.0),
    "tof": (50.0, 15_000.0),
    "lidar": (50.0, 300_000.0),
}


class DepthUnitWarning(UserWarning):
    """Depth values outside the plausible range of the sensor (probably a wrong unit)."""


@dataclass(frozen=True)
class DepthRange:
    """What :func:`check_depth_range` measured.

    Attributes
    ----------
    median_mm, p01_mm, p99_mm : float
        Median, 1st and 99th percentile of the valid depth (mm).
    outside : float
        Fraction of the valid pixels outside [min_mm, max_mm].
    message : str or None
        One line when the range is implausible (None: fine).
    """

    median_mm: float
    p01_mm: float
    p99_mm: float
    outside: float
    message: str | None


def resolve_depth_scales(
    depth_scale: float | None = None,
    input_depth_scale: float | None = None,
    output_depth_scale: float | None = None,
) -> tuple[float, float]:
    """(input, output) depth scales, raw units per metre.

    The rule: ``depth_scale`` (``--depth-scale``) is the input's only; the output is in mm
    (1000) unless ``output_depth_scale`` says otherwise. Giving ``depth_scale`` and a different
    ``input_depth_scale`` is refused.
    """
    old, new, out = "--depth-scale", "--input-depth-scale", "--output-depth-scale"
    if depth_scale is not None and input_depth_scale is not None:
        if check_depth_scale(depth_scale, old) != check_depth_scale(input_depth_scale, new):
            raise InputError(
                f"--depth-scale {depth_scale} and --input-depth-scale {input_depth_scale} "
                f"disagree: give one (both are the input's raw units per metre)"
            )
    inp, name = (input_depth_scale, new) if input_depth_scale is not None else (depth_scale, old)
    s_in = check_depth_scale(1000.0 if inp is None else inp, name)
    s_out = check_depth_scale(1000.0 if output_depth_scale is None else output_depth_scale, out)
    return s_in, s_out


def _scale_hint(median_mm: float, lo: float, hi: float, depth_scale: float, option: str) -> str:
    """Which input depth scale (``option``) would bring the median into the sensor's range
    (and 0.2–20 m): mm first where another scale was given (raw values in mm read as metres
    look like cm)."""
    for label, factor in (
        *([("mm ({} 1000)", 1.0)] if depth_scale != 1000.0 else []),
        ("metres ({} 1)", 1000.0),
        ("cm ({} 100)", 10.0),
        ("TUM's 1/5000 m (--input-format tum or {} 5000)", 0.2),
        ("0.1 mm ({} 10000)", 0.1),
        ("µm ({} 1000000)", 0.001),
    ):
        guess = median_mm * factor * depth_scale / 1000.0
        if lo <= guess <= hi and 200.0 <= guess <= 20_000.0:
            return f" The raw values look like {label.format(option)}"
    return ""


def check_depth_range(
    frames_mm: np.ndarray | Iterable[np.ndarray],
    *,
    sensor: str = "default",
    min_mm: float | None = None,
    max_mm: float | None = None,
    depth_scale: float = 1000.0,
    name: str = "input",
    action: str = "warn",
    max_outside: float = 0.05,
    option: str = "--input-depth-scale",
) -> DepthRange:
    """Check that depth (mm, after scaling) lies in the sensor's plausible range.

    Parameters
    ----------
    frames_mm : ndarray (h, w) or (T, h, w), or iterable of frames
        Depth in mm (0 / NaN = none), e.g. the first frame read.
    sensor : str
        A key of :data:`SENSOR_RANGES_MM` (default 50 mm – 100 m).
    min_mm, max_mm : float, optional
        Override the sensor's range.
    depth_scale : float
        The input depth scale used (for the hint of the message).
    name : str
        The input, for the message.
    action : {"warn", "refuse", "ignore"}
        When more than ``max_outside`` of the valid pixels (or the median) leave the range:
        warn (:class:`DepthUnitWarning`), raise InputError, or only report.
    option : str
        The command line option of the input's depth scale, for the message's hint.

    Returns
    -------
    DepthRange
    """
    if sensor not in SENSOR_RANGES_MM:
        raise InputError(f"unknown sensor {sensor!r} (one of: {', '.join(SENSOR_RANGES_MM)})")
    if action not in ("warn", "refuse", "ignore"):
        raise ValueError(f"action must be warn, refuse or ignore, got {action!r}")
    lo, hi = SENSOR_RANGES_MM[sensor]
    lo = lo if min_mm is None else float(min_mm)
    hi = hi if max_mm is None else float(max_mm)
    arrays = [frames_mm] if isinstance(frames_mm, np.ndarray) else list(frames_mm)
    vals = np.concatenate([np.asarray(a, np.float64).reshape(-1) for a in arrays])
    vals = vals[np.isfinite(vals) & (vals > 0)]
    if vals.size == 0:
        return DepthRange(math.nan, math.nan, math.nan, 0.0, None)
    p01, med, p99 = (float(v) for v in np.percentile(vals, [1, 50, 99]))
    outside = float(np.mean((vals < lo) | (vals > hi)))
    message = None
    if outside > max_outside or not lo <= med <= hi:
        # (the advice first: the one-line limit must not cut it)
        message = (
            f"{name}: wrong depth units?{_scale_hint(med, lo, hi, depth_scale, option)}: "
            f"{100 * outside:.0f}% of the depth outside {lo:g}–{hi:g} mm, plausible for a "
            f"{sensor} sensor (median {med:.4g} mm)"
        )
        if action == "refuse":
            raise InputError(message)
        if action == "warn":
            warnings.warn(message, DepthUnitWarning, stacklevel=2)
    return DepthRange(med, p01, p99, outside, message)


_TUM_NAME = re.compile(r"^[0-9]{9,10}\.[0-9]{3,9}$")


def detect_tum_scale(
    path: PathLike, raw: np.ndarray, *, frame_names: Iterable[str] | None = None
) -> str | None:
    """A one-line message when a PNG input read as plain mm PNGs looks like TUM RGB-D.

    TUM RGB-D stores 5000 units per metre: an indoor scene (0.5–5 m) gives raw values of
    2500–25000, i.e. 2.5–25 m when taken as mm. Flagged when the raw values fit TUM's range
    (median 2500–40000, 99th percentile > 10000, beyond a Kinect's 8–10 m when read as mm) and
    either the names are TUM timestamps (``1305031102.175304``) or the folder sits in a TUM
    sequence (``rgb.txt``/``depth.txt`` beside it), or the values alone exclude mm (99th
    percentile > 20000, i.e. 20 m for a Kinect-type sensor); or, at any median 2500–40000
    (a near scene), both the names and the sequence are TUM's.

    Parameters
    ----------
    path : path-like
        The PNG file or folder.
    raw : ndarray
        Raw 16-bit values of one or more frames (as stored, before any scale).
    frame_names : iterable of str, optional
        The frames' stems (default: looked up from ``path``).

    Returns
    -------
    str or None
        The message (None: does not look like TUM).
    """
    p = Path(path)
    v = np.asarray(raw).reshape(-1)
    v = v[v > 0].astype(np.float64)
    if v.size == 0:
        return None
    med, p99 = (float(x) for x in np.percentile(v, [50, 99]))
    if not 2500 <= med <= 40_000:
        return None
    if frame_names is None:
        frame_names = [p.stem] if p.is_file() else sorted(x.stem for x in p.glob("*.png"))
    names = list(frame_names)
    folder = p if p.is_dir() else p.parent
    named = bool(names) and all(_TUM_NAME.match(n) for n in names)
    sequence = any((folder.parent / f).is_file() for f in ("rgb.txt", "depth.txt"))
    # (a TUM sequence's layout and names: whatever the depth, a desk at 0.8 m too)
    if (p99 > 10_000 and (named or sequence or p99 > 20_000)) or (named and sequence):
        why = "TUM timestamp names" if named else "a TUM sequence" if sequence else "the values"
        # (the advice first: a long path must not push it past the one-line limit)
        return (
            f"{p.name}: use --input-format tum or --input-depth-scale 5000 (1000 keeps mm): "
            f"looks like TUM RGB-D depth, 5000 units/m ({why}; median {med / 5000:.2f} m, "
            f"{med / 1000:.1f} m as mm)"
        )
    return None


#: Share of the valid raw values that must be multiples of 8 for :func:`detect_sun_packing`
#: (a plain mm PNG has 1/8 of them by chance).
SUN_PACKED_SHARE = 0.95
#: ... of at least this many distinct values (a constant frame, e.g. 30000 everywhere, is a
#: multiple of 8 by chance; the SUN fixture's 64×48 crop of a wall has 10).
SUN_MIN_DISTINCT = 4


def detect_sun_packing(path: PathLike, raw: np.ndarray) -> str | None:
    """A one-line message when a PNG input read as plain mm PNGs looks like SUN RGB-D.

    SUN RGB-D rotates each 16-bit depth value (mm) left by 3 bits: below 8.192 m every raw
    value is 8 times the depth, so (nearly) all of them are multiples of 8, which a plain mm
    PNG's are by chance only (1 in 8), and their eighths lie in a camera's range. Flagged when
    at least :data:`SUN_PACKED_SHARE` of at least 100 valid raw values (of at least
    :data:`SUN_MIN_DISTINCT` distinct ones) are multiples of 8 and their eighths have a median
    of 300 mm – 10 m.

    Parameters
    ----------
    path : path-like
        The PNG file or folder (for the message).
    raw : ndarray
        Raw 16-bit values of one or more frames (as stored, before any scale).

    Returns
    -------
    str or None
        The message (None: does not look like SUN RGB-D).
    """
    v = np.asarray(raw).reshape(-1)
    v = v[np.isfinite(v) & (v > 0)]
    # (a few distinct values, e.g. a constant frame, say nothing about the packing)
    if v.size < 100 or np.any(v != np.round(v)) or np.unique(v).size < SUN_MIN_DISTINCT:
        return None
    packed = float(np.mean(np.mod(v, 8) == 0))
    med = float(np.median(v)) / 8.0
    if packed < SUN_PACKED_SHARE or not 300.0 <= med <= 10_000.0:
        return None
    return (
        f"{Path(path).name}: use --input-format sun: looks like SUN RGB-D depth, each value "
        f"rotated by 3 bits ({100 * packed:.0f} % of the raw values are multiples of 8; "
        f"median {med / 1000:.2f} m unpacked, {8 * med / 1000:.1f} m as mm)"
    )


#: Fewest raw units per metre of a 16-bit PNG output (100: 1 cm steps).
MIN_PNG_DEPTH_SCALE = 100.0


def check_output_capacity(
    path: PathLike,
    n_frames: int,
    *,
    fmt: str | None = None,
    max_depth_mm: float | None = None,
    depth_scale: float = 1000.0,
) -> None:
    """Refuse, before processing, an output that cannot hold ``n_frames`` frames.

    - a single ``.exr`` or ``.png`` file holds one frame (write a folder: a name without
      suffix, with ``--format exr`` for EXR frames);
    - a 16-bit PNG folder holds raw values ≤ 65535: with ``max_depth_mm`` (the input's
      largest depth) beyond 65535 / depth_scale m, refused with the scale that fits;
    - a 16-bit PNG holds whole raw units: below :data:`MIN_PNG_DEPTH_SCALE` units per metre
      (steps of more than 1 cm; 1 = whole metres) the depth would be rounded away.

    Raises
    ------
    InputError
        With one line saying what to change.
    """
    from upsr.io.video import _folder_output, _output_format

    p = Path(path)
    f = _output_format(p, fmt)
    if n_frames < 1:
        raise InputError(f"{p}: nothing to write ({n_frames} frames)")
    if f in ("exr", "png") and not _folder_output(f, p) and n_frames > 1:
        how = "--format exr and an output name" if f == "exr" else "an output name"
        raise InputError(
            f"{p}: a single .{f} file holds one frame, the video has {n_frames}: write a "
            f"folder of {f.upper()} frames ({how} without suffix)"
        )
    if f == "png" and check_depth_scale(depth_scale) < MIN_PNG_DEPTH_SCALE:
        raise InputError(
            f"{p}: a 16-bit PNG at --output-depth-scale {depth_scale:g} stores depth in steps "
            f"of {1000.0 / depth_scale:g} mm: use {MIN_PNG_DEPTH_SCALE:g} or more (1000 = mm), "
            f"or a float format (.npy, .tif, .exr)"
        )
    if f == "png" and max_depth_mm is not None:
        raw_max = max_depth_mm * check_depth_scale(depth_scale) / 1000.0
        if raw_max > 65535:
            fit = math.floor(65535 * 1000.0 / max_depth_mm)
            raise InputError(
                f"{p}: 16-bit PNG holds at most 65535 raw units: depth up to "
                f"{max_depth_mm:.0f} mm at {depth_scale:g} units/m needs {raw_max:.0f}; use "
                f"--output-depth-scale {fit} or less, or a float format (.npy, .tif, .exr)"
            )
