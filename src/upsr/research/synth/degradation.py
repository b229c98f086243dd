"""Sensor degradations applied to clean synthetic depth (``SPEC.md`` §1 noise model).

All functions take depth in mm (0 or NaN = no measurement), return a new float32 array of the
same shape and leave invalid pixels invalid (0). Randomness comes only from the
``numpy.random.Generator`` passed in, so results are reproducible.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError

__all__ = ["add_laplacian_noise", "dropout", "flying_pixel_artefacts"]

#: Smallest depth (mm) a valid pixel may take after noise: noise never makes a pixel invalid.
MIN_DEPTH_MM = 1.0


def _as_depth(depth: npt.ArrayLike) -> np.ndarray:
    arr = np.asarray(depth)
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)
    ):
        raise InputError(f"depth must be a numeric array, got dtype {arr.dtype}")
    if arr.ndim < 2:
        raise InputError(f"depth must be at least 2-D (..., h, w), got shape {arr.shape}")
    out = arr.astype(np.float32)
    if np.isinf(out).any():
        raise InputError("depth contains ±inf (use 0 or NaN for 'no measurement')")
    out[np.isnan(out)] = 0.0
    if (out < 0).any():
        raise InputError(f"depth contains negative values (min {float(out.min()):g} mm)")
    return out


def _check_rng(rng: np.random.Generator) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise InputError(
            f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), got {rng!r}"
        )
    return rng


def _check_fraction(value: float, name: str) -> float:
    value = float(value)
    if not (0.0 <= value <= 1.0):
        raise InputError(f"{name} must be in [0, 1], got {value!r}")
    return value


def add_laplacian_noise(
    depth: npt.ArrayLike,
    sigma_mm: float,
    rng: np.random.Generator,
    *,
    min_depth_mm: float = MIN_DEPTH_MM,
) -> np.ndarray:
    """Add i.i.d. Laplacian noise of standard deviation ``sigma_mm`` to the valid pixels.

    The density is (√2 / 2σ)·exp(−√2 |n| / σ), i.e. a Laplace law of scale b = σ/√2 (paper
    eq. 1, ``SPEC.md`` §1).

    Parameters
    ----------
    depth : array_like, shape (..., h, w)
        Clean depth (mm); 0 or NaN = invalid.
    sigma_mm : float
        Noise standard deviation σ (mm), ≥ 0.
    rng : numpy.random.Generator
        Source of randomness.
    min_depth_mm : float
        Noisy valid depths are clipped from below at this positive value so that noise never
        turns a measurement into "no measurement".

    Returns
    -------
    ndarray of float32, same shape; invalid pixels stay 0.
    """
    out = _as_depth(depth)
    sigma_mm = float(sigma_mm)
    if not (math.isfinite(sigma_mm) and sigma_mm >= 0):
        raise InputError(f"sigma_mm must be a finite number >= 0, got {sigma_mm!r}")
    if not (min_depth_mm > 0):
        raise InputError(f"min_depth_mm must be > 0, got {min_depth_mm!r}")
    rng = _check_rng(rng)
    valid = out > 0
    if sigma_mm == 0 or not valid.any():
        return out
    noise = rng.laplace(0.0, sigma_mm / math.sqrt(2.0), size=int(valid.sum()))
    out[valid] = np.maximum(out[valid] + noise, min_depth_mm)
    return out


def dropout(depth: npt.ArrayLike, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """Set each pixel to 0 (no return) independently with probability ``fraction``.

    Parameters
    ----------
    depth : array_like, shape (..., h, w)
        Depth (mm); 0 or NaN = invalid.
    fraction : float
        Probability in [0, 1] that a pixel is lost.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray of float32, same shape.
    """
    out = _as_depth(depth)
    fraction = _check_fraction(fraction, "fraction")
    rng = _check_rng(rng)
    if fraction > 0:
        out[rng.random(out.shape) < fraction] = 0.0
    return out


def flying_pixel_artefacts(
    depth: npt.ArrayLike,
    rng: np.random.Generator,
    *,
    probability: float = 0.5,
    threshold_mm: float = 100.0,
) -> np.ndarray:
    """Time-of-flight mixed pixels: edge pixels return a blend of foreground and background.

    A simple model of the "flying pixels" of ToF cameras: each valid pixel that has a valid
    4-neighbour more than ``threshold_mm`` away is, with probability ``probability``, replaced
    by w·d + (1 − w)·d_n with w ~ U(0, 1), d its depth and d_n that of its most distant such
    neighbour.

    Parameters
    ----------
    depth : array_like, shape (..., h, w)
        Depth (mm); 0 or NaN = invalid.
    rng : numpy.random.Generator
    probability : float
        Probability in [0, 1] that an edge pixel is mixed.
    threshold_mm : float
        Depth jump (mm) between 4-neighbours that counts as an edge.

    Returns
    -------
    ndarray of float32, same shape.
    """
    out = _as_depth(depth)
    probability = _check_fraction(probability, "probability")
    rng = _check_rng(rng)
    valid = out > 0
    # depth of the most distant valid 4-neighbour (NaN where none is beyond the threshold)
    partner = np.full(out.shape, np.nan, np.float32)
    gap = np.zeros(out.shape, np.float32)
    for axis in (-2, -1):
        for shift in (1, -1):
            nb = np.roll(out, shift, axis=axis)
            nb_valid = np.roll(valid, shift, axis=axis)
            # np.roll wraps around: the wrapped row/column has no neighbour
            edge = [slice(None)] * out.ndim
            edge[axis] = slice(0, 1) if shift == 1 else slice(-1, None)
            nb_valid[tuple(edge)] = False
            diff = np.abs(nb - out)
            better = valid & nb_valid & (diff > threshold_mm) & (diff > gap)
            partner[better] = nb[better]
            gap[better] = diff[better]
    chosen = np.isfinite(partner) & (rng.random(out.shape) < probability)
    w = rng.random(int(chosen.sum())).astype(np.float32)
    out[chosen] = w * out[chosen] + (1 - w) * partner[chosen]
    return out
