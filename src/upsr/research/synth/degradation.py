"""Sensor degradations applied to clean synthetic depth (``SPEC.md`` §1 noise model).

All functions take depth in mm (0 or NaN = no measurement), return a new float32 array of the
same shape and leave invalid pixels invalid (0). Randomness comes only from the
``numpy.random.Generator`` passed in, so results are reproducible.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError

__all__ = [
    "KINECT_BASELINE_MM",
    "KINECT_DISPARITY_STEP_PX",
    "KINECT_FOCAL_PX",
    "add_depth_dependent_noise",
    "add_laplacian_noise",
    "dropout",
    "flying_pixel_artefacts",
    "kinect",
    "kinect_axial_sigma_mm",
    "projector_shadows",
    "quantise_disparity",
    "tof_footprint",
]

#: Kinect v1 IR focal length (px at 640×480), projector–camera baseline (mm) and disparity
#: step (px): the sub-pixel refinement of the PrimeSense chip reports disparity in 1/8 px
#: (Khoshelham & Elberink 2012, "Accuracy and resolution of Kinect depth data", Sensors 12).
KINECT_FOCAL_PX = 580.0
KINECT_BASELINE_MM = 75.0
KINECT_DISPARITY_STEP_PX = 0.125

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


# --------------------------------------------------------------------------------------------
# Time-of-flight footprint
# --------------------------------------------------------------------------------------------


def tof_footprint(truth: npt.ArrayLike, r: int, *, min_valid_fraction: float = 0.5) -> np.ndarray:
    """Time-of-flight pixel footprint: each low-res pixel is the mean of its r×r truth block.

    A ToF pixel integrates the light returned over its whole footprint; with one depth per
    return the measured depth is (to first order) the mean of the depths in the footprint.
    Across a depth edge this mixes foreground and background into a *flying pixel* (Lefloch
    et al. 2013, "Technical foundation and calibration methods for time-of-flight cameras",
    LNCS 8200). Invalid truth pixels (0, no surface) return no light: they are left out of the
    mean, and the pixel reports no return (0) when fewer than ``min_valid_fraction`` of its
    block has depth. Block (i, j) covers truth rows r·i … r·i+r−1 and columns r·j … r·j+r−1,
    so the low-res pixel is centred where ``SPEC.md`` §1 puts it.

    Parameters
    ----------
    truth : array_like, shape (..., r·h, r·w)
        High-res depth (mm); 0 or NaN = no surface. Both image sides must be multiples of r.
    r : int
        Footprint size (the SR factor), ≥ 1.
    min_valid_fraction : float
        Smallest share in [0, 1] of valid truth pixels a block needs to return a depth.

    Returns
    -------
    ndarray of float32, shape (..., h, w)
        Depth (mm), 0 = no return.
    """
    arr = _as_depth(truth)
    if isinstance(r, bool) or not isinstance(r, (int, np.integer)) or r < 1:
        raise InputError(f"r must be an integer >= 1, got {r!r}")
    r = int(r)
    min_valid_fraction = _check_fraction(min_valid_fraction, "min_valid_fraction")
    big_h, big_w = arr.shape[-2:]
    if big_h % r or big_w % r:
        raise InputError(f"truth shape {arr.shape[-2:]} is not a multiple of r = {r}")
    blocks = arr.reshape(*arr.shape[:-2], big_h // r, r, big_w // r, r).astype(np.float64)
    valid = blocks > 0
    count = valid.sum(axis=(-3, -1))
    total = blocks.sum(axis=(-3, -1))
    keep = (count > 0) & (count >= min_valid_fraction * r * r)
    out = np.where(keep, total / np.maximum(count, 1), 0.0)
    return out.astype(np.float32)


# --------------------------------------------------------------------------------------------
# Depth-dependent noise
# --------------------------------------------------------------------------------------------

#: σ(z) as a callable of depth (mm, array) returning mm, or polynomial coefficients
#: (c0, c1, c2, …) in mm of σ = Σ c_k · z_m^k with z_m the depth in **metres**.
SigmaModel = Callable[[np.ndarray], npt.ArrayLike] | Sequence[float] | float


def _sigma_of_depth(sigma: SigmaModel, z_mm: np.ndarray) -> np.ndarray:
    if callable(sigma):
        out = np.asarray(sigma(z_mm), dtype=np.float64)
        out = np.broadcast_to(out, z_mm.shape)
    else:
        coeffs = np.atleast_1d(np.asarray(sigma, dtype=np.float64))
        if coeffs.ndim != 1 or coeffs.size == 0:
            raise InputError(f"sigma coefficients must be a 1-D sequence, got {sigma!r}")
        z_m = z_mm / 1000.0
        out = np.zeros_like(z_mm, dtype=np.float64)
        for c in coeffs[::-1]:  # Horner
            out = out * z_m + c
    if not np.isfinite(out).all() or (out < 0).any():
        raise InputError("sigma(z) must be finite and >= 0 on the valid depths")
    return out


def add_depth_dependent_noise(
    depth: npt.ArrayLike,
    sigma: SigmaModel,
    rng: np.random.Generator,
    *,
    law: Literal["laplace", "gaussian"] = "laplace",
    min_depth_mm: float = MIN_DEPTH_MM,
) -> np.ndarray:
    """Add independent zero-mean noise of depth-dependent standard deviation σ(z).

    Parameters
    ----------
    depth : array_like, shape (..., h, w)
        Clean depth (mm); 0 or NaN = invalid (stays 0).
    sigma : callable, sequence of float or float
        σ(z) in mm. A callable gets the valid depths (mm, float64 array) and returns σ (mm);
        a sequence (c0, c1, c2, …) means σ = c0 + c1·z_m + c2·z_m² + … mm with z_m the depth in
        metres; a float is a constant σ.
    rng : numpy.random.Generator
    law : {"laplace", "gaussian"}
        Laplace of scale σ/√2 (``SPEC.md`` §1) or Gaussian of std σ.
    min_depth_mm : float
        Noisy depths are clipped from below at this value (noise never invalidates a pixel).

    Returns
    -------
    ndarray of float32, same shape.
    """
    out = _as_depth(depth)
    rng = _check_rng(rng)
    if law not in ("laplace", "gaussian"):
        raise InputError(f"law must be 'laplace' or 'gaussian', got {law!r}")
    if not (min_depth_mm > 0):
        raise InputError(f"min_depth_mm must be > 0, got {min_depth_mm!r}")
    valid = out > 0
    if not valid.any():
        return out
    z = out[valid].astype(np.float64)
    s = _sigma_of_depth(sigma, z)
    if law == "laplace":
        noise = rng.laplace(0.0, 1.0, size=z.size) * (s / math.sqrt(2.0))
    else:
        noise = rng.standard_normal(z.size) * s
    out[valid] = np.maximum(z + noise, min_depth_mm)
    return out


# --------------------------------------------------------------------------------------------
# Structured light (Kinect v1)
# --------------------------------------------------------------------------------------------


def kinect_axial_sigma_mm(depth_mm: npt.ArrayLike) -> np.ndarray:
    """Axial noise std of the Kinect v1 versus depth: σ_z = 1.2 + 1.9·(z_m − 0.4)² mm.

    The fit of Nguyen, Izadi & Lovell 2012 ("Modeling Kinect sensor noise for improved 3D
    reconstruction and tracking", 3DIMPVT), σ_z(z) = 0.0012 + 0.0019·(z − 0.4)² m, written in
    mm with z_m the depth in metres (valid for 0.5–3 m and surfaces facing the sensor).

    Parameters
    ----------
    depth_mm : array_like
        Depth (mm).

    Returns
    -------
    ndarray of float64, σ_z in mm, same shape.
    """
    z_m = np.asarray(depth_mm, dtype=np.float64) / 1000.0
    return 1.2 + 1.9 * (z_m - 0.4) ** 2


def quantise_disparity(
    depth: npt.ArrayLike,
    *,
    focal_px: float = KINECT_FOCAL_PX,
    baseline_mm: float = KINECT_BASELINE_MM,
    step_px: float = KINECT_DISPARITY_STEP_PX,
) -> np.ndarray:
    """Quantise depth as a triangulation sensor does: disparity d = f·b/z rounded to a step.

    d = f·b/z is rounded to the nearest multiple of ``step_px`` and turned back into
    z = f·b/d. The depth step grows as Δz ≈ z²·step/(f·b): 1.5 mm at 0.8 m, 9 mm at 2 m,
    21 mm at 3 m for the Kinect v1 (f = 580 px, b = 75 mm, 1/8 px).

    Parameters
    ----------
    depth : array_like, shape (..., h, w)
        Depth (mm); 0 or NaN = invalid (stays 0).
    focal_px : float
        Focal length f (px) of the disparity measurement.
    baseline_mm : float
        Projector–camera baseline b (mm).
    step_px : float
        Disparity quantum (px).

    Returns
    -------
    ndarray of float32, same shape; a depth whose disparity rounds to 0 becomes 0.
    """
    out = _as_depth(depth)
    for name, val in (("focal_px", focal_px), ("baseline_mm", baseline_mm), ("step_px", step_px)):
        if not (math.isfinite(float(val)) and float(val) > 0):
            raise InputError(f"{name} must be a finite number > 0, got {val!r}")
    valid = out > 0
    fb = float(focal_px) * float(baseline_mm)
    d = np.round(fb / out[valid].astype(np.float64) / step_px) * step_px
    with np.errstate(divide="ignore"):
        z = np.where(d > 0, fb / np.where(d > 0, d, 1.0), 0.0)
    out[valid] = z
    return out


def projector_shadows(
    depth: npt.ArrayLike,
    *,
    focal_px: float,
    baseline_mm: float = KINECT_BASELINE_MM,
    projector_side: Literal["right", "left"] = "right",
    tolerance_px: float = 0.0,
) -> np.ndarray:
    """Set to 0 the pixels the projector of a structured-light sensor cannot illuminate.

    The projector sits ``baseline_mm`` beside the camera along the image x axis. A surface
    point seen in column u at disparity d = f·b/z projects to the projector's column u − d
    (projector on the right) or u + d (left). The point lies in the shadow of a nearer surface
    when a pixel on the projector's side of it, in the same row, reaches a projector column at
    or beyond its own: ``min_{k>j} (k − d_k) < j − d_j − tolerance`` (projector on the right).
    Beside a depth edge from z_near to z_far this blanks a band of
    f·b·(1/z_near − 1/z_far) px on the background, on the side of the foreground away from the
    projector (the far side of the jump as seen from the projector).

    Parameters
    ----------
    depth : array_like, shape (..., h, w)
        Depth (mm); 0 or NaN = no surface (casts no shadow).
    focal_px : float
        Focal length (px) of the image ``depth`` is sampled on (580 at 640×480 for Kinect v1).
    baseline_mm : float
        Projector–camera baseline b (mm).
    projector_side : {"right", "left"}
        Side of the camera (image +x or −x) where the projector is.
    tolerance_px : float
        Margin (px) by which a pixel must be hidden to count as shadowed (0: exact).

    Returns
    -------
    ndarray of float32, same shape; shadowed pixels are 0.
    """
    out = _as_depth(depth)
    if not (math.isfinite(float(focal_px)) and focal_px > 0):
        raise InputError(f"focal_px must be a finite number > 0, got {focal_px!r}")
    if not (math.isfinite(float(baseline_mm)) and baseline_mm > 0):
        raise InputError(f"baseline_mm must be a finite number > 0, got {baseline_mm!r}")
    if projector_side not in ("right", "left"):
        raise InputError(f"projector_side must be 'right' or 'left', got {projector_side!r}")
    work = out if projector_side == "right" else out[..., ::-1]
    valid = work > 0
    w = work.shape[-1]
    disp = np.where(valid, float(focal_px) * float(baseline_mm) / np.where(valid, work, 1.0), 0.0)
    cols = np.arange(w, dtype=np.float64)
    proj = np.where(valid, cols - disp, np.inf)  # projector column reached by each pixel
    # smallest projector column over the pixels strictly to the right (towards the projector)
    suffix = np.minimum.accumulate(proj[..., ::-1], axis=-1)[..., ::-1]
    right_min = np.concatenate([suffix[..., 1:], np.full((*proj.shape[:-1], 1), np.inf)], -1)
    shadow = valid & (right_min < proj - float(tolerance_px))
    work = work.copy()
    work[shadow] = 0.0
    return work if projector_side == "right" else np.ascontiguousarray(work[..., ::-1])


def kinect(
    depth: npt.ArrayLike,
    rng: np.random.Generator,
    *,
    focal_px: float = KINECT_FOCAL_PX,
    image_focal_px: float | None = None,
    baseline_mm: float = KINECT_BASELINE_MM,
    step_px: float = KINECT_DISPARITY_STEP_PX,
    dropout_fraction: float = 0.01,
    projector_side: Literal["right", "left"] = "right",
) -> np.ndarray:
    """Kinect v1 (structured light) degradation of a clean depth frame or video.

    In this order: projector shadows beside depth edges (:func:`projector_shadows`, with the
    focal length of the image), Gaussian axial noise of std :func:`kinect_axial_sigma_mm`
    (Nguyen et al. 2012), disparity quantisation to ``step_px`` with f = ``focal_px``,
    b = ``baseline_mm`` (:func:`quantise_disparity`: the native 640×480 disparity sets the depth
    resolution whatever the image size), and random dropouts (:func:`dropout`).

    Parameters
    ----------
    depth : array_like, shape (..., h, w)
        Clean depth (mm); 0 or NaN = no surface.
    rng : numpy.random.Generator
    focal_px : float
        Focal length (px) of the disparity quantisation (580 for the Kinect v1).
    image_focal_px : float, optional
        Focal length (px) of the image ``depth`` is sampled on, for the shadow widths.
        Default: ``focal_px · w / 640`` (the Kinect's field of view at width w).
    baseline_mm, step_px : float
        Baseline (mm) and disparity quantum (px).
    dropout_fraction : float
        Share of pixels lost at random (default 1 %).
    projector_side : {"right", "left"}

    Returns
    -------
    ndarray of float32, same shape.
    """
    out = _as_depth(depth)
    rng = _check_rng(rng)
    if image_focal_px is None:
        image_focal_px = float(focal_px) * out.shape[-1] / 640.0
    out = projector_shadows(
        out, focal_px=image_focal_px, baseline_mm=baseline_mm, projector_side=projector_side
    )
    out = add_depth_dependent_noise(out, kinect_axial_sigma_mm, rng, law="gaussian")
    out = quantise_disparity(out, focal_px=focal_px, baseline_mm=baseline_mm, step_px=step_px)
    return dropout(out, dropout_fraction, rng)
