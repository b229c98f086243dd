"""Accuracy metrics of a super-resolved depth map against its ground truth (``SPEC.md`` §6).

Everything is in millimetres (mm) and pixels (px) of the high-resolution grid. Depth 0 or NaN
means "no measurement" (invalid), in the estimate as in the truth. The arrays compared are
(h, w) frames or (T, h, w) videos of equal shape; for a video the spatial neighbourhoods are
taken per frame and the statistics are pooled over all pixels of all frames.

Definitions (r is the super-resolution factor, used as a radius in px):

- *discontinuity*: a pixel with a 4-neighbour whose true depth differs by more than
  ``discontinuity_mm`` (100 mm), a valid ↔ invalid transition counting as a discontinuity;
- *near a discontinuity*: within r px (Chebyshev distance: a (2r+1)×(2r+1) square) of one;
- ``mse`` / ``rmse``: squared error over the pixels valid in **both** truth and estimate
  (missing outputs are reported by ``missing``, not folded into the error);
- ``surface_rmse``: the same over such pixels farther than r px from any discontinuity;
- ``edge_accuracy``: of the truth-valid pixels near a discontinuity, the share whose estimate is
  valid and within ``edge_tolerance_mm`` (100 mm) of the truth; a missing output is wrong;
- ``flying_pixels``: of the estimate-valid pixels near a discontinuity, the share whose depth is
  more than ``flying_mm`` (150 mm) away from every valid true depth in its (2r+1)×(2r+1)
  neighbourhood;
- ``missing``: share of the truth-valid pixels that are invalid in the estimate;
- ``invented``: share of the truth-invalid pixels that are valid in the estimate.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from upsr.errors import InputError

__all__ = [
    "discontinuity_mask",
    "edge_accuracy",
    "evaluate",
    "flying_pixel_mask",
    "flying_pixels",
    "invented",
    "missing",
    "mse",
    "near_discontinuity",
    "rmse",
    "surface_rmse",
]

DISCONTINUITY_MM = 100.0
EDGE_TOLERANCE_MM = 100.0
FLYING_MM = 150.0


# --------------------------------------------------------------------------- input checks
def _as_depth(a: npt.ArrayLike, name: str) -> np.ndarray:
    """``a`` as float64 (h, w) or (T, h, w) depth in mm with invalid (NaN) pixels set to 0."""
    arr = np.asarray(a)
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)
    ):
        raise InputError(f"{name}: depth must be a numeric array, got dtype {arr.dtype}")
    if arr.ndim not in (2, 3):
        raise InputError(
            f"{name}: expected a depth frame (h, w) or video (T, h, w), got shape {arr.shape}"
        )
    if arr.size == 0:
        raise InputError(f"{name}: empty depth array of shape {arr.shape}")
    out = arr.astype(np.float64)
    if np.isinf(out).any():
        raise InputError(f"{name}: depth contains ±inf (use 0 or NaN for 'no measurement')")
    out[np.isnan(out)] = 0.0
    if (out < 0).any():
        raise InputError(f"{name}: depth contains negative values (min {out.min():g} mm)")
    return out


def _pair(estimate: npt.ArrayLike, truth: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    est = _as_depth(estimate, "estimate")
    tru = _as_depth(truth, "truth")
    if est.shape != tru.shape:
        raise InputError(f"estimate shape {est.shape} differs from truth shape {tru.shape}")
    if not (tru > 0).any():
        raise InputError("truth: no valid depth (all pixels are 0 or NaN); nothing to evaluate")
    return est, tru


def _check_radius(r: int) -> int:
    if isinstance(r, bool) or not isinstance(r, (int, np.integer)) or r < 0:
        raise InputError(f"r (radius in px, the SR factor) must be an integer >= 0, got {r!r}")
    return int(r)


def _check_mm(value: float, name: str) -> float:
    """``value`` as a finite float ≥ 0 (mm); booleans and non-numbers are refused."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{name} must be a finite number >= 0 (mm), got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and v >= 0):
        raise InputError(f"{name} must be a finite number >= 0 (mm), got {value!r}")
    return v


