"""Single-frame baselines of paper §7: nearest, naive bicubic, bicubic without flying pixels
(§7.4) and joint bilateral upsampling (Kopf et al. 2007, the "2-D/depth fusion" of Fig. 4 (c)).

Everything uses the pixel geometry of ``SPEC.md`` §1: low-res pixel (i, j) sits at high-res
coordinate ((i + 0.5)·r − 0.5, (j + 0.5)·r − 0.5). Depth is float32 mm, 0 = unknown.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method.upsampling import _check_scale, upsample_bicubic, upsample_nearest
from upsr.research.baselines._common import _as_frames

__all__ = [
    "bicubic",
    "bicubic_noflying",
    "joint_bilateral_upsampling",
    "nearest",
]


def nearest(lowres: npt.ArrayLike, r: int) -> np.ndarray:
    """Nearest-neighbour upsampling: each low-res pixel becomes an r×r block.

    The dense upsampling U of UP-SR (paper eq. 13–15) used on its own, one frame at a time.
    It keeps edges and invalid pixels (0) exactly where the low-res frame has them and
    creates no new depth values.

    Parameters
    ----------
    lowres : array_like, shape (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid (NaN becomes 0).
    r : int
        SR factor ≥ 1.

    Returns
    -------
    ndarray of float32, shape (r·h, r·w) or (T, r·h, r·w).
    """
    r = _check_scale(r)
    frames, single = _as_frames(lowres)
    out = upsample_nearest(frames, r).astype(np.float32, copy=False)
    return out[0] if single else out


def bicubic(lowres: npt.ArrayLike, r: int) -> np.ndarray:
    """Naive bicubic interpolation, the conventional baseline of paper §7 (Fig. 3 (b), 6).

    ``cv2.resize`` with ``INTER_CUBIC`` per frame (half-pixel convention of ``SPEC.md`` §1,
    replicated border). Invalid pixels (0) are interpolated as if they were depth 0, as a naive
    bicubic would; the result is clipped at 0 (overshoot below 0 becomes "invalid"). Between
    foreground and background it creates intermediate depths: the *flying pixels* the paper
    criticises.

    Parameters
    ----------
    lowres : array_like, shape (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid, both interpolated as depth 0.
    r : int
        SR factor ≥ 1.

    Returns
    -------
    ndarray of float32 ≥ 0 (0 = invalid), shape (r·h, r·w) or (T, r·h, r·w).
    """
    r = _check_scale(r)
    frames, single = _as_frames(lowres)
    out = upsample_bicubic(frames, r)
    return out[0] if single else out


# ------------------------------------------------------------------------------------------------
# Bicubic with the flying pixels removed (paper §7.4)
# ------------------------------------------------------------------------------------------------
def bicubic_noflying(lowres: npt.ArrayLike, r: int, threshold_mm: float = 100.0) -> np.ndarray:
    """Bicubic interpolation with its flying pixels removed by a fixed threshold (paper §7.4).

    The "modified bicubic interpolation" of paper §7.4 / Fig. 6: :func:`bicubic`, then every
    high-res pixel whose value is not supported by a nearby measurement is set to 0 (unknown).

    Rule: let N(p) be the valid low-res samples whose centres ((i + 0.5)·r − 0.5,
    (j + 0.5)·r − 0.5) lie within r high-res px of p in both directions (Chebyshev distance
    ≤ r, i.e. at most one low-res pixel away: the samples bicubic mostly interpolates between
    and the same (2r+1)² window as the flying-pixel metric of ``SPEC.md`` §6). The pixel keeps
    its bicubic value b(p) if ``min_{c ∈ N(p)} |b(p) − y(c)| ≤ threshold_mm`` and becomes 0
    otherwise (also when N(p) is empty). Values interpolated between a foreground and a
    background sample — or pulled towards 0 by a hole — are far from both and disappear;
    smooth surfaces keep their (noisy) interpolated depth.

    Parameters
    ----------
    lowres : array_like, shape (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid.
    r : int
        SR factor ≥ 1.
    threshold_mm : float
        The fixed threshold (mm), > 0. It should exceed the noise: with noise of std σ, about
        3σ keeps almost all surface pixels.

    Returns
    -------
    ndarray of float32, shape (r·h, r·w) or (T, r·h, r·w); 0 where removed or unknown.
    """
    r = _check_scale(r)
    threshold_mm = float(threshold_mm)
    if not (math.isfinite(threshold_mm) and threshold_mm > 0):
        raise InputError(f"threshold_mm must be a finite number > 0, got {threshold_mm!r}")
    frames, single = _as_frames(lowres)
    up = bicubic(frames, r)
    _, h, w = frames.shape
    hh, ww = h * r, w * r
    # high-res pixel → its low-res block (bi, bj) and the offset of its centre from the centre
    # of the low-res pixel (bi + di, bj + dj), in high-res px
    yy = np.arange(hh)
    xx = np.arange(ww)
    keep = np.zeros(up.shape, bool)
    for di in (-1, 0, 1):
        rows = yy // r + di
        dy = yy - ((rows + 0.5) * r - 0.5)
        row_ok = (rows >= 0) & (rows < h) & (np.abs(dy) <= r)
        rows_c = np.clip(rows, 0, h - 1)
        for dj in (-1, 0, 1):
            cols = xx // r + dj
            dx = xx - ((cols + 0.5) * r - 0.5)
            col_ok = (cols >= 0) & (cols < w) & (np.abs(dx) <= r)
            cols_c = np.clip(cols, 0, w - 1)
            sample = frames[:, rows_c[:, None], cols_c[None, :]]
            near = row_ok[:, None] & col_ok[None, :]
            keep |= near & (sample > 0) & (np.abs(up - sample) <= threshold_mm)
    out = np.where(keep & (up > 0), up, np.float32(0.0)).astype(np.float32)
    return out[0] if single else out


# ------------------------------------------------------------------------------------------------
# Joint bilateral upsampling (Kopf et al. 2007)
# ------------------------------------------------------------------------------------------------
@nb.njit(cache=True, nogil=True, parallel=True)
def _jbu_kernel(depth, guide_hr, guide_lr, r, radius, inv_2ss, inv_2sr, out):  # pragma: no cover
    h, w = depth.shape
    hh, ww, nc = guide_hr.shape
    for y in nb.prange(hh):
        py = (y + 0.5) / r - 0.5  # position of the high-res pixel in low-res pixel units
        ci = math.floor(py + 0.5)
        for x in range(ww):
            px = (x + 0.5) / r - 0.5
            cj = math.floor(px + 0.5)
            # exponents first, then weights relative to the largest (no underflow to 0/0)
            best = -np.inf
            for i in range(max(ci - radius, 0), min(ci + radius + 1, h)):
                for j in range(max(cj - radius, 0), min(cj + radius + 1, w)):
                    if depth[i, j] > 0:
                        ds2 = ((py - i) ** 2 + (px - j) ** 2) * (r * r)
                        dc2 = 0.0
                        for c in range(nc):
                            dc2 += (guide_hr[y, x, c] - guide_lr[i, j, c]) ** 2
                        e = -ds2 * inv_2ss - dc2 * inv_2sr
                        if e > best:
                            best = e
            if best == -np.inf:
                out[y, x] = 0.0
                continue
            num = 0.0
            den = 0.0
            for i in range(max(ci - radius, 0), min(ci + radius + 1, h)):
                for j in range(max(cj - radius, 0), min(cj + radius + 1, w)):
                    d = depth[i, j]
                    if d > 0:
                        ds2 = ((py - i) ** 2 + (px - j) ** 2) * (r * r)
                        dc2 = 0.0
                        for c in range(nc):
                            dc2 += (guide_hr[y, x, c] - guide_lr[i, j, c]) ** 2
                        wgt = math.exp(-ds2 * inv_2ss - dc2 * inv_2sr - best)
                        num += wgt * d
                        den += wgt
            out[y, x] = num / den


def _as_guide(guide: npt.ArrayLike, shape: tuple[int, int], name: str) -> np.ndarray:
    """A guide image as float32 (H, W, C), checked against the high-res ``shape``."""
    g = np.asarray(guide)
    if g.dtype == object or not (
        np.issubdtype(g.dtype, np.integer) or np.issubdtype(g.dtype, np.floating)
    ):
        raise InputError(f"{name}: guide must be a numeric image, got dtype {g.dtype}")
    if g.ndim == 2:
        g = g[..., None]
    if g.ndim != 3 or g.shape[:2] != shape:
        raise InputError(
            f"{name}: expected a guide image of shape {shape} or {(*shape, 'C')}, got {g.shape}"
        )
    g = g.astype(np.float32)
    if not np.isfinite(g).all():
        raise InputError(f"{name}: guide contains NaN or ±inf")
    return np.ascontiguousarray(g)


def joint_bilateral_upsampling(
    lowres_depth_frame: npt.ArrayLike,
    r: int,
    colour_hr: npt.ArrayLike,
    *,
    sigma_spatial_px: float | None = None,
    sigma_range: float | None = None,
) -> np.ndarray:
    r"""Joint bilateral upsampling of depth guided by a high-res image (Kopf et al. 2007).

    Kopf, Cohen, Lischinski, Uyttendaele, "Joint bilateral upsampling", ACM TOG 26(3) (SIGGRAPH
    2007), eq. 2; the "2-D/depth fusion" of the paper's Fig. 4 (c) ([5]):

    .. math::
        \tilde S_p = \frac{1}{k_p} \sum_{q_\downarrow \in \Omega} S_{q_\downarrow}\,
        f(\|p_\downarrow - q_\downarrow\|)\, g(\|\tilde I_p - \tilde I_q\|)

    p↓ is the position of the high-res pixel p on the low-res grid (``SPEC.md`` §1), q↓ runs
    over the low-res pixels of a (2R+1)² window around it, f and g are Gaussians of standard
    deviation ``sigma_spatial_px`` (distance measured in high-res px) and ``sigma_range``
    (guide units, Euclidean distance over the channels), k_p normalises the weights.
    Ĩ_q, the guide at the low-res sample q, is the mean of the guide over q's r×r block
    (what the low-res pixel covers). Invalid low-res pixels (0) get zero weight; a pixel
    with no valid sample in its window is 0. The window radius is R = ⌈2·σ_s / r⌉ low-res px
    (at least 1). Numba-compiled kernel, parallel over rows.

    Like any weighted average it mixes depths where the guide shows no edge, and it copies
    guide texture into the depth (the "texture copying" the paper notes).

    Parameters
    ----------
    lowres_depth_frame : array_like, shape (h, w) or (T, h, w)
        Depth (mm); 0 or NaN = invalid.
    r : int
        SR factor ≥ 1.
    colour_hr : array_like, shape (r·h, r·w), (r·h, r·w, C), or with a leading T for a video
        The registered high-res guide (colour or grey, any numeric range).
    sigma_spatial_px : float, optional
        Spatial σ in high-res px (default r: one low-res pixel).
    sigma_range : float, optional
        Range σ in guide units (default: 10 % of the guide's value range, at least 1e−6).

    Returns
    -------
    ndarray of float32, shape (r·h, r·w) (or (T, r·h, r·w)); 0 = unknown.
    """
    r = _check_scale(r)
    frames, single = _as_frames(lowres_depth_frame)
    t, h, w = frames.shape
    shape = (h * r, w * r)
    g = np.asarray(colour_hr)
    guides = [g] if single else list(g) if g.ndim >= 3 and len(g) == t else None
    if guides is None:
        raise InputError(
            f"colour_hr: a video of {t} depth frames needs {t} guide images, got shape {g.shape}"
        )
    sigma_s = float(r) if sigma_spatial_px is None else float(sigma_spatial_px)
    if not (math.isfinite(sigma_s) and sigma_s > 0):
        raise InputError(f"sigma_spatial_px must be a finite number > 0, got {sigma_spatial_px!r}")
    if sigma_range is not None and not (math.isfinite(sigma_range) and sigma_range > 0):
        raise InputError(f"sigma_range must be a finite number > 0, got {sigma_range!r}")
    radius = max(1, math.ceil(2.0 * sigma_s / r))
    outs = []
    for k, (depth, guide) in enumerate(zip(frames, guides, strict=True)):
        gh = _as_guide(guide, shape, f"colour_hr frame {k}" if not single else "colour_hr")
        sr = sigma_range
        if sr is None:
            sr = max(0.1 * float(gh.max() - gh.min()), 1e-6)
        gl = gh.reshape(h, r, w, r, gh.shape[2]).mean(axis=(1, 3), dtype=np.float64)
        out = np.empty(shape, np.float32)
        _jbu_kernel(
            np.ascontiguousarray(depth),
            gh,
            np.ascontiguousarray(gl, np.float32),
            r,
            radius,
            1.0 / (2.0 * sigma_s**2),
            1.0 / (2.0 * float(sr) ** 2),
            out,
        )
        outs.append(out)
    res = np.stack(outs)
    return res[0] if single else res
