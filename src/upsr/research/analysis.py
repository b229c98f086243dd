r"""Statistical performance of UP-SR (paper §6): the MSE model of the median fusion.

The fused image z = med_t(registered frames) (eq. 28) has, per the paper (eq. 31),

    MSE(z, x) = var(z) + ‖bias(z)‖²,   var(z) = n · var(z(i)),   ‖bias(z)‖² = n (r² − 1) ρ²

with n the number of high-res pixels, r the SR factor and ρ the mean error of an upsampled
pixel (eq. 34, data dependent; r = 1 is unbiased). var(z(i)) is the variance of the sample
median of N i.i.d. Laplace samples of standard deviation σ (scale b = σ/√2, density
(1/2b) e^{−|x|/b}). For even N the median is the mean of the two middle order statistics, as in
:func:`upsr.method.fusion.temporal_median` and :func:`numpy.median`. The Cramér–Rao bound of an
unbiased location estimate from N Laplace samples is b²/N = σ²/(2N) (Fisher information
1/b² per sample).

Exact variance of the median (derived here; eq. 35–37 as printed are wrong, see below)
---------------------------------------------------------------------------------------
Write X = S·E with a fair sign S and E ~ Exponential(scale b) independent (the Laplace law).
Let K ~ Binomial(N, 1/2) be the number of positive samples; given K = k, the positive samples
are k i.i.d. exponentials and the negative ones N − k others. Rényi's representation gives the
i-th smallest of k exponentials as E_(i:k) = b Σ_{l=1..i} Z_l / (k − l + 1) (Z_l i.i.d.
Exp(1)), hence, with H_j = Σ_{i≤j} 1/i and H⁽²⁾_j = Σ_{i≤j} 1/i²,

    E[E_(i:k)] = b (H_k − H_{k−i}),   var(E_(i:k)) = b² (H⁽²⁾_k − H⁽²⁾_{k−i}).

The median is symmetric about 0 (unbiased), so var(med) = E[med²].

* N = 2m + 1 odd: for k ≥ m + 1 the median is the (k − m)-th smallest positive sample,
  E_(k−m:k), whose mean is b (H_k − H_m) and variance b² (H⁽²⁾_k − H⁽²⁾_m); k ≤ m is the
  mirror image. Therefore

      var(med) / b² = 2^{1−N} Σ_{k=m+1..N} C(N, k) [ (H_k − H_m)² + H⁽²⁾_k − H⁽²⁾_m ].

* N = 2m even: for k = m the two middle samples are the smallest positive and the largest
  negative one, independent Exp(rate m/b) variables P and Q: med = (P − Q)/2,
  E[med²] = b²/(2m²). For k ≥ m + 1 both are positive: med = (A + B)/2 with
  A = E_(k−m:k) and B = A + b Z/m (Z ~ Exp(1) independent), so
  E[med²] = E[A²] + b E[A]/m + b²/(2m²). Therefore

      var(med) / b² = 2^{−N} C(N, m) / (2m²)
                      + 2^{1−N} Σ_{k=m+1..N} C(N, k) [ (H_k − H_m)² + H⁽²⁾_k − H⁽²⁾_m
                                                       + (H_k − H_m)/m + 1/(2m²) ].

All terms are positive (no cancellation) and rational: var(med)/σ² = (var(med)/b²)/2 is a
rational number (:func:`median_variance_fraction`), e.g. 1, 1/2, 23/72, 121/576 for N = 1…4.
It exceeds the Cramér–Rao factor 1/(2N) for every N and tends to it slowly: numerically
2N·var/σ² − 1 ≈ 1.596/√N (≈ 4/√(2πN)) for large N.

The same result in the form of the paper (order-statistic densities). With F, f the Laplace
cdf and density, F = 1 − e^{−x/b}/2 for x > 0. Odd N = 2m + 1: the median has density
N!/(m!)² F^m (1 − F)^m f; expanding (1 − e^{−x}/2)^m binomially and using
∫₀^∞ x² e^{−ax} dx = 2/a³ gives

    var(med) = 4σ² f_odd(N),
    f_odd(N) = 4 N!/(((N−1)/2)!)² (1/2)^{(N+1)/2}
               · Σ_{k=0..(N−1)/2} C((N−1)/2, k) (−1/2)^k / (N+1+2k)³.

Even N = 2m: var(med) = (E[X_(m+1)²] + E[X_(m) X_(m+1)])/2, from the density
N!/(m!(m−1)!) F^m (1−F)^{m−1} f of X_(m+1) and the joint density
N!/((m−1)!)² F(x)^{m−1} f(x) f(y) (1−F(y))^{m−1} (x < y); integrating by parts to bring every
term to the kernel (1 − e^{−x}/2)^{m−1} e^{−(m+1)x} gives

    var(med) = 2σ² f_even(N),
    f_even(N) = N!/((N/2)! (N/2−1)!) (1/2)^{N/2} [ (1/2)^{N/2} / N³
                + Σ_{k=0..N/2−1} C(N/2−1, k) (−1/2)^k (7N² + 8N(k+1) + 4(k+1)²) / (N² (N+2k+2)³) ].

What is wrong in the printed eq. 35–37: (i) the parity labels are swapped (the formula with
((N−1)/2)! is printed "for N even", the one with (N/2)! "for N odd"); (ii) for odd N the
printed var = 2σ² f(N) is half the true variance (it should be 4σ² f, i.e. the leading
constant 4 should be 8): as printed it tends to σ²/(4N), below the Cramér–Rao bound;
(iii) for even N the binomial coefficient is printed C((N−1)/2, k) but must be C(N/2−1, k)
(the sum's upper limit N/2 − 1 is printed correctly). See ``docs/analysis.md`` for a table.
The alternating sums lose precision for large N; :func:`median_variance_factor` evaluates the
positive Rényi sums instead.
"""