def _share(numerator: np.ndarray, denominator: np.ndarray) -> float:
    """``sum(numerator & denominator) / sum(denominator)``; NaN for an empty denominator."""
    n = int(np.count_nonzero(denominator))
    if n == 0:
        return math.nan
    return float(np.count_nonzero(numerator & denominator)) / n


def _as3d(a: np.ndarray) -> np.ndarray:
    return a[None] if a.ndim == 2 else a


# --------------------------------------------------------------------------- masks
def discontinuity_mask(truth: npt.ArrayLike, threshold_mm: float = DISCONTINUITY_MM) -> np.ndarray:
    """Pixels with a 4-neighbour across a depth discontinuity.

    Parameters
    ----------
    truth : array_like, shape (h, w) or (T, h, w)
        True depth (mm); 0 or NaN = invalid.
    threshold_mm : float
        A neighbour pair is a discontinuity when both are valid and their depths differ by more
        than ``threshold_mm``, or when exactly one of them is valid.

    Returns
    -------
    ndarray of bool, same shape as ``truth``
        True on both pixels of every discontinuous pair (frames are independent; the image
        border is not a discontinuity).
    """
    t = _as_depth(truth, "truth")
    threshold_mm = _check_mm(threshold_mm, "threshold_mm")
    valid = t > 0
    mask = np.zeros(t.shape, bool)
    for axis in (-2, -1):
        a = [slice(None)] * t.ndim
        b = [slice(None)] * t.ndim
        a[axis] = slice(None, -1)
        b[axis] = slice(1, None)
        ta, tb = t[tuple(a)], t[tuple(b)]
        va, vb = valid[tuple(a)], valid[tuple(b)]
        jump = (va != vb) | (va & vb & (np.abs(ta - tb) > threshold_mm))
        mask[tuple(a)] |= jump
        mask[tuple(b)] |= jump
    return mask


def _dilate(mask: np.ndarray, r: int) -> np.ndarray:
    """Per-frame square (2r+1)×(2r+1) dilation of a boolean (h, w) or (T, h, w) mask."""
    if r == 0:
        return mask.copy()
    size = (2 * r + 1, 2 * r + 1) if mask.ndim == 2 else (1, 2 * r + 1, 2 * r + 1)
    out = ndimage.maximum_filter(mask.view(np.uint8), size=size, mode="constant", cval=0)
    return out.astype(bool)


def near_discontinuity(
    truth: npt.ArrayLike, r: int, threshold_mm: float = DISCONTINUITY_MM
) -> np.ndarray:
    """Pixels within ``r`` px (Chebyshev distance) of a discontinuity of ``truth``.

    Parameters
    ----------
    truth : array_like, shape (h, w) or (T, h, w)
        True depth (mm); 0 or NaN = invalid.
    r : int
        Radius in px (the SR factor); the discontinuity mask is dilated by a (2r+1)² square.
    threshold_mm : float
        Discontinuity threshold, see :func:`discontinuity_mask`.

    Returns
    -------
    ndarray of bool, same shape as ``truth``
    """
    r = _check_radius(r)
    return _dilate(discontinuity_mask(truth, threshold_mm), r)


def _min_abs_diff_to_valid(
    est: np.ndarray, tru: np.ndarray, where: np.ndarray, r: int
) -> np.ndarray:
    """For each pixel in ``where``: min |est − truth(q)| over valid q in the (2r+1)² square.

    Invalid true depths count as +inf (never close). Returns a 1-D array in ``np.nonzero``
    order of ``where``. Cost: (2r+1)² vectorised gathers over the selected pixels only.
    """
    e3, t3, w3 = _as3d(est), _as3d(tru), _as3d(where)
    t_inf = np.where(t3 > 0, t3, np.inf)
    padded = np.pad(t_inf, ((0, 0), (r, r), (r, r)), constant_values=np.inf)
    ti, yi, xi = np.nonzero(w3)
    values = e3[ti, yi, xi]
    best = np.full(values.shape, np.inf)
    for dy in range(2 * r + 1):
        for dx in range(2 * r + 1):
            np.minimum(best, np.abs(values - padded[ti, yi + dy, xi + dx]), out=best)
    return best


