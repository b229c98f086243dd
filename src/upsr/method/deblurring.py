r"""Deblurring of the fused image with an L1 data term and bilateral total variation (eq. 29–30).

.. math::

    \hat x = \arg\min_x \; \|B x - z\|_1 + \lambda\, \Gamma_{BTV}(x), \qquad
    \Gamma_{BTV}(x) = \sum_{l,m=-P}^{P} \alpha^{|l|+|m|} \, \|x - S_x^l S_y^m x\|_1

(Farsiu et al. 2004). Depth-specific rules:

* only pixels valid in z (> 0) are unknowns; invalid pixels stay 0, never enter a blur or a
  BTV difference;
* with ``edge_mm`` set, BTV pairs across a depth discontinuity of the fused image (|Δz| >
  ``edge_mm``) are left out, so the regulariser never pulls foreground and background towards
  each other (no flying pixels). ``edge_mm=None`` gives the paper's plain BTV.

Solver: steepest descent on the subgradient (the paper's), normalised so that no pixel moves by
more than β_k per step, with the geometric schedule β_k = β₀·decay^k.
"""

from __future__ import annotations

import cv2
import numba as nb
import numpy as np
import numpy.typing as npt

from upsr._numba import SAFE_FASTMATH
from upsr.errors import InputError
from upsr.method.config import DeblurConfig

__all__ = [
    "btv_energy",
    "btv_subgradient",
    "deblur",
    "deblur_energy",
    "estimate_noise_mm",
    "smooth_surfaces",
]


def _shift_table(radius: int, alpha: float, lam: float = 1.0):
    """The (2P+1)²−1 shifts (l, m) ≠ 0 of eq. 29 with their weights 2·λ·α^{|l|+|m|}."""
    shifts = [(dl, dm) for dl in range(-radius, radius + 1) for dm in range(-radius, radius + 1)]
    shifts.remove((0, 0))
    weights = np.array([2.0 * lam * alpha ** (abs(a) + abs(b)) for a, b in shifts], np.float32)
    dls = np.array([a for a, _ in shifts], np.int64)
    dms = np.array([b for _, b in shifts], np.int64)
    return weights, dls, dms


@nb.njit(cache=True, nogil=True, parallel=True)
def _pair_masks(gp, dls, dms, pad, edge_mm, shifts, masks):  # pragma: no cover - numba
    """masks[q, i, j] = 1 where the pair (p, p + shift b), b = shifts[q], is regularised:
    both pixels valid in the guide and on one surface (|Δguide| ≤ edge_mm); else 0. Computed
    once per image. ``gp`` is the guide zero-padded by ``pad`` ≥ P on every side (outside the
    image = invalid), so that the loop over a row has no bounds test and vectorises (SIMD).
    One byte per pair: the descent reads it with one load and one conversion."""
    n_shifts, h, w = masks.shape
    for i in nb.prange(h):
        g = gp[i + pad, pad : pad + w]
        for q in range(n_shifts):
            b = shifts[q]
            c0 = pad + dms[b]
            n = gp[i + pad + dls[b], c0 : c0 + w]
            m = masks[q, i]
            for j in range(w):
                m[j] = np.uint8((g[j] > 0) & (n[j] > 0) & (abs(n[j] - g[j]) <= edge_mm))


@nb.njit(cache=True, nogil=True, inline="always", fastmath=True)
def _btv_row(xp, masks, weights, dls, dms, pad, i, j0, j1, acc):  # pragma: no cover - numba
    """acc[j] = Σ_b weights[b]·sign(x[i, j] − x[(i, j) + shift b]) over the pairs of
    masks[b, i] (the masks of every shift), for j0 ≤ j < j1 (acc[j − j0]).

    ``xp`` is x zero-padded by ``pad`` ≥ P on every side, so that the loop over j reads
    every shifted row without a bounds test and vectorises (SIMD)."""
    w = j1 - j0
    acc[:w] = 0.0
    xr = xp[i + pad, pad + j0 : pad + j1]
    for b in range(weights.size):
        wb = weights[b]
        c0 = pad + dms[b] + j0
        xn = xp[i + pad + dls[b], c0 : c0 + w]
        mrow = masks[b, i, j0:j1]
        for j in range(w):
            d = xr[j] - xn[j]
            s = np.float32(d > 0) - np.float32(d < 0)
            acc[j] += s * (wb * np.float32(mrow[j]))