from __future__ import annotations

import csv
import functools
import io
import math
import os
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import special

from upsr._atomic import write_text_atomic
from upsr.errors import InputError
from upsr.method.validation import MAX_DEPTH_MM

__all__ = [
    "bias_sq",
    "cramer_rao_bound",
    "estimate_rho",
    "format_analysis_table",
    "median_variance",
    "median_variance_factor",
    "median_variance_fraction",
    "monte_carlo_median_variance",
    "mse",
    "run_analysis",
]

#: Largest N for which :func:`run_analysis` runs its Monte-Carlo sweep.
MAX_FRAMES_ANALYSIS = 1000
#: Largest number of Monte-Carlo trials :func:`run_analysis` accepts.
MAX_TRIALS_ANALYSIS = 10_000_000
#: The σ grid (mm) of :func:`run_analysis`'s "vs σ" sweep, and its fixed N.
SIGMA_GRID_MM = tuple(float(s) for s in range(0, 101, 5))
N_FRAMES_VS_SIGMA = 9

_MC_CHUNK = 1 << 21  # samples per Monte-Carlo batch (bounded memory)


# -------------------------------------------------------------------------------------------------
# validation
# -------------------------------------------------------------------------------------------------
def _check_int(value: Any, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value}")
    return int(value)


def _check_sigma(sigma: npt.ArrayLike, name: str = "sigma") -> np.ndarray:
    try:
        s = np.asarray(sigma, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name} must be a number or an array of numbers: {e}") from None
    if not np.all(np.isfinite(s)) or np.any(s < 0):
        raise InputError(f"{name} must be finite and >= 0 (a noise standard deviation in mm)")
    return s


def _as_result(a: np.ndarray) -> Any:
    """0-d arrays → numpy float64 scalar, others unchanged."""
    return a[()] if a.ndim == 0 else a


