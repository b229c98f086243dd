"""Robust estimate of the noise std of a depth image (1.4826·MAD/√2 of neighbour differences).

Used by UP-SR for the per-video noise level (edge threshold and spurious-motion margin, fixed
from the first window by :class:`upsr.method.windowed.UPSR`) and for the first step of the
deblurring (:func:`upsr.method.deblurring.deblur`).
"""

from __future__ import annotations

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError

__all__ = ["estimate_noise_mm"]


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
def _robust_noise_kernel(z, lag):  # pragma: no cover - numba
    """1.4826·MAD/√2 of the valid same-surface differences ``lag`` px apart (see
    :func:`estimate_noise_mm`): one pass into one buffer, then two O(n) medians."""
    h, w = z.shape
    buf = np.empty(max(h * (w - lag), 0) + max((h - lag) * w, 0), np.float32)
    n = 0
    for di, dj in ((0, lag), (lag, 0)):
        for i in range(h - di):
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


def estimate_noise_mm(z: npt.ArrayLike, lag_px: int = 1) -> float:
    """Robust std (mm) of the noise in a depth image.

    1.4826·MAD/√2 of the differences between pixels ``lag_px`` apart (horizontally and
    vertically), over pairs of valid pixels on one surface (|Δ| < 100 mm). Use the SR factor as
    the lag for a fused image, whose noise comes in r×r blocks. Compiled: one pass, no
    temporaries, two O(n) medians; the same value as the NumPy version
    (:func:`upsr.research.oracle.estimate_noise_mm_numpy`).
    """
    z = np.ascontiguousarray(z, np.float32)
    if z.ndim != 2:
        raise InputError(f"estimate_noise_mm expects a 2-D depth image, got shape {z.shape}")
    return float(_robust_noise_kernel(z, int(lag_px)))
