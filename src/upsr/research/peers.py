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
    valid = video > 0
    inv2r = np.where(sr > 0, 1.0 / (2.0 * np.maximum(sr, 1e-6) ** 2), 0.0).astype(np.float32)
    pad = np.pad(video, ((0, 0), (rad, rad), (rad, rad)))
    h, w = video.shape[-2:]
    num = np.zeros(video.shape, np.float32)
    den = np.zeros(video.shape, np.float32)
    for dy in range(-rad, rad + 1):
        for dx in range(-rad, rad + 1):
            ws = math.exp(-(dy * dy + dx * dx) / (2.0 * sigma_space_px**2))
            nb = pad[:, rad + dy : rad + dy + h, rad + dx : rad + dx + w]
            wt = ws * np.exp(-((nb - video) ** 2) * inv2r) * (nb > 0)
            num += wt * nb
            den += wt
    out = np.where(valid & (den > 0), num / np.maximum(den, 1e-30), 0.0)
    out = np.where(sr > 0, out, video).astype(np.float32)
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
    """
    up = upsample_nearest(np.asarray(lowres, np.float32), r)
    sig = np.asarray(sigma_mm, np.float32)
    if sig.ndim >= 2:
        sig = upsample_nearest(sig, r)
    return masked_bilateral(
        up, float(r) if sigma_space_px is None else sigma_space_px, range_factor * sig
    )


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