# -------------------------------------------------------------------------------------------------
# exact median variance
# -------------------------------------------------------------------------------------------------
def median_variance_fraction(n_frames: int) -> Fraction:
    """Exact var(median)/σ² as a rational number (Rényi closed form, see module docstring).

    Uses exact rational arithmetic: O(N²) big-integer work, meant for N up to a few hundred
    (tests, documentation). :func:`median_variance_factor` is the fast float version.

    Parameters
    ----------
    n_frames : int
        Number N >= 1 of i.i.d. Laplace samples.

    Returns
    -------
    fractions.Fraction
        var(median of N Laplace samples of std σ) / σ², e.g. 1, 1/2, 23/72 for N = 1, 2, 3.
    """
    n = _check_int(n_frames, "n_frames", 1)
    m = n // 2
    h, h2 = [Fraction(0)], [Fraction(0)]
    for j in range(1, n + 1):
        h.append(h[-1] + Fraction(1, j))
        h2.append(h2[-1] + Fraction(1, j * j))
    total = Fraction(0)
    for k in range(m + 1, n + 1):
        mu = h[k] - h[m]
        term = mu * mu + h2[k] - h2[m]
        if n % 2 == 0:
            term += mu / m + Fraction(1, 2 * m * m)
        total += 2 * math.comb(n, k) * term
    if n % 2 == 0:
        total += Fraction(math.comb(n, m), 2 * m * m)
    return total / 2**n / 2  # / 2**N: binomial weights; / 2: b² = σ²/2


@functools.lru_cache(maxsize=256)
def _factor(n: int) -> float:
    m = n // 2
    k = np.arange(m + 1, n + 1)
    inv = 1.0 / np.arange(1, n + 1, dtype=np.float64)
    h = np.concatenate([[0.0], np.cumsum(inv)])
    h2 = np.concatenate([[0.0], np.cumsum(inv * inv)])
    if n <= 1024:  # exact integers, correctly rounded
        w = np.array([math.comb(n, int(i)) / 2**n for i in k])
        w_mid = math.comb(n, m) / 2**n
    else:
        logc = special.gammaln(n + 1) - n * math.log(2.0)
        w = np.exp(logc - special.gammaln(k + 1) - special.gammaln(n - k + 1))
        w_mid = math.exp(logc - 2 * special.gammaln(m + 1)) if n % 2 == 0 else 0.0
    mu = h[k] - h[m]
    term = mu * mu + (h2[k] - h2[m])
    if n % 2 == 1:
        return float(np.sum(w * term))  # 2^{1−N} Σ … / 2
    term = term + mu / m + 1.0 / (2.0 * m * m)
    return float(w_mid / (4.0 * m * m) + np.sum(w * term))


def median_variance_factor(n_frames: int) -> float:
    """var(median of N i.i.d. Laplace samples of std σ) / σ² (exact, float).

    Closed form (module docstring): with m = ⌊N/2⌋, H_j, H⁽²⁾_j the harmonic numbers of order
    1 and 2 and K ~ Binomial(N, 1/2) the number of positive samples,
    odd N: 2^{−N} Σ_{k>m} C(N,k) [(H_k − H_m)² + H⁽²⁾_k − H⁽²⁾_m]; even N: the same with the
    extra terms (H_k − H_m)/m + 1/(2m²) in the bracket, plus C(N,m) 2^{−N}/(4m²). It is the
    corrected paper eq. (35)–(37) divided by σ². Cost O(N); it tends to the Cramér–Rao factor
    1/(2N) as N → ∞.

    Parameters
    ----------
    n_frames : int
        N >= 1.

    Returns
    -------
    float
        1 for N = 1, 1/2 for N = 2, 23/72 for N = 3, …
    """
    return _factor(_check_int(n_frames, "n_frames", 1))


