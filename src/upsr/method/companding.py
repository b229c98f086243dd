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
fitted on the video's first frame with depth (:func:`knee_mm`): the level steps between its
distinct depths must follow α·z² (:func:`level_spacing`); on continuous depth (ToF, renders,
whole-mm integers of a sensor that does not quantise disparity) there is no knee and nothing
changes.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.method.validation import MAX_DEPTH_MM

__all__ = [
    "KNEE_STEPS",
    "MAX_ALPHA",
    "MIN_LEVELS",
    "NOISY_SHARE",
    "compand",
    "expand",
    "knee_mm",
    "level_spacing",
]

#: The edge threshold is this many level steps at the knee (and, in u, beyond it): two
#: neighbouring levels are one surface, two levels apart are two. Chosen on
#: ``benchmarks/outside_eval.py`` (the Kinect walls, corridor, hand and slanted scenes) beside
#: 1.2 and 1.5 (the corridor's far edges merged: its windowed edge accuracy 81.4 → 80.4 and
#: 78.2 %; the walls alike).
KNEE_STEPS = 1.05
#: Fewest distinct depths whose steps can show a level spacing.
MIN_LEVELS = 4
#: Share of the samples (each weighs on the step to the next level) whose step lies within
#: ×[2/3, 3/2] of α·z²: a disparity-quantised frame has 0.997–1.0.
CONSISTENT_SHARE = 0.8
#: Share of the horizontal neighbour pairs that differ: a noisy frame (the Kinect scenes of
#: ``benchmarks/outside_eval.py``: 0.58–0.86); a clean render's surfaces differ only at their
#: edges (thin legs and their mixed pixels on a wall, 64 % of whose pixels are leg or mix: 0.11).
NOISY_SHARE = 0.3
#: The coarsest level step of a camera, α per mm (20 mm at 1 m; a Kinect: 2.9 mm, 1/8 px of
#: disparity at f·b = 580 px · 75 mm): coarser steps are a render's few surfaces.
MAX_ALPHA = 2e-5


def level_spacing(frame: npt.ArrayLike) -> float | None:
    """α (1/mm) of the level step q(z) = α·z² between the distinct depths of a frame quantised
    in disparity, or None where its depths are not so quantised.

    α is the sample-weighted median of step / z² over the frame's distinct depths (each
    step at the depth between its two levels). The frame is taken as quantised where it holds
    at least :data:`MIN_LEVELS` distinct depths, at least :data:`CONSISTENT_SHARE` of the
    samples step to the next level by α·z² within a factor 1.5, α is at most
    :data:`MAX_ALPHA` and at least :data:`NOISY_SHARE` of its horizontal neighbour pairs
    differ (noise dithers a surface over its levels; a clean render does not).

    Parameters
    ----------
    frame : array_like (h, w)
        Depth (mm), 0 or NaN = no measurement.

    Returns
    -------
    float or None
    """
    f = np.asarray(frame, np.float64)
    z = f[np.isfinite(f) & (f > 0)]
    levels, counts = np.unique(z, return_counts=True)
    if levels.size < MIN_LEVELS:
        return None
    step = np.diff(levels)
    mid2 = (0.5 * (levels[1:] + levels[:-1])) ** 2
    ratio = step / mid2
    weight = counts[:-1].astype(np.float64)
    order = np.argsort(ratio)
    cum = np.cumsum(weight[order])
    alpha = float(ratio[order][np.searchsorted(cum, 0.5 * cum[-1])])
    fits = (step >= alpha * mid2 / 1.5) & (step <= 1.5 * alpha * mid2)
    if alpha > MAX_ALPHA or weight[fits].sum() < CONSISTENT_SHARE * weight.sum():
        return None
    f = np.nan_to_num(f)
    left, right = f[:, :-1], f[:, 1:]
    pairs = (left > 0) & (right > 0)
    differ = int((pairs & (left != right)).sum())
    return alpha if differ >= NOISY_SHARE * max(int(pairs.sum()), 1) else None


def knee_mm(frame: npt.ArrayLike, edge_mm: float) -> float:
    """The depth (mm) beyond which a video's depth is companded, from its first frame with
    depth (h, w): where the level step α·z² (:func:`level_spacing`) reaches ``edge_mm`` /
    :data:`KNEE_STEPS`; ``math.inf`` (no companding) where the frame is not quantised in
    disparity or no depth of it lies beyond that."""
    alpha = level_spacing(frame)
    if alpha is None or not alpha > 0:
        return math.inf
    knee = math.sqrt(edge_mm / (KNEE_STEPS * alpha))
    f = np.asarray(frame, np.float64)
    top = float(np.nanmax(f)) if f.size else 0.0
    return knee if knee < top else math.inf


def compand(depth: npt.ArrayLike, knee: float) -> np.ndarray:
    """Depth (mm, any shape, 0 = no measurement) companded beyond ``knee`` mm:
    u = 2·z_k − z_k²/z there, z elsewhere (float32; the array itself for ``knee`` = inf)."""
    z = np.asarray(depth, np.float32)
    if not math.isfinite(knee):
        return z
    out = np.empty_like(z)
    _compand_kernel(np.ascontiguousarray(z).reshape(-1), float(knee), out.reshape(-1))
    return out


def expand(companded: npt.ArrayLike, knee: float) -> np.ndarray:
    """The inverse of :func:`compand` (float32): z = z_k² / (2·z_k − u) beyond the knee, at most
    :data:`~upsr.method.validation.MAX_DEPTH_MM` (a deblurring step beyond the companded
    range's end)."""
    u = np.asarray(companded, np.float32)
    if not math.isfinite(knee):
        return u
    out = np.empty_like(u)
    top = 2.0 * knee - knee * knee / MAX_DEPTH_MM
    _expand_kernel(np.ascontiguousarray(u).reshape(-1), float(knee), top, out.reshape(-1))
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _compand_kernel(z: np.ndarray, knee: float, out: np.ndarray) -> None:  # pragma: no cover
    k = np.float32(knee)
    two_k, k2 = np.float32(2.0 * knee), np.float32(knee * knee)
    for i in range(z.size):  # (branch-free: both sides, one kept; 0 stays 0)
        v = z[i]
        out[i] = two_k - k2 / v if v > k else v


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _expand_kernel(  # pragma: no cover
    u: np.ndarray, knee: float, top: float, out: np.ndarray
) -> None:
    k = np.float32(knee)
    two_k, k2, t = np.float32(2.0 * knee), np.float32(knee * knee), np.float32(top)
    for i in range(u.size):
        v = u[i]
        out[i] = k2 / (two_k - min(v, t)) if v > k else v