def flying_pixel_mask(
    estimate: npt.ArrayLike,
    truth: npt.ArrayLike,
    r: int,
    *,
    flying_mm: float = FLYING_MM,
    discontinuity_mm: float = DISCONTINUITY_MM,
) -> np.ndarray:
    """Flying pixels of ``estimate``: valid outputs near an edge that match no true depth there.

    A pixel is flying when its estimate is valid, it lies within ``r`` px of a discontinuity of
    the truth, and its depth is more than ``flying_mm`` away from every valid true depth in its
    (2r+1)×(2r+1) neighbourhood (typically a value interpolated between foreground and
    background). The truth at the pixel itself need not be valid.

    Parameters
    ----------
    estimate, truth : array_like, shape (h, w) or (T, h, w)
        Depth in mm; 0 or NaN = invalid.
    r : int
        Radius in px (the SR factor).
    flying_mm : float
        Distance (mm) to the nearest plausible true depth above which a pixel is flying.
    discontinuity_mm : float
        Discontinuity threshold of the truth (mm).

    Returns
    -------
    ndarray of bool, same shape as the inputs
    """
    est, tru = _pair(estimate, truth)
    r = _check_radius(r)
    flying_mm = _check_mm(flying_mm, "flying_mm")
    candidates = (est > 0) & near_discontinuity(tru, r, discontinuity_mm)
    out = np.zeros(est.shape, bool)
    out[candidates] = _min_abs_diff_to_valid(est, tru, candidates, r) > flying_mm
    return out


# --------------------------------------------------------------------------- scalar metrics
def mse(estimate: npt.ArrayLike, truth: npt.ArrayLike) -> float:
    """Mean squared error (mm²) over pixels valid in both ``truth`` and ``estimate``.

    Missing outputs are not counted here (see :func:`missing`); NaN if no pixel is valid in
    both.
    """
    est, tru = _pair(estimate, truth)
    both = (est > 0) & (tru > 0)
    if not both.any():
        return math.nan
    return float(np.mean((est[both] - tru[both]) ** 2))


def rmse(estimate: npt.ArrayLike, truth: npt.ArrayLike) -> float:
    """Root mean squared error (mm) over pixels valid in both ``truth`` and ``estimate``."""
    return math.sqrt(mse(estimate, truth))


def surface_rmse(
    estimate: npt.ArrayLike,
    truth: npt.ArrayLike,
    r: int,
    *,
    discontinuity_mm: float = DISCONTINUITY_MM,
) -> float:
    """RMSE (mm) on smooth surfaces: pixels valid in both, farther than ``r`` px from any edge.

    NaN if there is no such pixel.
    """
    est, tru = _pair(estimate, truth)
    sel = (est > 0) & (tru > 0) & ~near_discontinuity(tru, r, discontinuity_mm)
    if not sel.any():
        return math.nan
    return math.sqrt(float(np.mean((est[sel] - tru[sel]) ** 2)))


def edge_accuracy(
    estimate: npt.ArrayLike,
    truth: npt.ArrayLike,
    r: int,
    *,
    tolerance_mm: float = EDGE_TOLERANCE_MM,
    discontinuity_mm: float = DISCONTINUITY_MM,
) -> float:
    """Share of truth-valid pixels within ``r`` px of an edge whose estimate is right.

    Right means valid and within ``tolerance_mm`` of the truth; a missing output is wrong.
    1.0 is perfect; NaN if the truth has no valid pixel near a discontinuity.
    """
    est, tru = _pair(estimate, truth)
    tolerance_mm = _check_mm(tolerance_mm, "tolerance_mm")
    sel = (tru > 0) & near_discontinuity(tru, r, discontinuity_mm)
    good = (est > 0) & (np.abs(est - tru) <= tolerance_mm)
    return _share(good, sel)