def median_variance(n_frames: int, sigma: npt.ArrayLike) -> Any:
    """Exact variance of the per-pixel median fusion, var(z(i)) of paper eq. (35).

    The variance of the sample median of ``n_frames`` i.i.d. Laplace samples of standard
    deviation ``sigma`` (scale σ/√2); for even N the median is the mean of the two middle
    order statistics. Equals ``median_variance_factor(n_frames) * sigma**2``; the derivation,
    and what is wrong in the printed eq. (35)–(37), is in the module docstring.

    Parameters
    ----------
    n_frames : int
        Number N >= 1 of fused frames.
    sigma : float or array_like
        Noise standard deviation(s) (mm), finite and >= 0.

    Returns
    -------
    numpy.float64 or ndarray
        Variance in sigma's unit squared (mm²), same shape as ``sigma``.

    Raises
    ------
    InputError
        ``n_frames`` not an integer >= 1, or ``sigma`` negative or not finite.
    """
    c = median_variance_factor(n_frames)
    s = _check_sigma(sigma)
    return _as_result(c * s * s)


def cramer_rao_bound(n_frames: int, sigma: npt.ArrayLike) -> Any:
    """Cramér–Rao bound σ²/(2N) of an unbiased depth estimate from N Laplace samples (§6.2).

    The Fisher information of one Laplace sample of scale b = σ/√2 about its location is 1/b²,
    so the bound is b²/N = σ²/(2N). The median reaches it only asymptotically:
    :func:`median_variance` > bound for every finite N (at N = 1: σ² vs σ²/2).

    Parameters
    ----------
    n_frames : int
        N >= 1.
    sigma : float or array_like
        Noise standard deviation(s), finite and >= 0.

    Returns
    -------
    numpy.float64 or ndarray
        The bound, same shape as ``sigma``.
    """
    n = _check_int(n_frames, "n_frames", 1)
    s = _check_sigma(sigma)
    return _as_result(s * s / (2.0 * n))


