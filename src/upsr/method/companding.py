"""Depth quantised in disparity: the far depths companded so that one level is one surface.

Beyond the paper. Structured-light and stereo cameras measure disparity d = f·b / z and
quantise it (a Kinect: 1/8 px with f·b = 580 px · 75 mm), so the distinct depths a video holds
lie one level step q(z) = α·z² apart (α = 1/(8·f·b): 2.87e-6 / mm for a Kinect). Beyond the
depth where q(z) exceeds the edge threshold (``UPSRConfig.edge_mm``, 100 mm: 5.9 m on a
Kinect), two neighbouring levels of one wall are two surfaces to every rule of the method that
compares depths against that threshold (the fusion, the trust, the slopes, the deblurring's
pairs), and the output keeps the staircase of the levels: a static Kinect wall at 7 m came out
at 54.7 mm surface rmse, the temporal mean of the raw frames at 31.5
(``benchmarks/outside_eval.py --scenes kinect_wall``).

A threshold that grows as q(z) in every rule would follow the depth; instead the depth itself is
companded, once per video, before everything the method does, and expanded back in the output
(:func:`compand`, :func:`expand`): up to a knee z_k the depth is kept (u = z), beyond it

    u = 2·z_k − z_k² / z,  so that du/dz = (z_k / z)²,

which makes a level step beyond the knee the same u-step everywhere (q(z_k), just below the
edge threshold: :data:`KNEE_STEPS`), makes a Kinect's noise (σ ∝ z²) about constant there, and
is affine in the disparity 1/z (a plane stays a plane in u over the image). The knee is
fitted on the video's first frame with depth (:func:`knee_mm`; for the edge step the method
uses, scaled for a near scene: :func:`upsr.method.statistics.video_knee_mm`): the level steps
between its distinct depths must follow α·z² (:func:`level_spacing`); on continuous depth
(ToF, renders, whole-mm integers of a sensor that does not quantise disparity) there is no
knee, and below the knee nothing changes.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.method.sorting import weighted_median
from upsr.method.validation import MAX_DEPTH_MM

__all__ = [
    "CONSISTENT_SHARE",
    "KEPT_SHARE",
    "KNEE_STEPS",
    "MAX_ALPHA",
    "MIN_LEVELS",
    "NOISY_SHARE",
    "POWER_SPAN",
    "POWER_TOLERANCE",
    "UNIT_STEPS",
    "LevelSpacing",
    "compand",
    "expand",
    "knee_at_spacing",
    "knee_mm",
    "level_fit",
    "level_spacing",
]

#: The edge threshold is this many level steps at the knee (and, in u, beyond it): two
#: neighbouring levels are one surface, two levels apart are two. Chosen on the Kinect scenes
#: of ``benchmarks/outside_eval.py`` beside 1.2 and 1.5 (``benchmarks/companding_eval.py``: the
#: corridor's far edges merge, its windowed edge accuracy 81.4 → 80.5 and 78.3 %, the slanted
#: scene's 76.4 → 74.6 and 73.8 %; the Kinect walls' surface rmse 0.1–5.7 mm lower, most on
#: the walls at 4–5 m slanted 35°).
KNEE_STEPS = 1.05
#: Fewest distinct depths whose steps can show a level spacing.
MIN_LEVELS = 4
#: Share of the samples (each weighs on the step to the next level) whose step lies within
#: ×[2/3, 3/2] of α·z²: a disparity-quantised frame has 0.997–1.0.
CONSISTENT_SHARE = 0.8
#: Share of the neighbour pairs that differ, along the rows and along the columns (each): a
#: noisy frame (the Kinect scenes of ``benchmarks/outside_eval.py``: 0.58–0.86); a clean
#: render's surfaces differ only at their edges (thin legs and their mixed pixels on a wall,
#: 64 % of whose pixels are leg or mix: 0.11), and a clean plane slanted along the rows, whose
#: columns step by α·z² exactly, not at all along its columns.
NOISY_SHARE = 0.3
#: The coarsest level step of a camera, α per mm (100 mm at 1 m: 1 px of disparity at
#: f·b = 10⁴ px·mm; a Kinect: 2.9 mm, 1/8 px at f·b = 580 px · 75 mm; an integer-disparity
#: stereo camera of f = 440 px, b = 75 mm: 30 mm).
MAX_ALPHA = 1e-4
#: Steps of fewer depth units (1 mm where every depth is whole mm, 0.1 mm where tenths) say
#: nothing of the levels: near a camera its levels are finer than the units and the rounding
#: sets the steps (a D435's 1/32 px at f·b = 385 px · 50 mm: 1.2 mm at 0.6 m).
UNIT_STEPS = 3.0
#: Least share of the samples whose step to the next level is kept: most where the depth is
#: quantised in disparity (a D435 with 30 % of its frame at 0.6 m: 0.7; a Kinect with 62 % at
#: 0.7 m: 0.38); few where whole mm of continuous noise step by 1 or 2 mm but in the sparse
#: tails (0.2 let through a whole-mm 8 × 10 frame of a wall with σ = 30 mm).
KEPT_SHARE = 0.3
#: Where the fitting steps' depths span at least this ratio, the steps must grow as z^p with p
#: within :data:`POWER_TOLERANCE` of 2 (disparity levels); a ramp of whole mm, or a plane's
#: columns in depth, steps alike at every depth (p ≈ 0).
POWER_SPAN = 1.3
POWER_TOLERANCE = 0.75


class LevelSpacing(NamedTuple):
    """A frame's disparity levels (:func:`level_fit`)."""

    #: α (1/mm) of the level step q(z) = α·z².
    alpha: float
    #: The farthest over the nearest depth of the level steps α was fitted on.
    span: float

    @property
    def confirmed(self) -> bool:
        """Whether the steps were seen to grow as z² (over a span of :data:`POWER_SPAN` or
        more): over a narrow span depth in equal units of a few mm (a ToF camera's 4 mm)
        fits an α too."""
        return self.span >= POWER_SPAN


