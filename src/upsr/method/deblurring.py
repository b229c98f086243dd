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
more than β_k per step, with the geometric schedule β_k = β₀·decay^k. With B = I the image is
extended beyond its border by P px of its odd reflection about its outermost blocks' centres
where a surface slopes across the border beyond the noise (:func:`_reflected`), so that the
pairs of a pixel at the border are as balanced there as inside: such a surface is not pulled
inwards at the border.
"""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method.config import DeblurConfig
from upsr.method.noise import estimate_noise_mm, noise_at_depth
from upsr.method.smoothing import smooth_output
from upsr.method.validation import as_depth_frame

__all__ = [
    "btv_energy",
    "btv_subgradient",
    "deblur",
    "deblur_energy",
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
    xp, z, spans, masks, weights, dls, dms, pos, pad, step, scales, n_chunks, out
):  # pragma: no cover - numba
    """One normalised subgradient step of eq. 30 with B = I, fused in one pass:
    out = x − step·(sign(x − z) + λ·∂Γ_BTV/∂x) on the pixels valid in z (0 elsewhere, as
    ``out`` already holds outside the span [spans[i, 0], spans[i, 1]) of valid pixels of each
    row); ``xp`` and ``out`` are padded by ``pad``; the weights include λ; ``scales`` (h, w):
    the step of each pixel relative to ``step`` (a 0×0 array: 1 everywhere).

    Each pair of pixels is visited once: the term T_b(p) = w_b·sign(x_p − x_{p+s_b}) of a
    shift s_b in ``pos`` (the half of the shifts that point down or right) enters the
    gradient at p with + and at p + s_b with − (the pair and its rule are symmetric), so
    the gradient at p is Σ_b T_b(p) − T_b(p − s_b) (masks[q]: the mask of shift pos[q]).
    The signs of the terms, sign(x_p − x_{p+s_b}) (0 for a pair left out), of the last
    ``pad`` + 1 rows are kept in a ring of bytes (a quarter of the memory of float terms: the
    step 25 % faster at 1024×592 than with float terms; w_b enters with the sum); the rows are
    cut into ``n_chunks`` bands (one per thread), each starting ``pad`` rows early. The result
    does not depend on ``n_chunks``."""
    h, w = z.shape
    n_pos = pos.size
    depth = pad + 1
    band = (h + n_chunks - 1) // n_chunks
    for c in nb.prange(n_chunks):
        r0 = c * band
        r1 = min(h, r0 + band)
        # terms[row % depth, q, pad + j]: the sign of the pair (p, p + s_pos[q]), p = (row, j);
        # zero outside the image (rows above it, the padding columns)
        terms = np.zeros((depth, n_pos, w + 2 * pad), np.int8)
        # the columns of each ring row that hold terms (all others are 0): a pair's term is
        # 0 unless its first pixel is valid, i.e. in the span of valid pixels of its row
        held = np.zeros((depth, 2), np.int64)
        acc = np.empty(w, np.float32)
        for i in range(max(r0 - pad, 0), r1):
            slot = i % depth
            terms[slot, :, pad + held[slot, 0] : pad + held[slot, 1]] = 0
            j0 = spans[i, 0]
            j1 = spans[i, 1]
            held[slot, 0] = j0
            held[slot, 1] = max(j1, j0)
            n = j1 - j0
            xr = xp[i + pad, pad + j0 : pad + j1]
            for q in range(n_pos):
                b = pos[q]
                c0 = pad + dms[b] + j0
                xn = xp[i + pad + dls[b], c0 : c0 + n]
                mrow = masks[q, i, j0:j1]
                trow = terms[slot, q, pad + j0 : pad + j1]
                for j in range(n):
                    d = xr[j] - xn[j]
                    t = np.int8(mrow[j])
                    trow[j] = t if d > 0 else (-t if d < 0 else np.int8(0))
            if i < r0 or j1 <= j0:
                continue
            # (every loop index below is the loop variable: no index arithmetic, SIMD)
            acc[:n] = 0.0
            for q in range(n_pos):
                b = pos[q]
                cur = terms[slot, q, pad + j0 : pad + j1]
                c0 = pad - dms[b] + j0
                prev = terms[(i - dls[b]) % depth, q, c0 : c0 + n]
                wb = weights[b]
                for j in range(n):
                    acc[j] += wb * np.float32(np.int8(cur[j] - prev[j]))
            orow = out[i + pad, pad + j0 : pad + j1]
            zr = z[i, j0:j1]
            if scales.shape[0] == 0:
                for j in range(n):
                    zv = zr[j]
                    d = xr[j] - zv
                    sgn = np.float32(d > 0) - np.float32(d < 0)
                    orow[j] = (xr[j] - step * (sgn + acc[j])) if zv > 0 else np.float32(0.0)
            else:
                sr = scales[i, j0:j1]
                for j in range(n):
                    zv = zr[j]
                    d = xr[j] - zv
                    sgn = np.float32(d > 0) - np.float32(d < 0)
                    sj = step * sr[j]
                    orow[j] = (xr[j] - sj * (sgn + acc[j])) if zv > 0 else np.float32(0.0)


#: Largest factor of a pixel's step over the image's typical step (a noise profile): the steps
#: of a far surface grow with its noise, never beyond (with p = 4 a surface 12 times deeper
#: than the rest had steps 20 736 times the typical one and ended 4 m off its 12 m:
#: tests/method/test_deblurring.py).
MAX_STEP_SCALE = 16.0


def _step_scales(
    z: np.ndarray, mask: np.ndarray, noise_profile: tuple[float, float] | None
) -> np.ndarray:
    """σ(z)/median σ(z) over the valid pixels of a noise profile with p > 0, at most
    :data:`MAX_STEP_SCALE`, float32 (H, W); else a (0, 0) array (one step)."""
    if noise_profile is None or not noise_profile[1] > 0:
        return np.zeros((0, 0), np.float32)
    sigma = noise_at_depth(z, *noise_profile)
    typical = float(np.median(sigma[mask]))
    if not typical > 0:
        return np.zeros((0, 0), np.float32)
    return np.minimum(sigma / np.float32(typical), np.float32(MAX_STEP_SCALE)).astype(np.float32)


#: A pixel beyond the border is the odd reflection of the one inside only where the step of
#: the surface across the border exceeds this many first steps β₀ (the fused image's noise):
#: on a flat surface the reflection's pixels are noisier than the ones they mirror.
REFLECTION_SIGNIFICANCE = 4.0


def _reflected(z: np.ndarray, margin: int, scale: int, gate: float = 0.0) -> np.ndarray:
    """``z`` (H, W) extended by ``margin`` px on every side (at most H − r, W − r; r =
    ``scale``) with its odd reflection about the centres of its outermost r×r blocks: beyond
    the border, 2·c − z(mirror), c the depth at those centres, where both are valid, the
    step |c − z(mirror)| exceeds ``gate`` and the result is > 0; else 0 (no pixel: the
    border's pairs stay one-sided, as on a flat surface). A plane and the staircase of its
    blocks go on as they are (a reflection about the border pixel would make the last block
    a plateau twice as long). Inside the image the BTV pairs of a pixel near the border are
    then as balanced as anywhere: cut off by the border they all pulled a surface sloping
    across it inwards (a floor at a grazing angle, 17 mm per px, r = 4: its last block 12–18
    mm off). Rows first, then columns of the rows' result (the corners from both)."""
    h, w = z.shape
    my = max(min(margin, h - scale), 0)
    mx = max(min(margin, w - scale), 0)
    out = np.zeros((h + 2 * my, w + 2 * mx), np.float32)
    out[my : my + h, mx : mx + w] = z
    _reflect_kernel(out, my, mx, h, w, scale, np.float32(gate))
    return out


@nb.njit(cache=True, nogil=True)
def _reflect_kernel(out, my, mx, h, w, scale, gate):  # pragma: no cover - numba
    """:func:`_reflected` in place: ``out`` holds the image at (my, mx); its margins (0) are
    filled, the rows' (over the image's columns) first, then the columns' (every row)."""
    lo, hi = (scale - 1) // 2, scale // 2  # the rows around the first block's centre
    for j in range(mx, mx + w):  # above and below
        _reflect_line(out[:, j], my, h, lo, hi, scale, gate)
    for i in range(out.shape[0]):  # left and right
        _reflect_line(out[i], mx, w, lo, hi, scale, gate)


@nb.njit(cache=True, nogil=True, inline="always")
def _reflect_line(line, m, n, lo, hi, scale, gate):  # pragma: no cover - numba
    """The ``m`` pixels before and after the ``n`` of ``line`` that start at ``m``."""
    for side in range(2):
        # the block centre's two pixels and the first mirror, counted inwards from the end
        a = line[m + lo] if side == 0 else line[m + n - 1 - lo]
        b = line[m + hi] if side == 0 else line[m + n - 1 - hi]
        if not (a > 0 and b > 0):
            continue
        c = 0.5 * (a + b)
        for k in range(1, m + 1):
            mirror = line[m + scale - 1 + k] if side == 0 else line[m + n - scale - k]
            v = 2.0 * c - mirror
            if mirror > 0 and abs(c - mirror) > gate and v > 0:
                if side == 0:
                    line[m - k] = v
                else:
                    line[m + n - 1 + k] = v


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


def deblur(
    z: npt.ArrayLike,
    cfg: DeblurConfig | None = None,
    *,
    scale: int = 1,
    noise_row_step: int = 1,
    noise_profile: tuple[float, float] | None = None,
) -> np.ndarray:
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
    noise_row_step : int
        The first step β₀ (without ``cfg.step_mm``) is the noise of z estimated from every
        ``noise_row_step``-th row (:func:`upsr.method.noise.estimate_noise_mm`).
    noise_profile : (float, float), optional
        (σ₁, p) of :func:`upsr.method.noise.noise_profile`: with p > 0 the step of each pixel
        is β·σ(z)/median σ(z) over the valid pixels (B = I only): the noise that the first
        step β measures is the image's typical noise, and a near surface of a
        structured-light camera, less noisy than the far ones, is smoothed less.

    Returns
    -------
    ndarray float32 (H, W), 0 exactly where z is 0.

    Raises
    ------
    InputError
        ``z`` not a depth image (:func:`~upsr.method.validation.as_depth_frame`: shape, dtype,
        ±inf, negative depth); ``cfg`` neither a :class:`DeblurConfig` nor a mapping of its
        options.
    """
    if isinstance(cfg, Mapping):
        cfg = DeblurConfig.from_mapping(cfg)
    elif cfg is not None and not isinstance(cfg, DeblurConfig):
        raise InputError(f"cfg must be a DeblurConfig or a mapping of its options, not {cfg!r}")
    z = as_depth_frame(z, name="z")
    x = _deblur(z, cfg, scale=scale, noise_row_step=noise_row_step, noise_profile=noise_profile)
    return smooth_output(x, cfg or DeblurConfig(), scale)


def _deblur(
    z: np.ndarray,
    cfg: DeblurConfig | None = None,
    *,
    scale: int = 1,
    noise_row_step: int = 1,
    noise_profile: tuple[float, float] | None = None,
) -> np.ndarray:
    """:func:`deblur` of a checked float32 depth image without its final smoothing (the
    finishing's call, every frame: the pipeline smooths each output frame last,
    :func:`upsr.method.smoothing.smooth_output`)."""
    cfg = cfg or DeblurConfig()
    z = np.ascontiguousarray(z, np.float32)
    mask = z > 0
    if not cfg.enabled or not mask.any():
        return z.copy()
    op = _blur_operator(mask, cfg, scale)
    beta = (
        cfg.step_mm
        if cfg.step_mm is not None
        else max(0.5, estimate_noise_mm(z, scale, row_step=noise_row_step))
    )
    s1 = sum(cfg.alpha ** abs(k) for k in range(-cfg.radius_px, cfg.radius_px + 1))
    norm = 1.0 + cfg.lam * 2.0 * (s1 * s1 - 1.0)
    edge = _edge(cfg.edge_mm)
    pad = cfg.radius_px
    if op is None:
        # B = I (the default): one fused compiled pass per iteration, two padded buffers, on
        # the image extended beyond its border by P px of its odd reflection (every pixel of
        # the image has all its pairs; 2P measured the same on a floor at a grazing angle)
        ze = _reflected(z, cfg.radius_px, scale, REFLECTION_SIGNIFICANCE * beta)
        weights, dls, dms = _shift_table(cfg.radius_px, cfg.alpha, cfg.lam)
        # the descent visits each pair once, from its upper (or left) pixel: those masks only
        pos = np.flatnonzero((dls > 0) | ((dls == 0) & (dms > 0)))
        masks = _masks(ze, dls, dms, edge, pos)
        spans = _valid_spans(ze > 0)
        n_chunks = min(nb.get_num_threads(), ze.shape[0])
        xp = _padded(ze, pad)
        nxt = np.zeros_like(xp)
        scales = _step_scales(ze, ze > 0, noise_profile)
        for _ in range(cfg.iterations):
            step = np.float32(beta / norm)
            _descent_step(
                xp, ze, spans, masks, weights, dls, dms, pos, pad, step, scales, n_chunks, nxt
            )
            xp, nxt = nxt, xp
            beta *= cfg.step_decay
        y0 = pad + (ze.shape[0] - z.shape[0]) // 2  # (the margins as far as the image allows)
        x0 = pad + (ze.shape[1] - z.shape[1]) // 2
        x = xp[y0 : y0 + z.shape[0], x0 : x0 + z.shape[1]].copy()
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
    # a pixel the descent took to 0 or below (no step schedule should) keeps the fused depth:
    # never a depth of a micrometre where z measured one
    np.copyto(x, z, where=mask & ~(x > 0))
    return x