def bias_sq(n_pixels: int, r: int, rho: npt.ArrayLike) -> Any:
    """Squared bias norm n·(r² − 1)·ρ² of the fused image (paper eq. 34).

    Each r×r patch has r² − 1 pixels made by the upsampling, each with mean error ρ; r = 1
    (pure denoising) is unbiased.

    Parameters
    ----------
    n_pixels : int
        Number n >= 1 of high-res pixels.
    r : int
        SR factor >= 1.
    rho : float or array_like
        Mean error per upsampled pixel (mm), finite.

    Returns
    -------
    numpy.float64 or ndarray
        ‖bias‖² (mm²), same shape as ``rho``.
    """
    n = _check_int(n_pixels, "n_pixels", 1)
    r = _check_int(r, "r", 1)
    try:
        p = np.asarray(rho, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InputError(f"rho must be a number or an array of numbers: {e}") from None
    if not np.all(np.isfinite(p)):
        raise InputError("rho must be finite")
    return _as_result(n * (r * r - 1) * p * p)


def mse(n_frames: int, sigma: npt.ArrayLike, r: int, rho: npt.ArrayLike, n_pixels: int = 1) -> Any:
    """Model MSE of the median fusion, n·var(z(i)) + n(r² − 1)ρ² (paper eq. 31, 34, 35).

    Parameters
    ----------
    n_frames : int
        Number N >= 1 of fused frames.
    sigma : float or array_like
        Noise standard deviation (mm), >= 0.
    r : int
        SR factor >= 1.
    rho : float or array_like
        Mean error per upsampled pixel (mm); broadcast against ``sigma``.
    n_pixels : int, default 1
        Number of high-res pixels n (1: the per-pixel MSE).

    Returns
    -------
    numpy.float64 or ndarray
        The total MSE (mm²) over ``n_pixels`` pixels.
    """
    n = _check_int(n_pixels, "n_pixels", 1)
    return _as_result(np.asarray(n * median_variance(n_frames, sigma) + bias_sq(n, r, rho)))


def estimate_rho(
    fused: npt.ArrayLike,
    truth: npt.ArrayLike,
    r: int,
    n_frames: int,
    sigma: float,
    valid: npt.ArrayLike | None = None,
) -> float:
    """Fit the mean upsampling error ρ of eq. (34) from a fused image and its ground truth.

    With n the number of pixels valid in both images (finite and non-zero, and in ``valid``)
    and MSE_total = Σ (fused − truth)² over them,
    ρ² = max(0, (MSE_total − n·var(z(i))) / (n (r² − 1))), var(z(i)) from
    :func:`median_variance`. For r = 1 the model has no bias term and ρ = 0.

    Parameters
    ----------
    fused, truth : array_like
        Same-shape depth maps (mm); 0 or NaN = no value.
    r : int
        SR factor >= 1.
    n_frames : int
        Number of fused frames N >= 1.
    sigma : float
        Noise standard deviation (mm) >= 0.
    valid : array_like of bool, optional
        Extra mask of the pixels to use (e.g. far from depth edges).

    Returns
    -------
    float
        ρ >= 0 (mm).

    Raises
    ------
    InputError
        Shapes differ, non-numeric data, or no pixel valid in both.
    """
    r = _check_int(r, "r", 1)
    var = float(median_variance(n_frames, float(_check_sigma(sigma))))
    try:
        z = np.asarray(fused, dtype=np.float64)
        x = np.asarray(truth, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InputError(f"fused and truth must be numeric arrays: {e}") from None
    if z.shape != x.shape:
        raise InputError(f"fused and truth differ in shape: {z.shape} vs {x.shape}")
    mask = np.isfinite(z) & np.isfinite(x) & (z != 0) & (x != 0)
    if valid is not None:
        v = np.asarray(valid)
        if v.shape != z.shape:
            raise InputError(f"valid has shape {v.shape}, expected {z.shape}")
        mask &= v.astype(bool)
    n = int(mask.sum())
    if n == 0:
        raise InputError("no pixel is valid in both the fused image and the truth")
    if r == 1:
        return 0.0
    mse_total = float(np.sum((z[mask] - x[mask]) ** 2))
    return math.sqrt(max(0.0, (mse_total - n * var) / (n * (r * r - 1))))


# -------------------------------------------------------------------------------------------------
# Monte-Carlo
# -------------------------------------------------------------------------------------------------
def monte_carlo_median_variance(
    n_frames: int,
    sigma: npt.ArrayLike,
    n_trials: int,
    rng: np.random.Generator | int | None = None,
) -> Any:
    """Monte-Carlo estimate of :func:`median_variance`.

    Draws ``n_trials`` sets of N i.i.d. Laplace samples of std σ (scale σ/√2) around 0, takes
    each set's median (:func:`numpy.median`: mean of the two middle values for even N) and
    returns the mean squared median, the unbiased estimate of the variance about the known
    true value 0. Independent draws for each σ; batches bound the memory.

    Parameters
    ----------
    n_frames : int
        N >= 1.
    sigma : float or array_like
        Noise standard deviation(s), finite and >= 0.
    n_trials : int
        Number of medians per σ (>= 1). The relative standard error is about
        √(var(med²))/(var·√n_trials), 2.2/√n_trials at N = 1, less for larger N.
    rng : numpy.random.Generator or int or None
        Random generator or seed.

    Returns
    -------
    numpy.float64 or ndarray
        Estimated variance(s), same shape as ``sigma``.
    """
    n = _check_int(n_frames, "n_frames", 1)
    trials = _check_int(n_trials, "n_trials", 1)
    s = _check_sigma(sigma)
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    out = np.empty(s.size, dtype=np.float64)
    rows = max(1, _MC_CHUNK // n)
    for i, sig in enumerate(s.ravel()):
        acc = 0.0
        done = 0
        while done < trials:
            t = min(rows, trials - done)
            med = np.median(gen.laplace(0.0, 1.0, size=(t, n)), axis=1)
            acc += float(np.dot(med, med))
            done += t
        out[i] = acc / trials * (sig * sig / 2.0)  # unit scale b = 1 → b² = σ²/2
    return _as_result(out.reshape(s.shape))


# -------------------------------------------------------------------------------------------------
# the printed eq. (35)–(37) and the corrected alternating sums (documentation, tests)
# -------------------------------------------------------------------------------------------------
def _f36_printed(n: int) -> float:
    """Eq. (36) exactly as printed (labelled "for N even"), Γ-extended to any N >= 1."""
    a = (n - 1) / 2
    pre = 4.0 * math.factorial(n) / special.gamma((n + 1) / 2) ** 2 * 0.5 ** ((n + 1) / 2)
    s = sum(special.binom(a, k) * (-0.5) ** k / (n + 1 + 2 * k) ** 3 for k in range(int(a) + 1))
    return float(pre * s)


def _f37_printed(n: int) -> float:
    """Eq. (37) exactly as printed (labelled "for N odd", binomial C((N−1)/2, k)), Γ-extended."""
    a = (n - 1) / 2
    pre = math.factorial(n) / (special.gamma(n / 2 + 1) * special.gamma(n / 2)) * 0.5 ** (n / 2)
    s = sum(
        special.binom(a, k)
        * (-0.5) ** k
        * (7 * n * n + 8 * n * (k + 1) + 4 * (k + 1) ** 2)
        / (n * n * (n + 2 * k + 2) ** 3)
        for k in range(math.floor(n / 2 - 1) + 1)
    )
    return float(pre * (0.5 ** (n / 2) / n**3 + s))


def _printed_variance_factor(n_frames: int, *, swap_parity: bool = False) -> float:
    """var(z(i))/σ² = 2 f(N) from the printed eq. (35)–(37), read as literally as possible.

    ``swap_parity=False``: eq. (36) for even N and eq. (37) for odd N as labelled (the
    half-integer factorials and binomials are evaluated with the Γ function, the sum limits
    rounded down). ``swap_parity=True``: the evident intent, eq. (36) for odd N and eq. (37)
    for even N, otherwise as printed.
    """
    n = _check_int(n_frames, "n_frames", 1)
    use36 = (n % 2 == 0) != swap_parity
    return 2.0 * (_f36_printed(n) if use36 else _f37_printed(n))


def _order_statistic_fraction(n_frames: int) -> Fraction:
    """var(median)/σ² from the corrected eq. (36)/(37) (alternating sums), in exact rationals.

    Odd N: 4 f_odd(N) (eq. 36 with the leading 4 → 8 when written as 2σ² f); even N:
    2 f_even(N) (eq. 37 with the binomial C(N/2 − 1, k)). See the module docstring.
    """
    n = _check_int(n_frames, "n_frames", 1)
    half = Fraction(1, 2)
    if n % 2 == 1:
        m = (n - 1) // 2
        s = sum(
            (math.comb(m, k) * (-half) ** k / Fraction(n + 1 + 2 * k) ** 3 for k in range(m + 1)),
            Fraction(0),
        )
        f = 4 * Fraction(math.factorial(n), math.factorial(m) ** 2) * half ** (m + 1) * s
        return 4 * f
    m = n // 2
    s = sum(
        (
            math.comb(m - 1, k)
            * (-half) ** k
            * Fraction(7 * n * n + 8 * n * (k + 1) + 4 * (k + 1) ** 2, n * n * (n + 2 * k + 2) ** 3)
            for k in range(m)
        ),
        Fraction(0),
    )
    pre = Fraction(math.factorial(n), math.factorial(m) * math.factorial(m - 1)) * half**m
    return 2 * pre * (half**m / Fraction(n) ** 3 + s)


# -------------------------------------------------------------------------------------------------
# the `upsr analyze` experiment
# -------------------------------------------------------------------------------------------------
def _csv(header: Sequence[str], rows: Sequence[Sequence[float]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in rows:
        w.writerow([v if isinstance(v, int) else f"{v:.10g}" for v in row])
    return buf.getvalue()


def _rel(a: float, b: float) -> float:
    return a / b - 1.0 if b > 0 else math.nan


def run_analysis(
    out: str | os.PathLike[str] = "results/analysis",
    *,
    sigma: float = 30.0,
    max_frames: int = 25,
    trials: int = 20_000,
    seed: int = 0,
) -> dict[str, Any]:
    """Theory vs Monte-Carlo for the median fusion: variance vs N and vs σ; CSV and PNG files.

    Sweep 1: N = 1 … ``max_frames`` at σ = ``sigma``: exact variance (:func:`median_variance`),
    Cramér–Rao bound, Monte-Carlo estimate and the printed eq. (35)–(37) (parity swapped to
    its evident intent). Sweep 2: σ = 0, 5, …, 100 mm at N = 9. Files in ``out``:
    ``analysis_vs_n.csv``, ``analysis_vs_sigma.csv``, ``analysis_vs_n.png``,
    ``analysis_vs_sigma.png`` (each figure with an ``.svg`` twin), each written atomically after
    all computations are done.

    Parameters
    ----------
    out : path-like
        Output folder (created if needed).
    sigma : float
        Noise std (mm) of sweep 1, finite and > 0.
    max_frames : int
        Largest N of sweep 1, 1 … 1000.
    trials : int
        Monte-Carlo medians per point, 1 … 10⁷.
    seed : int
        Seed (>= 0) of the Monte-Carlo draws.

    Returns
    -------
    dict
        ``vs_n`` and ``vs_sigma`` (lists of row dicts), ``files`` (name → path) and the
        parameters.
    """
    s, n_max, n_trials, seed, out_dir = _check_analysis(sigma, max_frames, trials, seed, out)
    rng_n, rng_s = (np.random.default_rng(c) for c in np.random.SeedSequence(seed).spawn(2))
    vs_n = _sweep_frames(s, n_max, n_trials, rng_n)
    vs_sigma = _sweep_sigma(n_trials, rng_s)
    from upsr.research._analysis_figures import analysis_plots
    from upsr.viz.figures import write_figure

    plot_n, plot_s = analysis_plots(vs_n, vs_sigma, s, n_trials, N_FRAMES_VS_SIGMA)

    out_dir.mkdir(parents=True, exist_ok=True)
    files = {
        "vs_n_csv": out_dir / "analysis_vs_n.csv",
        "vs_sigma_csv": out_dir / "analysis_vs_sigma.csv",
        "vs_n_png": out_dir / "analysis_vs_n.png",
        "vs_sigma_png": out_dir / "analysis_vs_sigma.png",
        "vs_n_svg": out_dir / "analysis_vs_n.svg",
        "vs_sigma_svg": out_dir / "analysis_vs_sigma.svg",
    }
    write_text_atomic(files["vs_n_csv"], _csv(list(vs_n[0]), [list(row.values()) for row in vs_n]))
    write_text_atomic(
        files["vs_sigma_csv"], _csv(list(vs_sigma[0]), [list(row.values()) for row in vs_sigma])
    )
    write_figure(files["vs_n_png"], plot_n)
    write_figure(files["vs_sigma_png"], plot_s)
    return {
        "sigma_mm": s,
        "max_frames": n_max,
        "trials": n_trials,
        "seed": seed,
        "vs_n": vs_n,
        "vs_sigma": vs_sigma,
        "files": {k: str(v) for k, v in files.items()},
    }


def _check_analysis(
    sigma: Any, max_frames: Any, trials: Any, seed: Any, out: str | os.PathLike[str]
) -> tuple[float, int, int, int, Path]:
    """The checked parameters of :func:`run_analysis` (InputError on a bad one)."""
    try:
        s = float(sigma)
    except (TypeError, ValueError):
        raise InputError(f"sigma must be a number of mm > 0, got {sigma!r}") from None
    if not (0 < s <= MAX_DEPTH_MM):  # (NaN too; 1e200 overflowed into an empty plot)
        raise InputError(f"sigma must be a number of mm in (0, {MAX_DEPTH_MM:g}], got {sigma!r}")
    n_max = _check_int(max_frames, "max_frames", 1)
    if n_max > MAX_FRAMES_ANALYSIS:
        raise InputError(f"max_frames must be <= {MAX_FRAMES_ANALYSIS}, got {n_max}")
    n_trials = _check_int(trials, "trials", 1)
    if n_trials > MAX_TRIALS_ANALYSIS:
        raise InputError(f"trials must be <= {MAX_TRIALS_ANALYSIS}, got {n_trials}")
    seed = _check_int(seed, "seed", 0)
    out_dir = Path(out)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{out_dir} exists and is not a folder")
    return s, n_max, n_trials, seed, out_dir


def _sweep_frames(
    s: float, n_max: int, n_trials: int, rng: np.random.Generator
) -> list[dict[str, Any]]:
    """Sweep 1 of :func:`run_analysis`: N = 1 … ``n_max`` at σ = ``s`` mm."""
    vs_n: list[dict[str, Any]] = []
    for n in range(1, n_max + 1):
        var = float(median_variance(n, s))
        mc = float(monte_carlo_median_variance(n, s, n_trials, rng))
        vs_n.append(
            {
                "n_frames": n,
                "sigma_mm": s,
                "variance_mm2": var,
                "crb_mm2": float(cramer_rao_bound(n, s)),
                "mc_variance_mm2": mc,
                "mc_rel_diff": _rel(mc, var),
                "paper_printed_mm2": _printed_variance_factor(n, swap_parity=True) * s * s,
                "variance_factor": median_variance_factor(n),
            }
        )
    return vs_n


def _sweep_sigma(n_trials: int, rng: np.random.Generator) -> list[dict[str, Any]]:
    """Sweep 2 of :func:`run_analysis`: σ over ``SIGMA_GRID_MM`` at N = ``N_FRAMES_VS_SIGMA``."""
    sig = np.array(SIGMA_GRID_MM)
    n9 = N_FRAMES_VS_SIGMA
    var_s = median_variance(n9, sig)
    crb_s = cramer_rao_bound(n9, sig)
    mc_s = monte_carlo_median_variance(n9, sig, n_trials, rng)
    return [
        {
            "sigma_mm": float(sig[i]),
            "n_frames": n9,
            "variance_mm2": float(var_s[i]),
            "crb_mm2": float(crb_s[i]),
            "mc_variance_mm2": float(mc_s[i]),
            "mc_rel_diff": _rel(float(mc_s[i]), float(var_s[i])),
        }
        for i in range(sig.size)
    ]


def format_analysis_table(result: dict[str, Any]) -> str:
    """A short text table of :func:`run_analysis`'s sweep vs N (and a line for the σ sweep)."""
    lines = [
        f"median fusion variance, Laplace noise sigma = {result['sigma_mm']:g} mm, "
        f"{result['trials']} Monte-Carlo trials",
        f"{'N':>4} {'var/s^2':>9} {'var mm^2':>10} {'CRB mm^2':>10} {'MC mm^2':>10} "
        f"{'MC/var-1':>9} {'printed':>10}",
    ]
    for row in result["vs_n"]:
        lines.append(
            f"{row['n_frames']:>4d} {row['variance_factor']:>9.5f} {row['variance_mm2']:>10.3f} "
            f"{row['crb_mm2']:>10.3f} {row['mc_variance_mm2']:>10.3f} "
            f"{row['mc_rel_diff']:>+9.2%} {row['paper_printed_mm2']:>10.3f}"
        )
    diffs = [abs(r["mc_rel_diff"]) for r in result["vs_sigma"] if math.isfinite(r["mc_rel_diff"])]
    n9 = result["vs_sigma"][0]["n_frames"]
    lines.append(
        f"vs sigma (0..{result['vs_sigma'][-1]['sigma_mm']:g} mm, N = {n9}): "
        f"var = {median_variance_factor(n9):.5f} sigma^2, "
        f"max |MC/var - 1| = {max(diffs, default=math.nan):.2%}"
    )
    return "\n".join(lines)
