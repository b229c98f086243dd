"""Edge-preserving smoothing of each surface of a high-res depth frame, along its plane
(beyond the paper).

The last step of every output frame (:func:`upsr.method.finishing.finish_frame`, after the
blocks follow their slopes) and of :func:`upsr.method.deblurring.deblur` when
``DeblurConfig.smooth_sigma_mm`` is set: it averages each pixel with its neighbours on the same
surface, each neighbour carried to the pixel along the surface's local plane.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr._numba import SAFE_FASTMATH
from upsr.errors import InputError
from upsr.method.config import DeblurConfig

__all__ = ["SAME_SURFACE_SIGMAS", "smooth_output", "smooth_surfaces"]

#: Without an edge threshold, a step of more than this many range stds across the slope's
#: baseline is an edge (the pipeline gives its own, ``edge_mm``).
SAME_SURFACE_SIGMAS = 6.0
#: Inverse depth (1/mm) is carried in units of 10⁻⁶/mm: 100–10 000 for depths of 0.1–10 m.
_INVERSE_UNIT = 1.0e6


def smooth_surfaces(
    depth_mm: npt.ArrayLike,
    sigma_mm: float,
    sigma_px: float,
    baseline_px: int | None = None,
    edge_mm: float | None = None,
) -> np.ndarray:
    """Edge-preserving smoothing of a high-res depth frame along each surface's plane.

    Not in the paper. A bilateral filter (Tomasi & Manduchi 1998) of the inverse depth, each
    neighbour q of a pixel p first carried to p along the local plane: in a pinhole camera a
    plane's inverse depth 1/z is an affine function of the pixel (u, v), so

        ŵ_q = w_q − g_p · (q − p),   w = 1/z,   g_p the gradient of w at p,

    is the plane's value at p for every q on it, whatever its slope, and the average

        1/ẑ_p = Σ_q G(q − p) · R(e_q) · ŵ_q / Σ_q G(q − p) · R(e_q),
        e_q = (ŵ_q − w_p) · z_p²   (mm),

    with the spatial weight G = exp(−|q − p|²/2 sigma_px²) over a circular window of radius
    ⌈2·sigma_px⌉ and the range weight R = exp(−e²/2 sigma_mm²), removes noise from slanted
    surfaces (floors and walls seen at grazing angles, a camera's own motion) as it does from
    fronto-parallel ones; a plain bilateral filter of z gives a steep surface's neighbours no
    weight and leaves its noise. Neighbours across a depth edge of more than a few
    ``sigma_mm`` get no weight (a 5σ step: exp(−12.5) ≈ 4·10⁻⁶), so no depth between two
    surfaces is created.

    The gradient g_p is the central difference of w over ±``baseline_px`` along each axis
    where the steps on both sides agree within ``edge_mm``; the one-sided difference where
    the other side has no depth (the frame's border, a hole) and the step is at most
    ``edge_mm``; 0 elsewhere, where the filter is a plain bilateral filter of w: never a
    slope from a pixel's step towards one side where the other side is an edge (the pixel
    may be a mix of the two surfaces: the one-sided slope there made flying pixels of pixels
    135–150 mm off, the realistic ToF room, recursive, seed 0: 0.46 → 0.50 %; without it
    0.46 → 0.45).
    Invalid pixels (0, NaN, ±inf, negative) are 0 in the output and, like the pixels outside
    the frame, never get any weight.

    Compiled: the range weight exp(−t), t = e²/2σ², is evaluated as p(t/64)⁶⁴, p the 4th-order
    Taylor polynomial of exp(−u) (relative error < 10⁻⁴ where the weight exceeds 10⁻⁴);
    rows are independent (the result does not depend on the number of threads).

    Parameters
    ----------
    depth_mm : array_like (H, W)
        Depth in mm, 0 = unknown.
    sigma_mm : float
        Range std (mm), > 0.
    sigma_px : float
        Spatial std (px), > 0.
    baseline_px : int, optional
        Half baseline b of the slope's differences (px, ≥ 1); default 2·sigma_px rounded,
        r for the pipeline's r/2 (one low-res pixel: across the step between two r×r blocks).
    edge_mm : float, optional
        A step of more than this (mm) across ``baseline_px`` is an edge, not a slope
        (default :data:`SAME_SURFACE_SIGMAS` · ``sigma_mm``; the pipeline gives its edge
        threshold).

    Returns
    -------
    ndarray float32 (H, W)

    References
    ----------
    C. Tomasi and R. Manduchi, "Bilateral filtering for gray and color images", ICCV 1998.
    """
    x = np.ascontiguousarray(depth_mm, dtype=np.float32)
    if x.ndim != 2:
        raise InputError(f"smooth_surfaces expects a 2-D depth image, got shape {x.shape}")
    if not (sigma_mm > 0 and sigma_px > 0):
        raise InputError(f"sigma_mm and sigma_px must be > 0, got {sigma_mm}, {sigma_px}")
    if baseline_px is None:
        baseline_px = max(1, round(2.0 * sigma_px))
    if int(baseline_px) != baseline_px or baseline_px < 1:
        raise InputError(f"baseline_px must be a whole number ≥ 1, got {baseline_px}")
    if edge_mm is None:
        edge_mm = SAME_SURFACE_SIGMAS * float(sigma_mm)
    if not edge_mm > 0:
        raise InputError(f"edge_mm must be > 0, got {edge_mm}")
    radius = int(np.ceil(2.0 * sigma_px))
    dys, dxs, weights = _window(radius, float(sigma_px))
    h, w = x.shape
    pad = max(radius, int(baseline_px))
    wp = np.zeros((h + 2 * pad, w + 2 * pad), np.float32)
    _inverse_kernel(x, pad, wp)
    out = np.empty((h, w), np.float32)
    # (t/64 for the 64th power of the Taylor polynomial; e in mm from Δw · z²/unit)
    c = np.float32(1.0 / (2.0 * float(sigma_mm) ** 2 * 64.0))
    _smooth_kernel(x, wp, pad, int(baseline_px), dys, dxs, weights, c, np.float32(edge_mm), out)
    return out


def smooth_output(
    out: np.ndarray, cfg: DeblurConfig, scale: int, *, edge_mm: float | None = None
) -> np.ndarray:
    """The final smoothing of an output frame with the deblurring's settings, beyond the
    paper: each surface smoothed along its plane (:func:`smooth_surfaces`, range std
    ``cfg.smooth_sigma_mm``, spatial std ``cfg.smooth_sigma_px`` or r/2, the slope measured
    across ±r px: one block), where the deblurring is on and ``cfg.smooth_sigma_mm`` is set.

    The pipeline's last step, after the blocks follow their slopes
    (:func:`upsr.method.finishing.finish_frame`): on a staircase the slopes it measures would
    be a block's steps (the realistic scenes' surface rmse, seed 0, windowed / recursive:
    −4.3 / −4.4 % smoothing inside the deblurring, −9.6 / −9.2 % last;
    docs/notes/depth-rules.md); :func:`upsr.method.deblurring.deblur` alone ends with it.

    Parameters
    ----------
    out : ndarray float32 (r·h, r·w)
        Depth (mm), 0 = unknown.
    cfg : DeblurConfig
        ``enabled``, ``smooth_sigma_mm``, ``smooth_sigma_px``, ``edge_mm``.
    scale : int
        r (the slope's half baseline and the default spatial std r/2).
    edge_mm : float, optional
        A step of more than this across ±r px is an edge, not a slope (the video's edge
        threshold; default ``cfg.edge_mm``).

    Returns
    -------
    ndarray float32 (r·h, r·w): ``out`` itself where the smoothing is off.
    """
    if not (cfg.enabled and cfg.smooth_sigma_mm is not None):
        return out
    sigma_px = cfg.smooth_sigma_px if cfg.smooth_sigma_px is not None else 0.5 * scale
    edge = cfg.edge_mm if edge_mm is None else edge_mm
    return smooth_surfaces(out, cfg.smooth_sigma_mm, sigma_px, baseline_px=scale, edge_mm=edge)


def _window(radius: int, sigma_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The offsets (dy, dx) of a circular window of ``radius`` px but its centre (weight 1,
    residual 0: the kernel's start) and their spatial weights exp(−(dy² + dx²)/2σ²)."""
    offsets = [
        (dy, dx)
        for dy in range(-radius, radius + 1)
        for dx in range(-radius, radius + 1)
        if (dy, dx) != (0, 0) and dy * dy + dx * dx <= radius * radius
    ]
    dys = np.array([dy for dy, _ in offsets], np.int64)
    dxs = np.array([dx for _, dx in offsets], np.int64)
    weights = np.exp(-(dys**2 + dxs**2) / (2.0 * sigma_px**2)).astype(np.float32)
    return dys, dxs, weights


@nb.njit(cache=True, nogil=True, parallel=True)
def _inverse_kernel(x, pad, wp):  # pragma: no cover - numba
    """``wp[pad + i, pad + j]``: the inverse depth unit / x[i, j] where x is a depth (finite,
    > 0), else left 0 (one pass; exact division, as NumPy's)."""
    h, w = x.shape
    unit = np.float32(_INVERSE_UNIT)
    for i in nb.prange(h):
        for j in range(w):
            v = x[i, j]
            if np.isfinite(v) and v > 0:
                wp[pad + i, pad + j] = unit / v


@nb.njit(cache=True, nogil=True, inline="always")
def _slope(a, p, m, s, inv_b, tol):  # pragma: no cover - numba
    """The gradient of w at a pixel of inverse depth ``a`` > 0 from its neighbours ``p``
    (+b) and ``m`` (−b), 0 where missing; ``s`` = z²/unit converts a step of w to mm:
    central where the two steps agree, one-sided where the other side has no depth.
    Branch-free (selects: the row's loop vectorises)."""
    dp = (p - a) * s
    dm = (a - m) * s
    okp = p > 0
    okm = m > 0
    agree = okp & okm & (abs(dp - dm) < tol)
    nearp = okp & (abs(dp) < tol) & ~okm
    nearm = okm & (abs(dm) < tol) & ~okp
    half = np.float32(0.5)
    zero = np.float32(0.0)
    one_sided = (p - a) if nearp else ((a - m) if nearm else zero)
    g = (p - m) * half if agree else one_sided
    return g * inv_b


@nb.njit(cache=True, nogil=True, parallel=True, fastmath=SAFE_FASTMATH)
def _smooth_kernel(depth, wp, pad, b, dys, dxs, weights, c, tol, out):  # pragma: no cover
    """The plane-following bilateral filter of the inverse depth ``wp`` (zero-padded by
    ``pad``) of ``depth`` into ``out`` (mm): each pixel's depth moved by the weighted mean of
    its neighbours' residuals ŵ_q − w_p (a surface of one depth keeps it exactly). ``depth``
    is read only where ``wp`` > 0 (elsewhere it may be NaN, ±inf or ≤ 0: out is 0 there)."""
    h, w = out.shape
    n = weights.size
    one = np.float32(1.0)
    zero = np.float32(0.0)
    inv_unit = np.float32(1.0 / _INVERSE_UNIT)
    inv_b = np.float32(1.0 / b)
    c2 = np.float32(1.0 / 2.0)  # the Taylor coefficients of exp(−u)
    c3 = np.float32(1.0 / 6.0)
    c4 = np.float32(1.0 / 24.0)
    for i in nb.prange(h):
        gy = np.empty(w, np.float32)
        gx = np.empty(w, np.float32)
        s = np.empty(w, np.float32)
        num = np.zeros(w, np.float32)
        den = np.ones(w, np.float32)  # (the pixel itself: weight 1, residual 0)
        row = wp[i + pad, pad : pad + w]
        drow = depth[i]
        up = wp[i + pad + b, pad : pad + w]
        down = wp[i + pad - b, pad : pad + w]
        right = wp[i + pad, pad + b : pad + b + w]
        left = wp[i + pad, pad - b : pad - b + w]
        for j in range(w):  # branch-free (SIMD)
            a = row[j]
            d = drow[j]
            sj = d * d * inv_unit
            valid = a > 0
            s[j] = sj
            gy[j] = _slope(a, up[j], down[j], sj, inv_b, tol) if valid else zero
            gx[j] = _slope(a, right[j], left[j], sj, inv_b, tol) if valid else zero
        for k in range(n):
            dy = np.float32(dys[k])
            dx = np.float32(dxs[k])
            wk = weights[k]
            c0 = pad + dxs[k]
            q = wp[i + pad + dys[k], c0 : c0 + w]
            for j in range(w):  # branch-free (SIMD)
                pred = q[j] - gy[j] * dy - gx[j] * dx
                e = (pred - row[j]) * s[j]
                u = min(e * e * c, one)  # t/64, t = e²/2σ² (beyond 64: weight ~e⁻⁶⁴)
                f = one - u * (one - u * (c2 - u * (c3 - u * c4)))
                f = f * f
                f = f * f
                f = f * f
                f = f * f
                f = f * f
                f = f * f
                wt = wk * f * np.float32(q[j] > 0)
                num[j] += wt * (pred - row[j])
                den[j] += wt
        orow = out[i]
        for j in range(w):
            a = row[j]
            orow[j] = drow[j] / (one + num[j] / (den[j] * a)) if a > 0 else zero