def level_spacing(frame: npt.ArrayLike) -> float | None:
    """α (1/mm) of :func:`level_fit`, or None where the frame's depths are not quantised in
    disparity."""
    fit = level_fit(frame)
    return None if fit is None else fit.alpha


def level_fit(frame: npt.ArrayLike) -> LevelSpacing | None:
    """The level step q(z) = α·z² between the distinct depths of a frame quantised in
    disparity, and the span of depths it was fitted over; None where its depths are not so
    quantised.

    α is the sample-weighted median of step / z² over the frame's distinct depths (each
    step at the depth between its two levels), of the steps of at least :data:`UNIT_STEPS`
    depth units. The frame is taken as quantised where those steps join at least
    :data:`MIN_LEVELS` distinct depths and :data:`KEPT_SHARE` of the samples, at least
    :data:`CONSISTENT_SHARE` of their samples step to the next level by α·z² within a factor
    1.5, those steps grow as z^p with p within :data:`POWER_TOLERANCE` of 2 where their depths
    span :data:`POWER_SPAN` or more, α is at most :data:`MAX_ALPHA`, and at least
    :data:`NOISY_SHARE` of the neighbour pairs differ along the rows and along the columns
    (noise dithers a surface over its levels; a clean render does not).

    Parameters
    ----------
    frame : array_like (h, w)
        Depth (mm), 0 or NaN = no measurement.

    Returns
    -------
    LevelSpacing or None
    """
    f = np.nan_to_num(np.asarray(frame, np.float64))
    levels, counts = np.unique(f[f > 0], return_counts=True)
    z_count = counts[:-1].sum()
    if levels.size < MIN_LEVELS:
        return None
    step = np.diff(levels)
    kept = step >= UNIT_STEPS * _unit(levels)  # (not set by the units' rounding)
    if np.count_nonzero(kept) < MIN_LEVELS - 1 or counts[:-1][kept].sum() < KEPT_SHARE * z_count:
        return None
    step = step[kept]
    mid2 = ((0.5 * (levels[1:] + levels[:-1])) ** 2)[kept]
    ratio = step / mid2
    weight = counts[:-1][kept].astype(np.float64)
    alpha = weighted_median(ratio, weight)
    fits = (step >= alpha * mid2 / 1.5) & (step <= 1.5 * alpha * mid2)
    if alpha > MAX_ALPHA or weight[fits].sum() < CONSISTENT_SHARE * weight.sum():
        return None
    z = np.sqrt(mid2[fits])
    fit = LevelSpacing(float(alpha), float(z.max() / z.min()))
    if fit.confirmed and not _grows_as_z2(np.log(step[fits]), np.log(z), weight[fits]):
        return None
    for a, b in ((f[:, :-1], f[:, 1:]), (f[:-1], f[1:])):  # along the rows, the columns
        pairs = (a > 0) & (b > 0)
        if int((pairs & (a != b)).sum()) < NOISY_SHARE * max(int(pairs.sum()), 1):
            return None
    return fit