def flying_pixels(
    estimate: npt.ArrayLike,
    truth: npt.ArrayLike,
    r: int,
    *,
    flying_mm: float = FLYING_MM,
    discontinuity_mm: float = DISCONTINUITY_MM,
) -> float:
    """Share of flying pixels among estimate-valid pixels within ``r`` px of an edge.

    See :func:`flying_pixel_mask`. 0.0 is perfect; 0.0 also when there is no such pixel
    (nothing could fly).
    """
    est, tru = _pair(estimate, truth)
    cand = (est > 0) & near_discontinuity(tru, r, discontinuity_mm)
    if not cand.any():
        return 0.0
    fly = flying_pixel_mask(est, tru, r, flying_mm=flying_mm, discontinuity_mm=discontinuity_mm)
    return float(np.count_nonzero(fly)) / int(np.count_nonzero(cand))


def missing(estimate: npt.ArrayLike, truth: npt.ArrayLike) -> float:
    """Share of truth-valid pixels that are invalid (0 or NaN) in the estimate."""
    est, tru = _pair(estimate, truth)
    return _share(est <= 0, tru > 0)


def invented(estimate: npt.ArrayLike, truth: npt.ArrayLike) -> float:
    """Share of truth-invalid pixels that are valid in the estimate (0.0 if none is invalid)."""
    est, tru = _pair(estimate, truth)
    share = _share(est > 0, tru <= 0)
    return 0.0 if math.isnan(share) else share


def evaluate(
    estimate: npt.ArrayLike,
    truth: npt.ArrayLike,
    r: int,
    *,
    discontinuity_mm: float = DISCONTINUITY_MM,
    edge_tolerance_mm: float = EDGE_TOLERANCE_MM,
    flying_mm: float = FLYING_MM,
) -> dict[str, float]:
    """All metrics of ``SPEC.md`` §6 at once (the masks are computed once).

    Parameters
    ----------
    estimate, truth : array_like, shape (h, w) or (T, h, w)
        Depth in mm; 0 or NaN = invalid. For a video the statistics are pooled over all frames.
    r : int
        The SR factor, used as the edge radius in px.
    discontinuity_mm, edge_tolerance_mm, flying_mm : float
        Thresholds (mm), see the module docstring.

    Returns
    -------
    dict
        ``rmse`` (mm), ``mse`` (mm²), ``surface_rmse`` (mm), ``edge_accuracy``,
        ``flying_pixels``, ``missing``, ``invented`` (shares in [0, 1]), and the pixel counts
        ``n_truth_valid``, ``n_edge``, ``n_surface``, ``n_flying``. Undefined values are NaN.

    Raises
    ------
    InputError
        Shapes differ, not 2-D/3-D, negative or infinite depths, truth without valid pixel.
    """
    est, tru = _pair(estimate, truth)
    r = _check_radius(r)
    edge_tolerance_mm = _check_mm(edge_tolerance_mm, "edge_tolerance_mm")
    flying_mm = _check_mm(flying_mm, "flying_mm")
    ev, tv = est > 0, tru > 0
    near = near_discontinuity(tru, r, discontinuity_mm)
    both = ev & tv
    err2 = np.where(both, (est - tru) ** 2, 0.0)

    n_both = int(np.count_nonzero(both))
    mse_v = float(err2.sum()) / n_both if n_both else math.nan
    surface = both & ~near
    n_surface = int(np.count_nonzero(surface))
    surf_v = math.sqrt(float(err2[surface].sum()) / n_surface) if n_surface else math.nan

    edge = tv & near
    good = ev & (np.abs(est - tru) <= edge_tolerance_mm)

    cand = ev & near
    n_cand = int(np.count_nonzero(cand))
    n_flying = 0
    if n_cand:
        n_flying = int(np.count_nonzero(_min_abs_diff_to_valid(est, tru, cand, r) > flying_mm))

    inv = _share(ev, ~tv)
    return {
        "rmse": math.sqrt(mse_v),
        "mse": mse_v,
        "surface_rmse": surf_v,
        "edge_accuracy": _share(good, edge),
        "flying_pixels": n_flying / n_cand if n_cand else 0.0,
        "missing": _share(~ev, tv),
        "invented": 0.0 if math.isnan(inv) else inv,
        "n_truth_valid": float(np.count_nonzero(tv)),
        "n_edge": float(np.count_nonzero(edge)),
        "n_surface": float(n_surface),
        "n_flying": float(n_flying),
    }
