"""Sorting networks and medians of sorted samples, the building blocks of the fusion's
per-pixel estimates (:mod:`upsr.method.fusion`), and the median of a few values by rank (the
anchor, the radial offsets, the slopes' symmetric neighbourhoods); the weighted median of a
video's statistics."""

from __future__ import annotations

import functools

import numba as nb
import numpy as np

from upsr._numba import SAFE_FASTMATH

__all__ = ["median_beyond", "sorting_network", "weighted_median"]


@nb.njit(cache=True, nogil=True, inline="always")
def _median_sorted(vals, lo, hi):  # pragma: no cover - numba
    """Median of the sorted vals[lo:hi] (mean of the two middle values for an even count)."""
    m = lo + (hi - lo) // 2
    if (hi - lo) % 2 == 1:
        return vals[m]
    return 0.5 * (vals[m - 1] + vals[m])


@nb.njit(cache=True, nogil=True, inline="always")
def _small_median(buf, m):  # pragma: no cover - numba
    """Median of buf[:m] (m ≥ 1, at most about 25; buf is left as it is): the value whose
    rank is the middle one, by counting the values below and up to each (O(m²) compares
    without data-dependent branches in the inner loop: 1.4–1.9× faster than an insertion
    sort for m = 5 … 25, and the same value, ties included)."""
    k = m // 2
    lower = np.float32(0.0)
    upper = np.float32(0.0)
    for p in range(m):
        x = buf[p]
        below = 0
        up_to = 0
        for q in range(m):
            below += buf[q] < x
            up_to += buf[q] <= x
        if below <= k < up_to:
            upper = x
        if below <= k - 1 < up_to:
            lower = x
    return upper if m % 2 == 1 else 0.5 * (lower + upper)


def sorting_network(n: int) -> np.ndarray:
    """Comparators (i, j), i < j, of Batcher's odd–even merge sort for n keys, as an (m, 2) array.

    Built for the next power of two and pruned of every comparator that touches a padding
    position ≥ n (padding keys are +∞, already in place, so those never swap). For the usual
    window lengths: 9 keys in 28 compare-exchanges, branch-free, instead of an insertion sort.
    """
    size = 1
    while size < n:
        size *= 2
    pairs: list[tuple[int, int]] = []

    def merge(lo: int, length: int, step: int) -> None:
        double = step * 2
        if double < length:
            merge(lo, length, double)
            merge(lo + step, length, double)
            pairs.extend((i, i + step) for i in range(lo + step, lo + length - step, double))
        else:
            pairs.append((lo, lo + step))

    def sort(lo: int, length: int) -> None:
        if length > 1:
            half = length // 2
            sort(lo, half)
            sort(lo + half, half)
            merge(lo, length, 1)

    sort(0, size)
    kept = [(i, j) for i, j in pairs if j < n]
    return np.array(kept, np.int64).reshape(-1, 2)


@nb.njit(cache=True, nogil=True, inline="always")
def _centre_sorted(vals, lo, hi, use_mean):  # pragma: no cover - numba
    """The estimate of the sorted vals[lo:hi]: their median, or their mean (``use_mean``)."""
    if use_mean:
        acc = 0.0
        for p in range(lo, hi):
            acc += vals[p]
        return np.float32(acc / (hi - lo))
    return _median_sorted(vals, lo, hi)


@nb.njit(cache=True, nogil=True, fastmath=SAFE_FASTMATH)
def _sort_columns(a, network):  # pragma: no cover - numba
    """Sort every column of a (n, m) at once: a branch-free min/max sorting network whose
    compare-exchanges are loops over the row (SIMD; a function of its own so that LLVM
    vectorises them)."""
    m = a.shape[1]
    for c in range(network.shape[0]):
        ap = a[network[c, 0]]
        aq = a[network[c, 1]]
        for j in range(m):
            lo = min(ap[j], aq[j])
            aq[j] = max(ap[j], aq[j])
            ap[j] = lo


@functools.lru_cache(maxsize=16)
def _network(n: int) -> np.ndarray:
    return sorting_network(n)


@nb.njit(cache=True, nogil=True, inline="always")
def _heaviest_run(vals, wts, m, edge_mm, g, bonus, ref_value):  # pragma: no cover - numba
    """The surface with the largest vote among the sorted vals[:m]: (lo, hi, weight) of the
    run vals[lo:hi] of consecutive values at most ``edge_mm`` apart whose weights ``wts``
    (plus ``bonus`` where the run holds the guide ``g`` ± ``edge_mm``, g > 0) add up most;
    of equal ones the first, or the one holding ``ref_value``."""
    best_lo = 0
    best_hi = 0
    best_w = -np.inf
    lo = 0
    acc = wts[0]
    for p in range(1, m + 1):
        if p == m or vals[p] - vals[p - 1] > edge_mm:
            has_ref = vals[lo] <= ref_value <= vals[p - 1]
            if g > 0 and vals[lo] - edge_mm <= g <= vals[p - 1] + edge_mm:
                acc += bonus
            if acc > best_w or (acc == best_w and has_ref):
                best_w = acc
                best_lo = lo
                best_hi = p
            lo = p
            acc = 0.0
        if p < m:
            acc += wts[p]
    return best_lo, best_hi, best_w


@nb.njit(cache=True, nogil=True, inline="always")
def _twice_beyond(values, m, limit):  # pragma: no cover - numba
    """(2·#{values[:m] > limit}, 2·#{values[:m] < −limit}): the median of values[:m] can
    exceed +limit (−limit) only where the first (second) is at least m, and does where it is
    more than m."""
    above = 0
    below = 0
    for q in range(m):
        above += values[q] > limit
        below += values[q] < -limit
    return 2 * above, 2 * below


def median_beyond(values: np.ndarray, limit: float) -> bool:
    """Whether |median(values)| > ``limit``, decided by counting the values beyond ±limit
    (more than half beyond one of them, or fewer than half beyond both); the median is
    computed only where exactly half lie beyond one (an even count). Exact, and O(n) without
    a selection.

    Parameters
    ----------
    values : ndarray (n,), n ≥ 1
    limit : float (≥ 0)

    Returns
    -------
    bool

    Examples
    --------
    >>> median_beyond(np.array([-1.0, 1.0, 3.0, 5.0]), 2.0)  # the median is 2.0
    False
    """
    n = values.size
    above, below = _twice_beyond(values, n, limit)
    if above < n and below < n:
        return False
    if above > n or below > n:
        return True
    return abs(float(np.median(values))) > limit


def weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    """The lower weighted median of ``values`` (1-D, at least one): the smallest value at which
    the cumulative weight of the values up to it reaches half the total (the depth levels'
    steps, each weighing its samples: :func:`upsr.method.noise.quantisation_step`,
    :func:`upsr.method.companding.level_spacing`)."""
    order = np.argsort(values)
    cum = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cum, 0.5 * cum[-1])])
