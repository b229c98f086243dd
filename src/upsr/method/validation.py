"""Checks and normalisation of depth inputs.

Conventions (``docs/SPEC.md`` §1): depth is in millimetres; 0 and NaN mean "no
measurement". Everything else must be a finite, non-negative number.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError

__all__ = [
    "MAX_DEPTH_MM",
    "as_depth_frame",
    "as_depth_video",
    "check_ref",
    "nan_as_zero",
    "no_valid_depth",
    "within_range",
]

#: Largest depth accepted (mm): 1 km. Depth cameras measure metres; a larger value is a unit
#: error or garbage (and 1e38 mm overflows float32 arithmetic into ±inf downstream).
MAX_DEPTH_MM = 1e6


def nan_as_zero(depth_mm: npt.ArrayLike) -> np.ndarray:
    """``depth_mm`` as float32 with NaN ("no measurement") as 0, what
    ``np.nan_to_num(np.asarray(depth_mm, np.float32), nan=0.0)`` gives, but the array itself,
    not a copy, where it is float32 and finite already (every frame :func:`as_depth_frame`
    checked, and what the method makes of them): for the method's functions that only read
    it (a copy of a 640×480 frame costs a millisecond, and a frame passes through a dozen).

    Parameters
    ----------
    depth_mm : array_like
        Depth (mm; 0 or NaN: no measurement).

    Returns
    -------
    ndarray float32, same shape; never to be written into (it may be ``depth_mm``).
    """
    z = np.asarray(depth_mm, np.float32)
    return z if np.isfinite(z).all() else np.nan_to_num(z, nan=0.0)


def as_depth_frame(
    frame: npt.ArrayLike,
    *,
    name: str = "frame",
    valid_range_mm: tuple[float, float] | None = None,
    mm_per_unit: float = 1.0,
) -> np.ndarray:
    """Return ``frame`` as a float32 (h, w) depth map in mm with invalid pixels set to 0.

    Parameters
    ----------
    frame : array_like
        (h, w) depth in mm, float or unsigned/signed integer; 0 or NaN = no measurement.
    name : str
        How to call the array in error messages.
    valid_range_mm : (float, float), optional
        (min, max): depths outside are no measurement (0), as a depth camera SDK's
        threshold filter makes them (``UPSRConfig.valid_range_mm``).
    mm_per_unit : float
        The frame's unit in mm (1 for mm; 1000 for metres): the product is taken in float64
        and rounded once (2.021 m is 2021 mm, not the float32 product's 2020.9999).

    Raises
    ------
    InputError
        Wrong number of dimensions, empty, non-numeric dtype, ±inf or negative depths.
    """
    arr = np.asarray(frame)
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)
    ):
        raise InputError(
            f"{name}: depth must be a numeric array (float or integer), got dtype {arr.dtype}"
        )
    if arr.ndim != 2:
        raise InputError(f"{name}: expected a 2-D depth frame (h, w), got shape {arr.shape}")
    if arr.size == 0:
        raise InputError(f"{name}: empty depth frame of shape {arr.shape}")
    if np.issubdtype(arr.dtype, np.floating) and np.isinf(arr).any():
        raise InputError(f"{name}: depth contains ±inf (use 0 or NaN for 'no measurement')")
    with np.errstate(over="ignore", invalid="ignore"):  # > float32 max: inf, refused below
        if mm_per_unit == 1.0:
            out = arr.astype(np.float32, copy=True)
        else:
            out = np.empty(arr.shape, np.float32)
            np.multiply(arr, float(mm_per_unit), out=out, dtype=np.float64, casting="unsafe")
    if np.issubdtype(arr.dtype, np.floating):
        np.nan_to_num(out, copy=False, nan=0.0, posinf=np.inf, neginf=-np.inf)
    if (out < 0).any():
        raise InputError(f"{name}: depth contains negative values (min {float(out.min()):g} mm)")
    top = float(out.max())
    if top > MAX_DEPTH_MM:
        big = float(np.nanmax(arr)) * mm_per_unit if np.issubdtype(arr.dtype, np.floating) else top
        raise InputError(
            f"{name}: depth {big:.3g} mm is beyond {MAX_DEPTH_MM:g} mm (1 km): wrong units "
            f"or corrupt data"
        )
    return within_range(out, valid_range_mm)


def within_range(depth: np.ndarray, valid_range_mm: tuple[float, float] | None) -> np.ndarray:
    """``depth`` (mm, any shape) with the depths outside ``valid_range_mm`` = (min, max) set to
    0 (no measurement; in place where it is float32); unchanged for None."""
    if valid_range_mm is None:
        return depth
    lo, hi = valid_range_mm
    out = np.asarray(depth, np.float32)
    out[(out < lo) | (out > hi)] = 0.0
    return out


def as_depth_video(
    frames: npt.ArrayLike,
    *,
    name: str = "input",
    valid_range_mm: tuple[float, float] | None = None,
) -> np.ndarray:
    """Return ``frames`` (an array, a sequence or an iterator of frames) as a float32
    (T, h, w) depth video in mm, invalid pixels set to 0.

    A single (h, w) frame is not accepted: a video is 3-D. Individual empty (all-invalid)
    frames are allowed, a video with no valid depth at all is not.

    Raises
    ------
    InputError
        Wrong shape or dtype, NaN-free ±inf, negative depths, no valid depth anywhere (within
        ``valid_range_mm``, see :func:`as_depth_frame`).
    """
    if isinstance(frames, Iterator):  # a generator of frames: np.asarray makes an object array
        frames = list(frames)
    arr = np.asarray(frames)
    if arr.dtype == object:
        raise InputError(f"{name}: object arrays are not depth data")
    if arr.ndim != 3:
        raise InputError(
            f"{name}: expected a depth video of shape (T, h, w), got shape {arr.shape}"
        )
    if 0 in arr.shape:
        raise InputError(f"{name}: empty depth video of shape {arr.shape}")
    out = np.empty(arr.shape, np.float32)
    for t in range(arr.shape[0]):
        out[t] = as_depth_frame(arr[t], name=f"{name} frame {t}", valid_range_mm=valid_range_mm)
    if not (out > 0).any():
        raise InputError(f"{name}: {no_valid_depth(valid_range_mm)}")
    return out


def check_ref(ref: object, n_frames: int) -> int:
    """The reference frame's index of a window of ``n_frames`` (None: the middle one), an
    integer in [0, n_frames), else :class:`~upsr.errors.InputError` (a bool is no index)."""
    if ref is None:
        return (n_frames - 1) // 2
    if isinstance(ref, bool) or not isinstance(ref, (int, np.integer)) or not 0 <= ref < n_frames:
        raise InputError(f"ref must be an integer in [0, {n_frames}), got {ref!r}")
    return int(ref)


def no_valid_depth(valid_range_mm: tuple[float, float] | None = None) -> str:
    """The error of a video without any valid depth (within ``valid_range_mm``)."""
    if valid_range_mm is None:
        return "no valid depth in any frame (all pixels are 0 or NaN)"
    lo, hi = valid_range_mm
    return f"no valid depth in any frame (all pixels are 0 or NaN, or outside {lo:g}-{hi:g} mm)"