@nb.njit(cache=True, nogil=True, parallel=True)
def _btv_gradient_kernel(xp, masks, weights, dls, dms, pad, out):  # pragma: no cover - numba
    h, w = out.shape
    for i in nb.prange(h):
        acc = np.empty(w, np.float32)
        _btv_row(xp, masks, weights, dls, dms, pad, i, 0, w, acc)
        out[i] = acc


@nb.njit(cache=True, nogil=True, parallel=True, fastmath=True)
def _descent_step(
    xp, z, spans, masks, weights, dls, dms, pos, pad, step, n_chunks, out
):  # pragma: no cover - numba
    """One normalised subgradient step of eq. 30 with B = I, fused in one pass:
    out = x − step·(sign(x − z) + λ·∂Γ_BTV/∂x) on the pixels valid in z (0 elsewhere, as
    ``out`` already holds outside the span [spans[i, 0], spans[i, 1]) of valid pixels of each
    row); ``xp`` and ``out`` are padded by ``pad``; the weights include λ.

    Each pair of pixels is visited once: the term T_b(p) = w_b·sign(x_p − x_{p+s_b}) of a
    shift s_b in ``pos`` (the half of the shifts that point down or right) enters the
    gradient at p with + and at p + s_b with − (the pair and its rule are symmetric), so
    the gradient at p is Σ_b T_b(p) − T_b(p − s_b) (masks[q]: the mask of shift pos[q]).
    The terms of the last ``pad`` + 1 rows
    are kept in a ring; the rows are cut into ``n_chunks`` bands (one per thread), each
    starting ``pad`` rows early. The result does not depend on ``n_chunks``."""
    h, w = z.shape
    n_pos = pos.size
    depth = pad + 1
    band = (h + n_chunks - 1) // n_chunks
    for c in nb.prange(n_chunks):
        r0 = c * band
        r1 = min(h, r0 + band)
        # terms[row % depth, q, pad + j] of the pair (p, p + s_pos[q]), p = (row, j); zero
        # outside the image (rows above it, the padding columns)
        terms = np.zeros((depth, n_pos, w + 2 * pad), np.float32)
        # the columns of each ring row that hold terms (all others are 0): a pair's term is
        # 0 unless its first pixel is valid, i.e. in the span of valid pixels of its row
        held = np.zeros((depth, 2), np.int64)
        acc = np.empty(w, np.float32)
        for i in range(max(r0 - pad, 0), r1):
            slot = i % depth
            terms[slot, :, pad + held[slot, 0] : pad + held[slot, 1]] = 0.0
            j0 = spans[i, 0]
            j1 = spans[i, 1]
            held[slot, 0] = j0
            held[slot, 1] = max(j1, j0)
            n = j1 - j0
            xr = xp[i + pad, pad + j0 : pad + j1]
            for q in range(n_pos):
                b = pos[q]
                wb = weights[b]
                c0 = pad + dms[b] + j0
                xn = xp[i + pad + dls[b], c0 : c0 + n]
                mrow = masks[q, i, j0:j1]
                trow = terms[slot, q, pad + j0 : pad + j1]
                for j in range(n):
                    d = xr[j] - xn[j]
                    sgn = np.float32(d > 0) - np.float32(d < 0)
                    trow[j] = sgn * (wb * np.float32(mrow[j]))
            if i < r0 or j1 <= j0:
                continue
            # (every loop index below is the loop variable: no index arithmetic, SIMD)
            acc[:n] = 0.0
            for q in range(n_pos):
                b = pos[q]
                cur = terms[slot, q, pad + j0 : pad + j1]
                c0 = pad - dms[b] + j0
                prev = terms[(i - dls[b]) % depth, q, c0 : c0 + n]
                for j in range(n):
                    acc[j] += cur[j] - prev[j]
            orow = out[i + pad, pad + j0 : pad + j1]
            zr = z[i, j0:j1]
            for j in range(n):
                zv = zr[j]
                d = xr[j] - zv
                sgn = np.float32(d > 0) - np.float32(d < 0)
                orow[j] = (xr[j] - step * (sgn + acc[j])) if zv > 0 else np.float32(0.0)


def _padded(x: np.ndarray, pad: int) -> np.ndarray:
    out = np.zeros((x.shape[0] + 2 * pad, x.shape[1] + 2 * pad), np.float32)
    out[pad : pad + x.shape[0], pad : pad + x.shape[1]] = x
    return out


