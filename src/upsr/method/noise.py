"""Robust estimates of the noise of depth images.

:func:`estimate_noise_mm` (1.4826·MAD/√2 of neighbour differences): the per-video noise level
of UP-SR (edge threshold and spurious-motion margin, fixed from the first window by
:class:`upsr.method.windowed.UPSR`) and the first step of the deblurring
(:func:`upsr.method.deblurring.deblur`).

:func:`noise_profile` (beyond the paper): how the noise grows with depth, σ(z) = σ₁·(z/1 m)^p.
Time-of-flight noise hardly depends on depth (p ≈ 0); the noise of structured-light and stereo
cameras grows about as z² (the disparity noise and its quantisation, Nguyen et al. 2012: a
Kinect's σ is 7 mm at 2 m and 16 mm at 3 m). One σ per video then trusts the misregistered
samples of near surfaces, distrusts the samples of far ones and smooths every surface alike;
the trust tolerance (:func:`upsr.method.trust.reference_anchor`), the significance of the
radial offsets (:func:`upsr.method.trust.radial_offsets`) and each pixel's deblurring step
(:func:`upsr.method.deblurring.deblur`) follow σ(z) instead.

:func:`temporal_noise_mm` (beyond the paper): the std of the temporal differences of static
pixels. :func:`tail_ratio`: how heavy the tails of the spatial noise are, and
:func:`quantisation_step`: how far apart the depth's levels lie in noise stds, which choose
the fusion's estimator (:func:`choose_estimator`: the median for heavy tails, the mean of the
trusted samples for Gaussian or quantised noise).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method.sorting import weighted_median

__all__ = [
    "NOISE_FREE_MM",
    "PROFILE_BIN_RATIO",
    "PROFILE_MAX_POWER",
    "PROFILE_MAX_PX",
    "PROFILE_MIN_POWER",
    "PROFILE_MIN_SAMPLES",
    "PROFILE_MIN_SPAN",
    "QUANTISED_STEPS",
    "TAIL_QUANTILES",
    "TAIL_RATIO_MEDIAN",
    "choose_estimator",
    "estimate_noise_mm",
    "noise_at_depth",
    "noise_profile",
    "quantisation_step",
    "second_differences",
    "spatial_noise_mm",
    "tail_ratio",
    "temporal_noise_mm",
]

#: :func:`tail_ratio` above which the noise is heavy-tailed and the median is kept: halfway
#: between i.i.d. Gaussian noise (1.955) and Laplacian noise (2.205). On the realistic scenes
#: (seeds 0–2, 64×56, Laplace σ = 5–80, Gauss σ = 10–80, ToF σ = 10 / 20): Gaussian 1.92–2.02,
#: Laplacian 2.10–2.35. (The excess kurtosis of the temporal differences, 0.75 between
#: Gaussian 0 and Laplacian 1.5, chose before: it reads the motion of a moving camera as heavy
#: tails, 2.2–2.9 for the room at Gauss 20, whose surfaces came out 2–11 % worse with the
#: median, static ones up to 18 %.)
TAIL_RATIO_MEDIAN = 2.06
#: :func:`tail_ratio`'s quantiles of the absolute second differences.
TAIL_QUANTILES = (0.9, 0.6)
#: Below this spatial noise (mm, :func:`estimate_noise_mm`) the frames show none: noise-free
#: depth, or quantised depth whose neighbours mostly agree (a Kinect's 0 mm); the recursive
#: mode's trust noise then comes from the temporal differences (:func:`temporal_noise_mm`).
NOISE_FREE_MM = 1.0
#: Depth quantised in steps of at least this many noise stds (:func:`quantisation_step`) is
#: fused by the mean of the trusted samples whatever its tails: the median of quantised
#: samples is one of the levels, the mean falls between them. A Kinect-like sensor (disparity
#: in 1/8 px, Nguyen et al.'s noise) gives 1.1–1.7, float samples of continuous noise 0.00,
#: the same rounded to whole mm 0.02–0.10 (the realistic scenes, seeds 0–2); the median's
#: static surfaces there were up to 5× worse (4.9 against 1.0 mm on the deforming body's wall).
QUANTISED_STEPS = 0.5

#: Depth bins of :func:`noise_profile`: each this factor deeper than the previous (far wider
#: than the noise, so that the noise does not choose a sample's bin).
PROFILE_BIN_RATIO = 1.2
#: Fewest second differences in a bin of :func:`noise_profile`.
PROFILE_MIN_SAMPLES = 400
#: :func:`noise_profile` uses the triples centred on every k-th row of larger frames, about
#: this many centres in all (three VGA frames: 0.06 s instead of 0.17).
PROFILE_MAX_PX = 1 << 18
#: Smallest ratio of the deepest to the nearest bin for a power to be fitted.
PROFILE_MIN_SPAN = 1.3
#: A fitted power below this is taken for noise that does not depend on depth (p = 0). On the
#: realistic scenes (4 scenes × 2 seeds, ``benchmarks/realistic_eval.py``) Laplacian, Gaussian
#: and ToF noise fit −0.27 … +0.07, the Kinect model 1.56 … 1.86.
PROFILE_MIN_POWER = 0.5
#: A fitted power above this is no sensor's noise (stereo and structured light: about 2) but
#: what is left of depth without noise (a clean render: rounding that grows with depth; a
#: 14 m corridor fitted p = 9.6, and the deblurring's steps at 12 m were 2.7 million times its
#: median step): taken for p = 0 (``UPSRConfig``'s trust_noise_profile allows up to 4 too).
PROFILE_MAX_POWER = 4.0


@nb.njit(cache=True, nogil=True)
def _select_pair(d, k, lo, hi):  # pragma: no cover - numba
    """The (k−1)-th and k-th smallest values of ``d`` (0-based, k ≥ 1), exactly, in O(n): a
    4096-bin histogram over [lo, hi] finds the bins that hold the two ranks, and only the
    values of those bins are sorted. (Four interleaved histograms: consecutive values often
    fall in one bin, and one counter would make each count wait for the previous one.)"""
    n_bins = 4096
    scale = n_bins / (hi - lo)
    n = d.size
    bins = np.empty(n, np.int32)
    for i in range(n):
        bins[i] = min(max(np.int64((d[i] - lo) * scale), 0), n_bins - 1)
    partial = np.zeros((4, n_bins), np.int32)
    n4 = n - n % 4
    for i in range(0, n4, 4):
        partial[0, bins[i]] += 1
        partial[1, bins[i + 1]] += 1
        partial[2, bins[i + 2]] += 1
        partial[3, bins[i + 3]] += 1
    for i in range(n4, n):
        partial[0, bins[i]] += 1
    counts = np.empty(n_bins, np.int64)
    for b in range(n_bins):
        counts[b] = partial[0, b] + partial[1, b] + partial[2, b] + partial[3, b]
    below = 0
    b = 0
    while below + counts[b] <= k - 1:
        below += counts[b]
        b += 1
    # rank k lies in bin b too, or in the next non-empty bin
    last = b
    while below + counts[b : last + 1].sum() <= k:
        last += 1
    members = np.empty(counts[b : last + 1].sum(), d.dtype)
    m = 0
    for i in range(n):
        if b <= bins[i] <= last:
            members[m] = d[i]
            m += 1
    members.sort()
    return members[k - 1 - below], members[k - below]


@nb.njit(cache=True, nogil=True)
def _median(d, lo, hi):  # pragma: no cover - numba
    """np.median of a float32 array with values in [lo, hi] (same float32 arithmetic)."""
    n = d.size
    if n == 1:
        return d[0]
    below, above = _select_pair(d, n // 2, lo, hi)
    if n % 2:
        return above
    return (below + above) / np.float32(2.0)


@nb.njit(cache=True, nogil=True)
def _robust_noise_kernel(z, lag, row_step):  # pragma: no cover - numba
    """1.4826·MAD/√2 of the valid same-surface differences ``lag`` px apart (see
    :func:`estimate_noise_mm`) from every ``row_step``-th row: one pass into one buffer,
    then two O(n) medians."""
    h, w = z.shape
    buf = np.empty(max(h * (w - lag), 0) + max((h - lag) * w, 0), np.float32)
    n = 0
    for di, dj in ((0, lag), (lag, 0)):
        for i in range(0, h - di, row_step):
            for j in range(w - dj):
                a = z[i + di, j + dj]
                b = z[i, j]
                if a > 0 and b > 0:
                    d = a - b
                    if abs(d) < 100.0:
                        buf[n] = d
                        n += 1
    if n == 0:
        return 0.0
    d = buf[:n]
    med = _median(d, np.float32(-100.0), np.float32(100.0))
    for i in range(n):
        d[i] = abs(d[i] - med)
    mad = _median(d, np.float32(0.0), np.float32(200.0))
    return np.float32(1.4826) * mad / np.sqrt(2.0)


def estimate_noise_mm(z: npt.ArrayLike, lag_px: int = 1, *, row_step: int = 1) -> float:
    """Robust std (mm) of the noise in a depth image.

    1.4826·MAD/√2 of the differences between pixels ``lag_px`` apart (horizontally and
    vertically), over pairs of valid pixels on one surface (|Δ| < 100 mm). Use the SR factor as
    the lag for a fused image, whose noise comes in r×r blocks. Compiled: one pass, no
    temporaries, two O(n) medians; the same value as the NumPy version
    (:func:`upsr.research.oracle.estimate_noise_mm_numpy`).

    Parameters
    ----------
    z : array_like (H, W)
        Depth (mm), 0 = no measurement.
    lag_px : int
        Distance of the two pixels of a difference.
    row_step : int
        The differences whose first pixel lies on every ``row_step``-th row only (a sample
        of the image, ``row_step`` times faster; 1: all).
    """
    z = np.ascontiguousarray(z, np.float32)
    if z.ndim != 2:
        raise InputError(f"estimate_noise_mm expects a 2-D depth image, got shape {z.shape}")
    if int(row_step) < 1:
        raise InputError(f"row_step must be at least 1, got {row_step}")
    return float(_robust_noise_kernel(z, int(lag_px), int(row_step)))


def noise_profile(
    frames: npt.ArrayLike, edge_mm: float, *, max_frames: int = 3
) -> tuple[float, float]:
    """How the noise std grows with depth: σ(z) = σ₁·(z / 1 m)^p.

    From the second differences z₋ − 2z₀ + z₊ of three consecutive pixels (horizontally and
    vertically) on one surface (both steps within ``edge_mm``) of the first ``max_frames``
    frames (centred on every k-th row of large frames, :data:`PROFILE_MAX_PX`): a slope
    cancels, the variance is 6σ² for independent noise, and the depth of the triple (their
    mean) is uncorrelated with it, so that binning by depth does not select the noise. Per
    depth bin (:data:`PROFILE_BIN_RATIO` apart, at least :data:`PROFILE_MIN_SAMPLES` triples)
    the std of the differences within 8 robust stds (1.4826·MAD; the std where the MAD is 0:
    quantised depth) / √6; then a least-squares line of log σ against log z, weighted by the
    bins' counts. Spatial: a moving camera or object does not inflate it as it inflates
    temporal differences.

    Parameters
    ----------
    frames : array_like (T, h, w) or (h, w)
        Depth (mm), 0 or NaN = no measurement.
    edge_mm : float
        Depth step that separates two surfaces.
    max_frames : int
        How many of the first frames are used.

    Returns
    -------
    (sigma_1m_mm, power): σ₁ (mm, the std at 1 m) and p. p = 0 (σ₁ the counts-weighted mean
    std of the bins) where the depths span less than :data:`PROFILE_MIN_SPAN`, where the
    fitted power is below :data:`PROFILE_MIN_POWER` or above :data:`PROFILE_MAX_POWER`, or
    where no bin is filled (σ₁ = 0).
    """
    z = np.asarray(frames, np.float32)
    if z.ndim == 2:
        z = z[None]
    if z.ndim != 3:
        raise InputError(f"noise_profile expects (T, h, w) depth frames, got shape {z.shape}")
    z = np.nan_to_num(z[: max(int(max_frames), 1)].astype(np.float64), nan=0.0)
    # the triples centred on every k-th row, about PROFILE_MAX_PX centres in all (k = 1:
    # every row, and every vertical triple)
    k = max(1, math.ceil(z.size / PROFILE_MAX_PX))
    d2, zm = second_differences(z, float(edge_mm), row_step=k, depths=True)
    if d2.size == 0:
        return 0.0, 0.0
    which = np.floor(np.log(zm) / math.log(PROFILE_BIN_RATIO)).astype(np.int64)
    order = np.argsort(which, kind="stable")
    which, d2, zm = which[order], d2[order], zm[order]
    starts = np.flatnonzero(np.r_[True, which[1:] != which[:-1]])
    bins = []
    for lo, hi in zip(starts, np.r_[starts[1:], which.size], strict=True):
        if hi - lo < PROFILE_MIN_SAMPLES:
            continue
        x = d2[lo:hi] - np.median(d2[lo:hi])
        scale = 1.4826 * float(np.median(np.abs(x)))
        if scale <= 0:
            scale = float(x.std())
        if scale > 0:
            x = x[np.abs(x) <= 8.0 * scale]
        std = float(x.std()) / math.sqrt(6.0)
        if std > 0:
            bins.append((float(np.median(zm[lo:hi])), std, float(hi - lo)))
    if not bins:
        return 0.0, 0.0
    zb, sb, nb_ = (np.array(v) for v in zip(*bins, strict=True))
    level = float(np.average(sb, weights=nb_))
    if zb.max() / zb.min() < PROFILE_MIN_SPAN:
        return level, 0.0
    w = np.sqrt(nb_)
    design = np.stack([np.ones_like(zb), np.log(zb / 1000.0)], axis=1)
    (log_s1, power), *_ = np.linalg.lstsq(design * w[:, None], np.log(sb) * w, rcond=None)
    if not PROFILE_MIN_POWER <= power <= PROFILE_MAX_POWER:
        return level, 0.0
    return float(math.exp(log_s1)), float(power)


@nb.njit(cache=True, nogil=True, inline="always")
def _sigma_at(sigma, power, depth):  # pragma: no cover - numba
    """σ(z) of :func:`noise_at_depth` for one depth z > 0 in a compiled kernel: ``sigma``
    itself where ``power`` is 0 (no profile), else σ₁·(z / 1 m)^p."""
    return sigma if power == 0.0 else sigma * (depth / 1000.0) ** power


def noise_at_depth(depth_mm: npt.ArrayLike, sigma_1m_mm: float, power: float) -> np.ndarray:
    """σ(z) = σ₁·(z / 1 m)^p (mm) of a :func:`noise_profile`, 0 where the depth is not > 0."""
    z = np.asarray(depth_mm, np.float64)
    with np.errstate(invalid="ignore"):
        out = float(sigma_1m_mm) * np.power(np.where(z > 0, z, 1.0) / 1000.0, float(power))
    return np.where(z > 0, out, 0.0).astype(np.float32)


def temporal_noise_mm(frames: npt.ArrayLike, edge_mm: float) -> float:
    """Std (mm, per sample) of the temporal noise of static pixels.

    From the differences of consecutive frames where both have depth and the difference is
    within 4·``edge_mm`` (depth edges that moved left out) and then within 8 robust stds
    (1.4826·MAD: static pixels; the tails of the noise itself kept). Std per sample = std of
    the differences / √2.

    Parameters
    ----------
    frames : array_like (T, h, w)
        Depth (mm), 0 or NaN = no measurement.
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    float: 0 with fewer than 50 differences.
    """
    z = np.asarray(frames, np.float32)
    z = np.where(np.isnan(z), np.float32(0.0), z)
    if z.shape[0] < 2:
        return 0.0
    a, b = z[1:], z[:-1]
    d = (a - b)[(a > 0) & (b > 0)].astype(np.float64)
    d = d[np.abs(d) <= 4.0 * edge_mm]
    if d.size < 50:
        return 0.0
    d = d - np.median(d)
    scale = 1.4826 * np.median(np.abs(d))
    if scale <= 0:
        scale = float(d.std())
    d = d[np.abs(d) <= 8.0 * scale] if scale > 0 else d
    return math.sqrt(float(d.var()) / 2.0)


def second_differences(
    frames: npt.ArrayLike,
    edge_mm: float,
    noise_mm: float = 0.0,
    *,
    row_step: int = 1,
    depths: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """The second differences z_l − 2·z_c + z_r of three consecutive valid pixels along the
    rows and columns of ``frames``, over the triples whose outer pixels lie within
    max(``edge_mm``, 8·``noise_mm``) of their centre (one surface; with a noise, the tails of
    strong noise kept): slopes cancel, motion does not enter. For i.i.d. noise of std σ their
    std is σ·√6.

    Parameters
    ----------
    frames : array_like (..., h, w)
        Depth (mm), 0 or NaN = no measurement.
    edge_mm : float
        Depth step that separates two surfaces.
    noise_mm : float
        Noise std (mm).
    row_step : int
        Only the triples centred on every ``row_step``-th row (along the rows from row 0,
        along the columns from row 1): a sample of large frames.
    depths : bool
        Also return each triple's mean depth.

    Returns
    -------
    ndarray float64 (n,), and with ``depths`` the (n,) mean depths: all frames' triples along
    the rows, then all frames' triples along the columns, each frame's one frame at a time.
    """
    z = np.asarray(frames)
    z = z.reshape(-1, *z.shape[-2:])
    limit = max(float(edge_mm), 8.0 * float(noise_mm))
    rows = np.arange(1, z.shape[1] - 1, row_step)
    along_rows: list[np.ndarray] = [np.empty(0)]
    along_cols: list[np.ndarray] = [np.empty(0)]
    means_rows: list[np.ndarray] = [np.empty(0)]
    means_cols: list[np.ndarray] = [np.empty(0)]
    for frame in z:  # (one frame's temporaries at a time)
        f = np.asarray(frame, np.float64)
        f = np.where(np.isfinite(f), f, 0.0)
        h = f[::row_step]
        for (a, b, c), diffs, means in (
            ((h[:, :-2], h[:, 1:-1], h[:, 2:]), along_rows, means_rows),
            ((f[rows - 1], f[rows], f[rows + 1]), along_cols, means_cols),
        ):
            ok = (a > 0) & (b > 0) & (c > 0) & (np.abs(a - b) <= limit) & (np.abs(c - b) <= limit)
            diffs.append((a - 2.0 * b + c)[ok])
            if depths:
                means.append(((a + b + c) / 3.0)[ok])
    d2 = np.concatenate(along_rows + along_cols)
    return (d2, np.concatenate(means_rows + means_cols)) if depths else d2


def spatial_noise_mm(differences: np.ndarray, noise_mm: float) -> float:
    """A sample's noise std (mm) from space: the std of the :func:`second_differences`
    ``differences`` over √6 (unbiased for any law of the noise), at least ``noise_mm`` (the
    robust estimate of :func:`estimate_noise_mm`, which reads 0.84–0.9σ under Laplacian
    noise).

    Unlike the temporal differences (:func:`temporal_noise_mm`), which a moving camera's
    slanted surfaces inflate to three times the noise, second differences cancel slopes and
    motion. Returns ``noise_mm`` without noise (``noise_mm`` ≤ 0) or with fewer than 50
    differences.
    """
    d = np.asarray(differences, np.float64)
    if not noise_mm > 0 or d.size < 50:
        return float(noise_mm)
    return max(float(noise_mm), float(np.std(d)) / math.sqrt(6.0))


def tail_ratio(differences: np.ndarray) -> float:
    """How heavy the tails of the spatial noise are: the ratio of the 0.9 and 0.6 quantiles
    (:data:`TAIL_QUANTILES`) of the absolute :func:`second_differences`.

    Second differences cancel slopes and camera motion, which the temporal differences read
    as heavy tails; quantiles, unlike the kurtosis, ignore the few depth edges left in.
    I.i.d. Gaussian noise gives 1.955, Laplacian 2.205 (:data:`TAIL_RATIO_MEDIAN` between).

    Returns
    -------
    float: NaN without noise (the 0.6 quantile 0) or with fewer than 50 differences.
    """
    d = np.abs(np.asarray(differences, np.float64))
    if d.size < 50:
        return math.nan
    high, low = np.quantile(d, TAIL_QUANTILES)
    return float(high / low) if low > 0 else math.nan


def quantisation_step(
    frames: npt.ArrayLike,
    sigma_mm: float,
    profile: tuple[float, float] | None = None,
) -> float:
    """How coarsely the depth is quantised against its noise: the step from each valid
    sample's depth to the next larger depth found in ``frames``, in noise stds at that depth,
    its median over the samples.

    Structured-light and stereo cameras quantise disparity (a Kinect: 1/8 px), so their depths
    take few distinct values, one level step apart (≈ 1.5 σ for a Kinect, at every depth);
    continuous noise gives nearly as many distinct values as samples (≈ 0), whole-mm integers
    with σ ≥ 10 mm at most 0.1.

    Parameters
    ----------
    frames : array_like (..., h, w)
        Depth (mm), 0 or NaN = no measurement.
    sigma_mm : float
        Noise std (mm), where ``profile`` is None.
    profile : (float, float), optional
        (σ₁, p) of :func:`noise_profile`: the noise std σ₁·(z / 1 m)^p at each depth z.

    Returns
    -------
    float: the median step in stds (each std at least 0.5 mm); NaN with fewer than two
    distinct depths.
    """
    z = np.asarray(frames, np.float64).ravel()
    z = z[np.isfinite(z) & (z > 0)]
    levels, counts = np.unique(z, return_counts=True)
    if levels.size < 2:
        return math.nan
    step = np.diff(levels)
    below = levels[:-1]
    sigma = noise_at_depth(below, *profile) if profile is not None else float(sigma_mm)
    ratio = step / np.maximum(sigma, 0.5)
    return weighted_median(ratio, counts[:-1])  # each sample weighs once (the top level: none)


def choose_estimator(tail: float, *, quantised: bool = False) -> str:
    """``"median"`` for heavy-tailed noise (:func:`tail_ratio` above
    :data:`TAIL_RATIO_MEDIAN`, or unknown), else ``"mean"`` of the trusted samples; ``"mean"``
    for quantised depth (:data:`QUANTISED_STEPS`) whatever its tails."""
    if quantised:
        return "mean"
    if not math.isfinite(tail) or tail > TAIL_RATIO_MEDIAN:
        return "median"
    return "mean"
