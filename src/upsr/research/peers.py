"""Simple peers of UP-SR for the realistic-sensor benchmark: per-frame filters, temporal mean.

These are what a practitioner would try first on a noisy depth video:

* :func:`bilateral_nearest` — nearest upsampling, then a per-frame bilateral filter (Tomasi &
  Manduchi 1998) that ignores invalid pixels (a normalised, masked convolution) and is told
  the true noise level: range sigma = 3·σ, so that noise is smoothed but depth edges are not;
* :func:`temporal_mean` — the plain per-pixel mean of the valid raw samples over a window of
  frames, then nearest upsampling: the maximum-likelihood fusion for Gaussian noise on a
  *static* scene with a static camera (it blurs anything that moves).

Depth in mm, 0 or NaN = no measurement; outputs are float32 with 0 where nothing is known.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method.upsampling import upsample_nearest

__all__ = ["bilateral_nearest", "masked_bilateral", "temporal_mean"]


def _as_video(depth: npt.ArrayLike) -> tuple[np.ndarray, bool]:
    arr = np.asarray(depth, dtype=np.float32)
    if arr.ndim not in (2, 3):
        raise InputError(f"depth must be (h, w) or (T, h, w), got shape {arr.shape}")
    arr = np.where(np.isfinite(arr) & (arr > 0), arr, 0.0).astype(np.float32)
    return (arr[None], True) if arr.ndim == 2 else (arr, False)


@nb.njit(cache=True, nogil=True)
def _bilateral_blocks_kernel(low, sr, table, r, k):  # pragma: no cover - numba
    """:func:`masked_bilateral` of the nearest upsampling of ``low``, computed per block.

    The upsampled frame is constant on r×r blocks, so the range weight depends only on the
    pair of blocks and the spatial weights summed over a block are a table
    ``table[a, b, oy + k, ox + k]`` (sub-pixel (a, b) of the output block, block offset).
    """
    t_total, h, w = low.shape
    out = np.zeros((t_total, h * r, w * r), low.dtype)
    num = np.empty((r, r))
    den = np.empty((r, r))
    for t in range(t_total):
        for i in range(h):
            for j in range(w):
                z = low[t, i, j]
                s = sr[t, i, j]
                if z <= 0:
                    continue
                if s <= 0:
                    out[t, i * r : i * r + r, j * r : j * r + r] = z
                    continue
                inv = 1.0 / (2.0 * s * s)
                num[:] = 0.0
                den[:] = 0.0
                for oy in range(-k, k + 1):
                    ii = i + oy
                    if ii < 0 or ii >= h:
                        continue
                    for ox in range(-k, k + 1):
                        jj = j + ox
                        if jj < 0 or jj >= w:
                            continue
                        q = low[t, ii, jj]
                        if q <= 0:
                            continue
                        d = q - z
                        wr = math.exp(-d * d * inv)
                        for a in range(r):
                            for b in range(r):
                                wt = table[a, b, oy + k, ox + k] * wr
                                num[a, b] += wt * q
                                den[a, b] += wt
                for a in range(r):
                    for b in range(r):
                        if den[a, b] > 0:
                            out[t, i * r + a, j * r + b] = num[a, b] / den[a, b]
    return out


def _block_table(r: int, sigma_space_px: float, rad: int) -> tuple[np.ndarray, int]:
    """Spatial weights of :func:`masked_bilateral` summed over each r×r block (see kernel)."""
    k = math.ceil((rad + r) / r)
    table = np.zeros((r, r, 2 * k + 1, 2 * k + 1))
    off = np.arange(-k, k + 1)
    for a in range(r):
        dy = (r * off[:, None] + np.arange(r)[None, :] - a).astype(np.float64)  # (2k+1, r)
        wy = np.where(np.abs(dy) <= rad, np.exp(-(dy**2) / (2 * sigma_space_px**2)), 0.0).sum(1)
        table[a] = wy[None, :, None] * 1.0  # filled with the x factor below
    for b in range(r):
        dx = (r * off[:, None] + np.arange(r)[None, :] - b).astype(np.float64)
        wx = np.where(np.abs(dx) <= rad, np.exp(-(dx**2) / (2 * sigma_space_px**2)), 0.0).sum(1)
        table[:, b] *= wx[None, None, :]
    return table, k


def masked_bilateral(
    depth: npt.ArrayLike,
    sigma_space_px: float,
    sigma_range_mm: float | npt.ArrayLike,
    *,
    radius_px: int | None = None,
) -> np.ndarray:
    """Bilateral filter of each frame over its valid pixels only.

    out(p) = Σ_q w(p, q)·z(q) / Σ_q w(p, q) over valid q within ``radius_px`` (Chebyshev), with
    w = exp(−|p − q|² / 2σ_s²) · exp(−(z(q) − z(p))² / 2σ_r(p)²). Invalid pixels stay invalid
    and never vote.

    Parameters
    ----------
    depth : array_like (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid.
    sigma_space_px : float
        Spatial std σ_s (px) > 0.
    sigma_range_mm : float or array_like broadcastable to ``depth``
        Range std σ_r (mm); where it is 0 the pixel is returned unchanged.
    radius_px : int, optional
        Window half size; default ⌈2σ_s⌉.

    Returns
    -------
    ndarray of float32, same shape.
    """
    video, single = _as_video(depth)
    if not (math.isfinite(sigma_space_px) and sigma_space_px > 0):
        raise InputError(f"sigma_space_px must be > 0, got {sigma_space_px!r}")
    rad = math.ceil(2 * sigma_space_px) if radius_px is None else int(radius_px)
    sr = np.broadcast_to(
        np.asarray(sigma_range_mm, np.float32), video.shape[-2:] if single else video.shape
    )
    sr = sr[None] if single else sr
    if not np.isfinite(sr).all() or (sr < 0).any():
        raise InputError("sigma_range_mm must be finite and >= 0")
    # the per-block kernel at r = 1: each "block" is one pixel, the table its spatial weights
    table, k = _block_table(1, sigma_space_px, rad)
    out = _bilateral_blocks_kernel(
        np.ascontiguousarray(video), np.ascontiguousarray(sr), table, 1, k
    )
    return out[0] if single else out


def bilateral_nearest(
    lowres: npt.ArrayLike,
    r: int,
    sigma_mm: float | npt.ArrayLike,
    *,
    range_factor: float = 3.0,
    sigma_space_px: float | None = None,
) -> np.ndarray:
    """Per-frame peer: nearest upsampling, then :func:`masked_bilateral` knowing the noise.

    Parameters
    ----------
    lowres : array_like (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid.
    r : int
        SR factor ≥ 1.
    sigma_mm : float or array_like broadcastable to ``lowres``
        True noise std σ (mm) of the input, per low-res pixel if it depends on depth.
    range_factor : float
        Range sigma = ``range_factor`` · σ (default 3).
    sigma_space_px : float, optional
        Spatial std on the high-res grid; default r (one low-res pixel).

    Returns
    -------
    ndarray of float32 (…, r·h, r·w)
        Equal to ``masked_bilateral(upsample_nearest(lowres, r), σ_s, range_factor·σ)``
        (σ upsampled likewise), computed block-wise on the low-res grid (≈ r² times faster).
    """
    video, single = _as_video(lowres)
    if isinstance(r, bool) or not isinstance(r, (int, np.integer)) or r < 1:
        raise InputError(f"r must be an integer >= 1, got {r!r}")
    r = int(r)
    ss = float(r) if sigma_space_px is None else float(sigma_space_px)
    if not (math.isfinite(ss) and ss > 0):
        raise InputError(f"sigma_space_px must be > 0, got {sigma_space_px!r}")
    sig = np.asarray(sigma_mm, np.float32)
    sr = np.broadcast_to(range_factor * sig, video.shape[-2:] if single else video.shape)
    sr = np.ascontiguousarray(sr[None] if single else sr, dtype=np.float32)
    if not np.isfinite(sr).all() or (sr < 0).any():
        raise InputError("sigma_mm must be finite and >= 0")
    table, k = _block_table(r, ss, math.ceil(2 * ss))
    out = _bilateral_blocks_kernel(np.ascontiguousarray(video), sr, table, r, k)
    return out[0] if single else out


def temporal_mean(lowres: npt.ArrayLike, r: int, n_frames: int = 9) -> np.ndarray:
    """Per-pixel mean of the valid raw samples in a centred window, nearest-upsampled.

    The window of frame t holds ``n_frames`` frames with t in the middle, shifted inwards at
    the ends of the video (as UP-SR's windows). A pixel with no valid sample stays 0.

    Parameters
    ----------
    lowres : array_like (T, h, w)
        Depth (mm); 0 or NaN = invalid.
    r : int
        SR factor ≥ 1.
    n_frames : int
        Window length N (1 ≤ N ≤ T).

    Returns
    -------
    ndarray of float32 (T, r·h, r·w)
    """
    video, single = _as_video(lowres)
    t_total = video.shape[0]
    if single or not (1 <= int(n_frames) <= t_total):
        raise InputError(f"temporal_mean needs (T, h, w) with 1 <= n_frames <= T, got {n_frames}")
    n = int(n_frames)
    csum = np.concatenate([np.zeros((1, *video.shape[1:])), np.cumsum(video, 0, dtype=np.float64)])
    ccnt = np.concatenate([np.zeros((1, *video.shape[1:])), np.cumsum(video > 0, 0)])
    out = np.empty(video.shape, np.float32)
    for t in range(t_total):
        start = min(max(t - (n - 1) // 2, 0), t_total - n)
        s = csum[start + n] - csum[start]
        c = ccnt[start + n] - ccnt[start]
        out[t] = np.where(c > 0, s / np.maximum(c, 1), 0.0)
    return upsample_nearest(out, r)