def _valid_spans(mask: np.ndarray) -> np.ndarray:
    """[first, last + 1) column of the valid pixels of each row ((0, 0) for an empty row)."""
    w = mask.shape[1]
    first = np.argmax(mask, axis=1)
    stop = w - np.argmax(mask[:, ::-1], axis=1)
    empty = ~mask.any(axis=1)
    first[empty] = 0
    stop[empty] = 0
    return np.stack([first, stop], axis=1).astype(np.int64)


def _masks(
    guide: np.ndarray,
    dls: np.ndarray,
    dms: np.ndarray,
    edge_mm: float,
    shifts: np.ndarray | None = None,
) -> np.ndarray:
    """The pair masks of :func:`_pair_masks` for ``shifts`` (default: all, in order)."""
    which = np.arange(dls.size) if shifts is None else np.asarray(shifts, np.int64)
    masks = np.empty((which.size, *guide.shape), np.uint8)
    pad = int(max(np.abs(dls).max(initial=0), np.abs(dms).max(initial=0)))
    _pair_masks(_padded(guide, pad), dls, dms, pad, float(edge_mm), which, masks)
    return masks


@nb.njit(cache=True, nogil=True)
def _btv_energy_kernel(x, guide, radius, alpha, edge_mm):  # pragma: no cover - numba
    h, w = x.shape
    total = 0.0
    for i in range(h):
        for j in range(w):
            gv = guide[i, j]
            if gv <= 0:
                continue
            for dl in range(-radius, radius + 1):
                ii = i + dl
                if ii < 0 or ii >= h:
                    continue
                for dm in range(-radius, radius + 1):
                    jj = j + dm
                    if (dl == 0 and dm == 0) or jj < 0 or jj >= w:
                        continue
                    gn = guide[ii, jj]
                    if gn <= 0 or abs(gn - gv) > edge_mm:
                        continue
                    total += alpha ** (abs(dl) + abs(dm)) * abs(x[i, j] - x[ii, jj])
    return total


def _edge(edge_mm: float | None) -> float:
    return np.inf if edge_mm is None else float(edge_mm)


def btv_energy(
    x: npt.ArrayLike,
    guide: npt.ArrayLike,
    *,
    radius_px: int = 2,
    alpha: float = 0.7,
    edge_mm: float | None = None,
) -> float:
    """Γ_BTV(x) of eq. 29 over the pairs of pixels valid in ``guide`` (and on one surface)."""
    return float(
        _btv_energy_kernel(
            np.ascontiguousarray(x, np.float64),
            np.ascontiguousarray(guide, np.float64),
            int(radius_px),
            float(alpha),
            _edge(edge_mm),
        )
    )


def btv_subgradient(
    x: npt.ArrayLike,
    guide: npt.ArrayLike,
    *,
    radius_px: int = 2,
    alpha: float = 0.7,
    edge_mm: float | None = None,
) -> np.ndarray:
    """Subgradient of :func:`btv_energy` with respect to x (one fused pass, no temporaries).

    Because the shifts l, m = −P…P come in opposite pairs, ∂Γ/∂x_p =
    2 Σ_{(l,m)≠0} α^{|l|+|m|} sign(x_p − x_{p+(l,m)}) over the admissible pairs.
    """
    xa = np.ascontiguousarray(x, np.float32)
    weights, dls, dms = _shift_table(int(radius_px), float(alpha))
    masks = _masks(np.asarray(guide, np.float32), dls, dms, _edge(edge_mm))
    out = np.empty_like(xa)
    _btv_gradient_kernel(_padded(xa, int(radius_px)), masks, weights, dls, dms, int(radius_px), out)
    return out


class _MaskedBlur:
    """B restricted to the valid pixels: B x = (K ∗ (m·x)) / (K ∗ m) on m, a linear operator
    with adjoint Bᵀ g = m · K ∗ (m·g / (K ∗ m)) (K symmetric)."""

    def __init__(self, mask: np.ndarray, model: str, sigma_px: float, scale: int) -> None:
        self.mask = mask.astype(np.float32)
        if model == "box":
            k = max(int(scale), 1)
            self._apply = lambda a: cv2.blur(a, (k, k), borderType=cv2.BORDER_CONSTANT)
        else:
            self._apply = lambda a: cv2.GaussianBlur(
                a, (0, 0), sigma_px, borderType=cv2.BORDER_CONSTANT
            )
        norm = self._apply(self.mask)
        self._inv_norm = np.where(norm > 1e-6, 1.0 / np.maximum(norm, 1e-6), 0.0).astype(np.float32)

    def forward(self, x: np.ndarray) -> np.ndarray:
        return self._apply(x * self.mask) * self._inv_norm * self.mask

    def adjoint(self, g: np.ndarray) -> np.ndarray:
        return self._apply(g * self.mask * self._inv_norm) * self.mask


