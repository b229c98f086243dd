"""Edge-preserving smoothing of each surface of a high-res depth frame (beyond the paper).

The last step of :func:`upsr.method.deblurring.deblur` when ``DeblurConfig.smooth_sigma_mm``
is set: it turns the r×r staircase of dense upsampling into the ramp it samples.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr._numba import SAFE_FASTMATH
from upsr.errors import InputError

__all__ = ["smooth_surfaces"]


def smooth_surfaces(depth_mm: npt.ArrayLike, sigma_mm: float, sigma_px: float) -> np.ndarray:
    """Edge-preserving bilateral smoothing of a high-res depth frame, surface by surface.

    Not in the paper: after the fusion (and deblurring) a slanted surface still shows the
    r×r staircase of dense upsampling wherever the motion did not sample it at sub-pixel
    offsets. A bilateral filter with a small range std ``sigma_mm`` turns the steps into the
    ramp they sample, without mixing surfaces: samples across a depth edge of more than a few
    ``sigma_mm`` get no weight (a 5·σ jump gets exp(−12.5) ≈ 4·10⁻⁶ of the weight), so no depth
    between foreground and background is created. Invalid pixels (0, NaN, ±inf, negative) are
    0 in the output and, like the pixels outside the frame, never get any weight.

    Compiled (beyond OpenCV's ``bilateralFilter``, which it replaces): the weight of a pair of
    pixels is computed once for both (half the exponentials), and the range weight
    exp(−Δ²/2σ²) is evaluated as p(t/64)⁶⁴, p the 4th-order Taylor polynomial of exp(−u)
    (relative error < 10⁻⁴ where the weight exceeds 10⁻⁴; the output is within 0.005 mm of
    the exact filter, tests/method/test_smoothing.py). The rows are cut into bands, one per thread;
    the result does not depend on their number.

    Parameters
    ----------
    depth_mm : array_like (H, W)
        Depth in mm, 0 = unknown.
    sigma_mm : float
        Range std (mm), > 0.
    sigma_px : float
        Spatial std (px), > 0; a circular window of radius ⌈2·sigma_px⌉ px (OpenCV's).

    Returns
    -------
    ndarray float32 (H, W)
    """
    x = np.asarray(depth_mm, dtype=np.float32)
    if x.ndim != 2:
        raise InputError(f"smooth_surfaces expects a 2-D depth image, got shape {x.shape}")
    if not (sigma_mm > 0 and sigma_px > 0):
        raise InputError(f"sigma_mm and sigma_px must be > 0, got {sigma_mm}, {sigma_px}")
    radius = int(np.ceil(2.0 * sigma_px))
    dys, dxs, weights = _half_window(radius, float(sigma_px))
    h, w = x.shape
    xp = np.zeros((h + 2 * radius, w + 2 * radius), np.float32)
    inner = xp[radius : radius + h, radius : radius + w]
    np.copyto(inner, x, where=np.isfinite(x) & (x > 0))  # NaN, ±inf, ≤ 0: invalid
    out = np.empty((h, w), np.float32)
    n_chunks = max(1, min(nb.get_num_threads(), h))
    # (t/64 for the 64th power of the Taylor polynomial)
    c = np.float32(1.0 / (2.0 * float(sigma_mm) ** 2 * 64.0))
    _smooth_kernel(xp, radius, dys, dxs, weights, c, n_chunks, out)
    return out


def _half_window(radius: int, sigma_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The offsets (dy, dx) of a circular window of ``radius`` px that point down or right
    (one of each symmetric pair) and their spatial weights exp(−(dy² + dx²)/2σ²)."""
    offsets = [
        (dy, dx)
        for dy in range(radius + 1)
        for dx in range(-radius, radius + 1)
        if (dy > 0 or dx > 0) and dy * dy + dx * dx <= radius * radius
    ]
    dys = np.array([dy for dy, _ in offsets], np.int64)
    dxs = np.array([dx for _, dx in offsets], np.int64)
    weights = np.exp(-(dys**2 + dxs**2) / (2.0 * sigma_px**2)).astype(np.float32)
    return dys, dxs, weights


@nb.njit(cache=True, nogil=True, parallel=True, fastmath=SAFE_FASTMATH)
def _smooth_kernel(xp, pad, dys, dxs, weights, c, n_chunks, out):  # pragma: no cover - numba
    """Bilateral filter of the valid pixels of xp (zero-padded by ``pad``) into ``out``.

    The weight W_k(p) of the pair (p, p + o_k), o_k one of the half window's offsets, is
    computed once and kept in a ring of the last ``pad`` + 1 rows; the output at p gathers
    Σ_k W_k(p)·x(p + o_k) + W_k(p − o_k)·x(p − o_k) (and its own value, weight 1), in the
    same order whatever the bands: each band starts ``pad`` rows early."""
    h, w = out.shape
    n = weights.size
    depth = pad + 1
    band = (h + n_chunks - 1) // n_chunks
    one = np.float32(1.0)
    c2 = np.float32(1.0 / 2.0)  # the Taylor coefficients of exp(−u)
    c3 = np.float32(1.0 / 6.0)
    c4 = np.float32(1.0 / 24.0)
    for ch in nb.prange(n_chunks):
        r0 = ch * band
        r1 = min(h, r0 + band)
        # ring[row % depth, k, pad + j]: W_k of pixel (row, j); 0 in the padding columns
        # and for the rows above the image (never written)
        ring = np.zeros((depth, n, w + 2 * pad), np.float32)
        num = np.empty(w, np.float32)
        den = np.empty(w, np.float32)
        for i in range(max(r0 - pad, 0), r1):
            slot = i % depth
            xr = xp[i + pad, pad : pad + w]
            for k in range(n):
                c0 = pad + dxs[k]
                xn = xp[i + pad + dys[k], c0 : c0 + w]
                wk = weights[k]
                t = ring[slot, k, pad : pad + w]
                for j in range(w):  # branch-free (SIMD)
                    a = xr[j]
                    b = xn[j]
                    d = a - b
                    u = min(d * d * c, one)  # t/64, t = Δ²/2σ² (beyond 64: weight ~e⁻⁶⁴)
                    e = one - u * (one - u * (c2 - u * (c3 - u * c4)))
                    e = e * e
                    e = e * e
                    e = e * e
                    e = e * e
                    e = e * e
                    e = e * e
                    t[j] = wk * e * np.float32((a > 0) & (b > 0))
            if i < r0:
                continue
            for j in range(w):
                valid = np.float32(xr[j] > 0)
                num[j] = xr[j] * valid
                den[j] = valid
            for k in range(n):
                dy = dys[k]
                c0 = pad + dxs[k]
                cur = ring[slot, k, pad : pad + w]
                xn = xp[i + pad + dy, c0 : c0 + w]
                for j in range(w):
                    num[j] += cur[j] * xn[j]
                    den[j] += cur[j]
                c1 = pad - dxs[k]
                prev = ring[(i - dy) % depth, k, c1 : c1 + w]
                xm = xp[i + pad - dy, c1 : c1 + w]
                for j in range(w):
                    num[j] += prev[j] * xm[j]
                    den[j] += prev[j]
            orow = out[i]
            for j in range(w):
                orow[j] = num[j] / den[j] if xr[j] > 0 else np.float32(0.0)