def _grows_as_z2(log_step: np.ndarray, log_z: np.ndarray, weight: np.ndarray) -> bool:
    """Whether the steps grow as z² (weighted least squares of log step on log z; asked
    where the levels span :data:`POWER_SPAN` or more, ``LevelSpacing.confirmed``)."""
    mz = np.average(log_z, weights=weight)
    ms = np.average(log_step, weights=weight)
    var = np.average((log_z - mz) ** 2, weights=weight)
    power = np.average((log_z - mz) * (log_step - ms), weights=weight) / var
    return abs(power - 2.0) <= POWER_TOLERANCE


def _unit(levels: np.ndarray) -> float:
    """1 (mm) where every depth is whole mm, 0.1 where tenths, else 0 (continuous)."""
    for unit in (1.0, 0.1):
        scaled = levels / unit
        if np.all(np.abs(scaled - np.round(scaled)) <= 1e-3 * np.maximum(1.0, scaled * 1e-4)):
            return unit
    return 0.0


def knee_mm(frame: npt.ArrayLike, edge_mm: float) -> float:
    """The depth beyond which a video's depth is companded, from its first frame with depth:
    where the level step α·z² (:func:`level_spacing`) reaches ``edge_mm`` /
    :data:`KNEE_STEPS`, whether or not the frame holds depth beyond it (a camera that turns
    from a near wall to a far one).

    Parameters
    ----------
    frame : array_like (h, w)
        Depth (mm), 0 or NaN = no measurement.
    edge_mm : float
        The edge step the method compares depths with (mm).

    Returns
    -------
    float: z_k (mm); ``math.inf`` (no companding) where the frame is not quantised in
    disparity.
    """
    return knee_at_spacing(level_spacing(frame), edge_mm)


def knee_at_spacing(alpha: float | None, edge_mm: float) -> float:
    """:func:`knee_mm` from a frame's :func:`level_spacing` α (1/mm; None: not quantised in
    disparity, ``math.inf``)."""
    if alpha is None or not alpha > 0:
        return math.inf
    return math.sqrt(edge_mm / (KNEE_STEPS * alpha))


def compand(depth: npt.ArrayLike, knee: float) -> np.ndarray:
    """Depth companded beyond a knee: u = 2·z_k − z_k²/z beyond it, z elsewhere.

    Parameters
    ----------
    depth : array_like (any shape)
        Depth (mm), 0 or NaN = no measurement (kept).
    knee : float
        z_k (mm); ``math.inf``: nothing is companded.

    Returns
    -------
    ndarray float32, C-ordered, same shape (for ``knee`` = inf: ``depth`` as float32, the
    array itself where it is one)
    """
    z = np.asarray(depth, np.float32)
    if not math.isfinite(knee):
        return z
    z = np.ascontiguousarray(z)
    out = np.empty(z.shape, np.float32)  # (C order: its flat view is the kernel's output)
    _compand_kernel(z.reshape(-1), float(knee), out.reshape(-1))
    return out


def expand(companded: npt.ArrayLike, knee: float) -> np.ndarray:
    """The inverse of :func:`compand`: z = z_k² / (2·z_k − u) beyond the knee.

    Parameters
    ----------
    companded : array_like (any shape)
        u (mm in :func:`compand`'s units), 0 = no measurement (kept).
    knee : float
        z_k (mm); ``math.inf``: nothing is expanded.

    Returns
    -------
    ndarray float32, C-ordered, same shape: depth (mm), at most
    :data:`~upsr.method.validation.MAX_DEPTH_MM` (a deblurring step beyond the companded
    range's end).
    """
    u = np.asarray(companded, np.float32)
    if not math.isfinite(knee):
        return u
    u = np.ascontiguousarray(u)
    out = np.empty(u.shape, np.float32)
    top = 2.0 * knee - knee * knee / MAX_DEPTH_MM
    _expand_kernel(u.reshape(-1), float(knee), top, out.reshape(-1))
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _compand_kernel(z: np.ndarray, knee: float, out: np.ndarray) -> None:  # pragma: no cover
    k = np.float32(knee)
    two_k, k2 = np.float32(2.0 * knee), np.float32(knee * knee)
    for i in range(z.size):
        v = z[i]
        out[i] = two_k - k2 / v if v > k else v


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _expand_kernel(  # pragma: no cover
    u: np.ndarray, knee: float, top: float, out: np.ndarray
) -> None:
    k = np.float32(knee)
    two_k, k2, t = np.float32(2.0 * knee), np.float32(knee * knee), np.float32(top)
    cap = np.float32(MAX_DEPTH_MM)  # (float32 cancellation near the top)
    for i in range(u.size):
        v = u[i]
        out[i] = min(k2 / (two_k - min(v, t)), cap) if v > k else v