def _blur_operator(mask: np.ndarray, cfg: DeblurConfig, scale: int) -> _MaskedBlur | None:
    if cfg.blur == "none" or (cfg.blur == "box" and scale <= 1):
        return None
    return _MaskedBlur(mask, cfg.blur, cfg.blur_sigma_px, scale)


def deblur_energy(x: npt.ArrayLike, z: npt.ArrayLike, cfg: DeblurConfig, scale: int = 1) -> float:
    """The objective of eq. 30, ‖Bx − z‖₁ + λ Γ_BTV(x), over the pixels valid in z."""
    z = np.asarray(z, np.float32)
    x = np.asarray(x, np.float32)
    mask = z > 0
    op = _blur_operator(mask, cfg, scale)
    bx = x if op is None else op.forward(x)
    data = float(np.abs(bx - z)[mask].sum(dtype=np.float64))
    return data + cfg.lam * btv_energy(
        x, z, radius_px=cfg.radius_px, alpha=cfg.alpha, edge_mm=cfg.edge_mm
    )


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


def deblur(z: npt.ArrayLike, cfg: DeblurConfig | None = None, *, scale: int = 1) -> np.ndarray:
    """Estimate x̂ of eq. 30 from the fused image z by normalised subgradient descent, then
    smooth each surface (``cfg.smooth_sigma_mm``, beyond the paper).

    Parameters
    ----------
    z : array_like, (H, W)
        Fused depth (mm), 0 = unknown.
    cfg : DeblurConfig
        λ, α, P, blur model, step schedule, iterations, edge rule (see :class:`DeblurConfig`).
    scale : int
        SR factor r (size of the ``"box"`` blur model).

    Returns
    -------
    ndarray float32 (H, W), 0 exactly where z is 0.
    """
    cfg = cfg or DeblurConfig()
    z = np.ascontiguousarray(z, np.float32)
    mask = z > 0
    if not cfg.enabled or not mask.any():
        return z.copy()
    op = _blur_operator(mask, cfg, scale)
    beta = cfg.step_mm if cfg.step_mm is not None else max(0.5, estimate_noise_mm(z, scale))
    s1 = sum(cfg.alpha ** abs(k) for k in range(-cfg.radius_px, cfg.radius_px + 1))
    norm = 1.0 + cfg.lam * 2.0 * (s1 * s1 - 1.0)
    edge = _edge(cfg.edge_mm)
    pad = cfg.radius_px
    if op is None:
        # B = I (the default): one fused compiled pass per iteration, two padded buffers
        weights, dls, dms = _shift_table(cfg.radius_px, cfg.alpha, cfg.lam)
        # the descent visits each pair once, from its upper (or left) pixel: those masks only
        pos = np.flatnonzero((dls > 0) | ((dls == 0) & (dms > 0)))
        masks = _masks(z, dls, dms, edge, pos)
        spans = _valid_spans(mask)
        n_chunks = min(nb.get_num_threads(), z.shape[0])
        xp, nxt = _padded(z, pad), _padded(np.zeros_like(z), pad)
        for _ in range(cfg.iterations):
            step = np.float32(beta / norm)
            _descent_step(xp, z, spans, masks, weights, dls, dms, pos, pad, step, n_chunks, nxt)
            xp, nxt = nxt, xp
            beta *= cfg.step_decay
        x = xp[pad : pad + z.shape[0], pad : pad + z.shape[1]].copy()
    else:
        weights, dls, dms = _shift_table(cfg.radius_px, cfg.alpha)
        masks = _masks(z, dls, dms, edge)
        x = z.copy()
        reg = np.empty_like(z)
        for _ in range(cfg.iterations):
            grad = op.adjoint(np.sign(op.forward(x) - z))
            _btv_gradient_kernel(_padded(x, pad), masks, weights, dls, dms, pad, reg)
            grad += cfg.lam * reg
            x -= (beta / norm) * grad
            x[~mask] = 0.0
            beta *= cfg.step_decay
    np.maximum(x, np.float32(1e-3), out=x, where=mask)
    if cfg.smooth_sigma_mm is not None:
        sigma_px = cfg.smooth_sigma_px if cfg.smooth_sigma_px is not None else 0.5 * scale
        x = smooth_surfaces(x, cfg.smooth_sigma_mm, sigma_px)
    return x


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
    the exact filter, tests/test_deblurring.py). The rows are cut into bands, one per thread;
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
