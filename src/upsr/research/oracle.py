"""Plain NumPy reference implementations of the compiled (numba) kernels.

These are "the straightforward path": vectorised NumPy versions of

* :func:`upsr.method.fusion.temporal_median` (:func:`temporal_median_numpy`),
* :func:`upsr.method.deblurring.btv_subgradient` (:func:`btv_subgradient_numpy`),
* :func:`upsr.method.noise.estimate_noise_mm` (:func:`estimate_noise_mm_numpy`),
* :func:`upsr.method.deblurring.deblur` with B = I (:func:`deblur_numpy`),
* :func:`upsr.method.outliers.remove_speckles` (OpenCV's speckle filter:
  :func:`upsr.research._oracle_speckles.remove_speckles_opencv`),
* :func:`upsr.super_resolve` with nothing shared between windows, flows at the full r and
  the kernels above (:func:`super_resolve_straightforward`),

with the same semantics, down to the float32 / float64 arithmetic of the kernels. They exist
for the tests (the compiled kernels must compute the same thing) and for the speed benchmark
(the speed-up of the compiled kernels over plain NumPy). They are slow on purpose: no numba,
only array operations, loops only over the samples of a pixel or over the BTV shifts.
"""

from __future__ import annotations

import functools

import numpy as np
import numpy.typing as npt

from upsr.method.config import DeblurConfig, UPSRConfig
from upsr.method.deblurring import REFLECTION_SIGNIFICANCE
from upsr.method.noise import noise_at_depth
from upsr.method.smoothing import smooth_output
from upsr.research._oracle_consistency import misregistered_numpy, registered_samples_numpy
from upsr.research._oracle_edges import edge_votes_numpy
from upsr.research._oracle_speckles import remove_speckles_opencv

__all__ = [
    "btv_subgradient_numpy",
    "deblur_numpy",
    "estimate_noise_mm_numpy",
    "super_resolve_straightforward",
    "temporal_median_numpy",
]


def _take(a: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """a[idx[i, j], i, j] for an (N, H, W) array a and an (H, W) index array."""
    return np.take_along_axis(a, idx[None], axis=0)[0]


def temporal_median_numpy(
    stack: npt.ArrayLike,
    ref: int | None = None,
    *,
    weights: npt.ArrayLike | None = None,
    guide: npt.ArrayLike | None = None,
    guide_bonus: float = 0.35,
    min_valid_fraction: float = 0.5,
    edge_mm: float = 100.0,
    use_mean: bool = False,
) -> np.ndarray:
    """Invalid-aware temporal median, in plain NumPy: the reference of
    :func:`upsr.method.fusion.temporal_median` (same parameters, same result).

    Per pixel: NaN samples (outside the frame) abstain; samples ≤ 0 (no return) only vote on
    validity. The pixel is valid if the weighted share of valid samples among the in-frame ones
    is larger than ``min_valid_fraction`` (equal: valid if the reference sample is). Its valid
    samples are sorted; if their spread is at most ``edge_mm`` the output is their median,
    otherwise they are split into surfaces at gaps larger than ``edge_mm``, each surface votes
    with the sum of its weights (plus ``guide_bonus`` × the valid weight if it holds the guide
    depth, within ``edge_mm``), the largest vote wins (a later surface with an equal vote only
    if it holds the reference sample) and the output is the median of its samples.

    Weights are accumulated in float64, depths stay float32, as in the compiled kernel.

    Parameters
    ----------
    stack : array_like, (N, H, W)
        Registered frames in mm: > 0 valid, 0 = no return, NaN = outside the frame.
    ref : int, optional
        Index of the reference frame (tie-breaks); default the middle one.
    weights : array_like (N, H, W), optional
        Vote weight of each sample (default 1), broadcast to the stack's shape.
    guide : array_like (H, W), optional
        Guide depth (≤ 0 or NaN: none).
    guide_bonus : float
        Weight of the guide, as a share of the total valid vote weight.
    min_valid_fraction : float
        Threshold on the weighted share of valid samples.
    edge_mm : float
        Gap (mm) between sorted samples that separates two surfaces.
    use_mean : bool
        The mean of the winning surface's samples instead of their median (the fusion's
        ``estimator="mean"``).

    Returns
    -------
    ndarray float32 (H, W): the fused depth, 0 where nothing is known.
    """
    arr, ref, wts, g = _fusion_inputs(stack, ref, weights, guide)
    edge = np.float64(edge_mm)
    valid = arr > 0
    known, w_valid, nv, ref_value = _validity_vote(arr, valid, wts, ref, min_valid_fraction)
    vals, ws, in_sorted = _sorted_valid_samples(arr, valid, wts, nv)
    lo, hi = _winning_surface(
        vals,
        ws,
        in_sorted,
        nv,
        known & ~_one_surface(vals, nv, edge),
        g,
        w_valid,
        ref_value,
        edge=edge,
        guide_bonus=guide_bonus,
    )
    med = _mean_of_range(vals, lo, hi) if use_mean else _median_of_range(vals, lo, hi)
    return np.where(known, med, np.float32(0.0)).astype(np.float32)


def _fusion_inputs(
    stack: npt.ArrayLike,
    ref: int | None,
    weights: npt.ArrayLike | None,
    guide: npt.ArrayLike | None,
) -> tuple[np.ndarray, int, np.ndarray, np.ndarray]:
    """The checked inputs of :func:`temporal_median_numpy`: the stack (N, H, W) float32, the
    reference index, the weights (N, H, W) float32 and the guide (H, W) float64 (0: none)."""
    arr = np.asarray(stack, dtype=np.float32)
    if arr.ndim != 3:
        raise ValueError(f"stack must be (N, H, W), got shape {arr.shape}")
    n = arr.shape[0]
    ref = (n - 1) // 2 if ref is None else int(ref)
    if not 0 <= ref < n:
        raise ValueError(f"ref must be in [0, {n}), got {ref}")
    if weights is None:
        wts = np.ones(arr.shape, np.float32)
    else:
        wts = np.broadcast_to(np.asarray(weights, dtype=np.float32), arr.shape)
    if guide is None:
        g = np.zeros(arr.shape[1:], np.float64)
    else:
        g = np.asarray(guide, dtype=np.float32).astype(np.float64)
    return arr, ref, wts, g


def _validity_vote(
    arr: np.ndarray, valid: np.ndarray, wts: np.ndarray, ref: int, min_valid_fraction: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Which pixels are known (weighted share of valid samples among the in-frame ones above
    ``min_valid_fraction``; equal: the reference sample decides), with the valid weight
    (float64 sums of the float32 weights, in sample order, as the kernel), the number of
    valid samples and the reference sample (float64, 0 if invalid)."""
    inside = ~np.isnan(arr)
    w_in = np.zeros(arr.shape[1:], np.float64)
    w_valid = np.zeros(arr.shape[1:], np.float64)
    for k in range(arr.shape[0]):
        w_in += np.where(inside[k], wts[k], np.float32(0.0))
        w_valid += np.where(valid[k], wts[k], np.float32(0.0))
    nv = valid.sum(axis=0)
    r = arr[ref]
    ref_value = np.where(r > 0, r, np.float32(0.0)).astype(np.float64)
    mvf = np.float64(min_valid_fraction)
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = w_valid / w_in
    known = (nv > 0) & ~((frac < mvf) | ((frac == mvf) & (ref_value == 0.0)))
    return known, w_valid, nv, ref_value


def _sorted_valid_samples(
    arr: np.ndarray, valid: np.ndarray, wts: np.ndarray, nv: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The samples of each pixel sorted (invalid ones as +inf, last), their weights alongside
    (0 for the invalid ones) and the mask of the first ``nv`` (the valid ones)."""
    n = arr.shape[0]
    keys = np.where(valid, arr, np.float32(np.inf))
    order = np.argsort(keys, axis=0, kind="stable")
    vals = np.take_along_axis(keys, order, axis=0)
    ws = np.take_along_axis(np.where(valid, wts, np.float32(0.0)), order, axis=0)
    in_sorted = np.arange(n).reshape(n, 1, 1) < nv
    return vals, ws, in_sorted


def _one_surface(vals: np.ndarray, nv: np.ndarray, edge: np.float64) -> np.ndarray:
    """Whether the valid samples of a pixel span at most ``edge`` (one surface)."""
    vmin = vals[0]
    vmax = _take(vals, np.maximum(nv - 1, 0))
    with np.errstate(invalid="ignore"):  # inf - inf where no sample is valid
        return (vmax - vmin).astype(np.float64) <= edge


def _winning_surface(
    vals: np.ndarray,
    ws: np.ndarray,
    in_sorted: np.ndarray,
    nv: np.ndarray,
    several: np.ndarray,
    g: np.ndarray,
    w_valid: np.ndarray,
    ref_value: np.ndarray,
    *,
    edge: np.float64,
    guide_bonus: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The sorted range [lo, hi) of the winning surface of each pixel (all its valid samples
    where ``several`` is false): surfaces split at gaps > ``edge``, each votes with the sum of
    its weights plus ``guide_bonus`` × the valid weight if it holds the guide depth; the
    largest vote wins (a later equal one only if it holds the reference sample)."""
    n = vals.shape[0]
    # surfaces: labels by the cumulative count of gaps > edge_mm in the sorted valid samples
    gaps = np.zeros(vals.shape, bool)
    if n > 1:
        with np.errstate(invalid="ignore"):
            step = (vals[1:] - vals[:-1]).astype(np.float64)
        gaps[1:] = in_sorted[1:] & (step > edge)
    labels = np.cumsum(gaps, axis=0)
    best_lo = np.zeros(vals.shape[1:], np.int64)
    best_hi = nv.astype(np.int64)
    best_w = np.full(vals.shape[1:], -np.inf)
    n_labels = int(labels[:, several].max()) + 1 if several.any() else 0
    for c in range(n_labels):
        member = in_sorted & (labels == c)
        count = member.sum(axis=0)
        exists = several & (count > 0)
        lo = (in_sorted & (labels < c)).sum(axis=0)
        hi = lo + count
        lo_v = _take(vals, np.minimum(lo, n - 1)).astype(np.float64)
        hi_v = _take(vals, np.clip(hi - 1, 0, n - 1)).astype(np.float64)
        acc = np.where(member, ws, np.float32(0.0)).sum(axis=0, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            holds_guide = (g > 0) & (lo_v - edge <= g) & (g <= hi_v + edge)
            acc = acc + np.where(holds_guide, guide_bonus * w_valid, 0.0)
        has_ref = (lo_v <= ref_value) & (ref_value <= hi_v)
        better = exists & ((acc > best_w) | ((acc == best_w) & has_ref))
        best_w = np.where(better, acc, best_w)
        best_lo = np.where(better, lo, best_lo)
        best_hi = np.where(better, hi, best_hi)
    return best_lo, best_hi


def _median_of_range(vals: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The median of the sorted samples lo..hi−1 of each pixel (float32: the mean of the two
    middle values if their number is even)."""
    n = vals.shape[0]
    mid = lo + (hi - lo) // 2
    upper = _take(vals, np.clip(mid, 0, n - 1))
    lower = _take(vals, np.clip(mid - 1, 0, n - 1))
    odd = (hi - lo) % 2 == 1
    with np.errstate(invalid="ignore", over="ignore"):
        return np.where(odd, upper, np.float32(0.5) * (lower + upper))


def _mean_of_range(vals: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The mean of the sorted samples lo..hi−1 of each pixel (float64 sum, float32 result)."""
    idx = np.arange(vals.shape[0])[:, None, None]
    inside = (idx >= lo) & (idx < hi)
    total = np.where(inside, vals, 0.0).sum(axis=0, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (total / np.maximum(hi - lo, 1)).astype(np.float32)


def _checked_stack(
    stack: np.ndarray,
    lowres: np.ndarray,
    maps: np.ndarray,
    ref: int,
    cfg,
    edge_mm: float,
    noise_mm: float,
    anchor: np.ndarray | None,
    profile: tuple[float, float] | None = None,
    caps: np.ndarray | None = None,
    tol: np.ndarray | None = None,
    mixed: bool = False,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """The registered stack with the samples of frames misregistered around a pixel, or that
    did not follow a thin part the others followed (without ``mixed`` pixels), or with a
    radial offset too large to trust there, or beyond the reach of a pixel that moved
    (:func:`upsr.method.memory.beyond_reach`, flow grid = output grid), or nearer than a hole
    of the reference allows, abstaining (NaN, like samples outside); the radial offsets of
    the window and the thin parts followed (or None)."""
    from upsr.method.alternatives import thin_fronts
    from upsr.method.consistency import hole_backgrounds, thin_parts_followed
    from upsr.method.memory import beyond_reach
    from upsr.method.trust import far_offsets, radial_offsets
    from upsr.method.upsampling import upsample_nearest

    n, r = lowres.shape[0], cfg.scale
    offsets = None
    if cfg.radial_compensation and n > 1:
        offsets = radial_offsets(
            lowres, maps, r, ref, sigma_mm=noise_mm, edge_mm=edge_mm,
            radius_px=cfg.radial_radius_px, anchor=anchor, noise_profile=profile,
        )  # fmt: skip
    bad = np.zeros(lowres.shape, bool)
    followed = None
    if cfg.check_registration and n > 1:
        reg = registered_samples_numpy(lowres, maps, r)
        bad = misregistered_numpy(reg, lowres[ref], ref, edge_mm=edge_mm, offsets=offsets)
        if anchor is not None and not mixed:
            followed, lost = thin_parts_followed(
                reg, anchor, tol, thin_fronts(anchor, tol, edge_mm, border_strips=True), ref,
                edge_mm=edge_mm,
                offsets=offsets, min_trusted=cfg.min_trusted_samples, maps=maps,
            )  # fmt: skip
            bad |= lost
    if offsets is not None:
        bad |= far_offsets(offsets, edge_mm)
    if caps is not None:
        bad |= beyond_reach(maps, caps, ref, grid_scale=r)
    stack = np.where(np.stack([upsample_nearest(b, r) for b in bad]), np.nan, stack)
    if cfg.check_registration:
        # a sample nearer than a hole of the reference allows abstains (fusion's hole_floors)
        bg = upsample_nearest(hole_backgrounds(lowres[ref]), r)
        vc = stack
        if offsets is not None:
            vc = stack - np.stack([upsample_nearest(o, r) for o in offsets])
        with np.errstate(invalid="ignore"):
            nearer = (bg > 0)[None] & (stack > 0) & (vc < bg[None] - np.float32(edge_mm))
        stack = np.where(nearer, np.nan, stack)
    return stack.astype(np.float32), offsets, followed


def _abstaining(
    measured: np.ndarray,
    ref: int,
    mixed: bool,
    cfg,
    edge_mm: float,
    noise_mm: float,
    profile: tuple[float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray]:
    """The window with its mixed pixels (``mixed``) and the reference's lone outliers (with
    the trust test) abstaining, before anything is fused; the reference's anchor and
    tolerance (None without the trust test), computed once as by :class:`upsr.UPSR`; and the
    reference's measurement at its removed mixed pixels (0 elsewhere)."""
    from upsr.method.mixed import ABSTAIN, remove_mixed_pixels, removed_depths
    from upsr.method.trust import abstain_lone_outliers, reference_anchor

    lowres = measured
    if mixed:
        lowres = remove_mixed_pixels(measured, edge_mm, marker=ABSTAIN, thin_parts=cfg.thin_parts)
    mixes = removed_depths(measured[ref], lowres[ref])
    if cfg.trust_k is None:
        return lowres, None, None, mixes
    anchor, tol = reference_anchor(
        lowres[ref], noise_mm, cfg.trust_k, edge_mm, noise_profile=profile,
        own_surface="except_rims", keep_steep=not mixed,
    )  # fmt: skip
    return abstain_lone_outliers(lowres, ref, anchor), anchor, tol, mixes


def _trusted_stack(
    stack, anchor, tol, offsets, cfg, edge_mm: float, mixes: np.ndarray, followed, mixed: bool
):
    """The trust rules of the fusion (:mod:`upsr.method.trust`), on the registered high-res
    stack: radial offsets subtracted, untrusted samples abstaining (NaN). Returns the stack,
    the anchor (high-res, 0: none), and the pixels where the output is the anchor. ``stack``
    (N, r·h, r·w); ``anchor``, ``tol``, ``mixes``, ``followed`` (h, w; the last may be None);
    ``offsets`` (N, h, w) or None; ``mixed``: the sensor mixes (no border strips)."""
    from upsr.method.alternatives import alternatives_on_grid, mix_tolerance, surface_alternatives
    from upsr.method.upsampling import upsample_nearest

    r = cfg.scale
    up = lambda a: upsample_nearest(a, r)  # noqa: E731
    if offsets is None:
        offsets = np.zeros((stack.shape[0], *anchor.shape), np.float32)
    alternatives = surface_alternatives(
        anchor, tol, edge_mm, mixes, followed, border_strips=not mixed
    )
    near, near_tol, far, far_tol = alternatives_on_grid(alternatives, r)
    a_hr, t_hr, m_hr, mt_hr = up(anchor), up(tol), up(mixes), up(mix_tolerance(anchor, tol, mixes))
    v = stack
    inside = ~np.isnan(v)
    with np.errstate(invalid="ignore"):
        vc = v - np.stack([up(o) for o in offsets])
        has = inside & (v > 0)
        own = has & (a_hr > 0) & (np.abs(vc - a_hr) <= t_hr)
        side = (np.abs(vc - near) <= near_tol) | (np.abs(vc - far) <= far_tol)
        # a removed mixed pixel's samples: on a surface around it or near its own depth
        free = (a_hr <= 0) & ~(has & (mt_hr > 0) & ~side & (np.abs(vc - m_hr) > mt_hr))
    valid = has & (free | own | side)
    vote = inside & (free | valid)
    out = np.where(vote, np.where(has, vc, v), np.float32(np.nan)).astype(np.float32)
    m, n_own = valid.sum(axis=0), own.sum(axis=0)
    k = cfg.min_trusted_samples
    fallback = (a_hr > 0) & ((m < k) | ((m == n_own) & (n_own < k)))
    # only the own surface trusted: its samples alone (no competition with other surfaces)
    only_own = (a_hr > 0) & (m == n_own)
    return out, a_hr, fallback, only_own


def estimate_noise_mm_numpy(z: npt.ArrayLike, lag_px: int = 1) -> float:
    """:func:`upsr.method.noise.estimate_noise_mm` with NumPy: 1.4826·MAD/√2 of the valid
    same-surface (|Δ| < 100 mm) differences ``lag_px`` apart, horizontally and vertically."""
    z = np.asarray(z, np.float32)
    diffs = []
    for a, b in ((z[:, lag_px:], z[:, :-lag_px]), (z[lag_px:, :], z[:-lag_px, :])):
        d = (a - b)[(a > 0) & (b > 0)]
        diffs.append(d[np.abs(d) < 100.0])
    d = np.concatenate(diffs)
    if d.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


def btv_subgradient_numpy(
    x: npt.ArrayLike,
    guide: npt.ArrayLike,
    *,
    radius_px: int = 2,
    alpha: float = 0.7,
    edge_mm: float | None = None,
) -> np.ndarray:
    """Subgradient of the BTV energy (eq. 29) in plain NumPy: the reference of
    :func:`upsr.method.deblurring.btv_subgradient`.

    ∂Γ/∂x_p = 2 Σ_{(l,m)≠0} α^{|l|+|m|} sign(x_p − x_{p+(l,m)}) over the shifts |l|, |m| ≤ P
    whose neighbour lies in the image, is valid in ``guide`` (> 0) and is on the same surface
    (|guide_p − guide_n| ≤ ``edge_mm``); 0 at the pixels invalid in ``guide``. One loop over
    the (2P+1)² − 1 shifts, shifted slices inside; float32 accumulation, as the kernel.

    Parameters
    ----------
    x : array_like (H, W)
        Current estimate (mm).
    guide : array_like (H, W)
        Validity (> 0) and surfaces of the pairs (the fused image).
    radius_px : int
        BTV half-window P (px).
    alpha : float
        Decay α of the BTV weights.
    edge_mm : float or None
        Pairs with |Δguide| larger than this are left out; ``None``: none is.

    Returns
    -------
    ndarray float32 (H, W)
    """
    xa = np.asarray(x, dtype=np.float32)
    gd = np.asarray(guide, dtype=np.float32)
    if xa.shape != gd.shape or xa.ndim != 2:
        raise ValueError(f"x and guide must be (H, W) of one shape, got {xa.shape}, {gd.shape}")
    edge = np.float64(np.inf if edge_mm is None else edge_mm)
    radius = int(radius_px)
    h, w = xa.shape
    valid = gd > 0
    out = np.zeros((h, w), np.float32)
    for dl in range(-radius, radius + 1):
        for dm in range(-radius, radius + 1):
            i0, i1 = max(0, -dl), min(h, h - dl)
            j0, j1 = max(0, -dm), min(w, w - dm)
            if (dl == 0 and dm == 0) or i0 >= i1 or j0 >= j1:
                continue
            here = (slice(i0, i1), slice(j0, j1))
            there = (slice(i0 + dl, i1 + dl), slice(j0 + dm, j1 + dm))
            pair = valid[here] & valid[there] & (np.abs(gd[here] - gd[there]) <= edge)
            d = xa[here] - xa[there]
            sign = (d > 0).astype(np.float32) - (d < 0).astype(np.float32)
            weight = np.float32(2.0 * alpha ** (abs(dl) + abs(dm)))
            out[here] += np.where(pair, weight * sign, np.float32(0.0))
    return out


def _reflected_numpy(z: np.ndarray, margin: int, scale: int, gate: float) -> np.ndarray:
    """:func:`upsr.method.deblurring._reflected` in plain NumPy: ``z`` extended by ``margin``
    px (at most H − r, W − r) of its odd reflection 2·c − z(mirror) about the centres c of
    its outermost r×r blocks, where both have depth, |c − z(mirror)| > ``gate`` and the
    result is > 0 (else 0); the rows first, then the columns of their result."""

    def rows(a: np.ndarray) -> np.ndarray:
        h = a.shape[0]
        m = max(min(margin, h - scale), 0)
        lo, hi = (scale - 1) // 2, scale // 2
        out = np.zeros((h + 2 * m, a.shape[1]), np.float32)
        out[m : m + h] = a
        for centre, mirror_of, row_of in (
            ((a[lo], a[hi]), lambda k: a[scale - 1 + k], lambda k: m - k),
            ((a[h - 1 - lo], a[h - 1 - hi]), lambda k: a[h - scale - k], lambda k: m + h - 1 + k),
        ):
            c = 0.5 * (centre[0] + centre[1])
            for k in range(1, m + 1):
                mirror = mirror_of(k)
                v = 2.0 * c - mirror
                ok = (centre[0] > 0) & (centre[1] > 0) & (mirror > 0) & (np.abs(c - mirror) > gate)
                out[row_of(k)] = np.where(ok & (v > 0), v, 0.0)
        return out

    return np.ascontiguousarray(rows(rows(np.asarray(z, np.float32)).T).T)


def deblur_numpy(
    z: npt.ArrayLike,
    cfg: DeblurConfig | None = None,
    *,
    scale: int = 1,
    noise_profile: tuple[float, float] | None = None,
    smooth: bool = True,
) -> np.ndarray:
    """BTV-L1 deblurring with B = I in plain NumPy: the reference of
    :func:`upsr.method.deblurring.deblur` (same step rule, same result up to sign ties).

    x₀ = z; x_{k+1} = x_k − β_k / norm · (sign(x_k − z) + λ ∂Γ_BTV(x_k)) on the pixels valid
    in z (0 elsewhere), β₀ = ``cfg.step_mm`` or max(0.5, noise of z), β_{k+1} = β_k ·
    ``cfg.step_decay``, norm = 1 + 2λ((Σ_k α^|k|)² − 1) (with a ``noise_profile`` (σ₁, p),
    p > 0, each pixel's step times σ(z)/median σ(z)); then x ≥ 10⁻³ mm on the valid pixels
    and :func:`upsr.method.smoothing.smooth_surfaces` if ``cfg.smooth_sigma_mm`` is set.

    Parameters
    ----------
    z : array_like, (H, W)
        Fused depth (mm), 0 = unknown.
    cfg : DeblurConfig, optional
        Its ``blur`` must give B = I: ``"none"`` (or ``"box"`` at ``scale`` 1, as in
        :func:`upsr.method.deblurring.deblur`).
    scale : int
        SR factor r (the lag of the noise estimate, the default smoothing std).
    smooth : bool
        The final smoothing (False: the pipeline's, which smooths each output frame last).

    Returns
    -------
    ndarray float32 (H, W), 0 exactly where z is 0.

    Raises
    ------
    NotImplementedError
        For a blur model B ≠ I (``"gaussian"``, or ``"box"`` with ``scale`` > 1).
    """
    cfg = cfg or DeblurConfig()
    if not (cfg.blur == "none" or (cfg.blur == "box" and scale <= 1)):
        raise NotImplementedError(
            f"deblur_numpy implements only B = I (blur='none'), got blur={cfg.blur!r} "
            f"at scale {scale}; use upsr.method.deblurring.deblur"
        )
    z = np.array(z, dtype=np.float32)
    mask = z > 0
    if not cfg.enabled or not mask.any():
        return z
    beta = cfg.step_mm if cfg.step_mm is not None else max(0.5, estimate_noise_mm_numpy(z, scale))
    s1 = sum(cfg.alpha ** abs(k) for k in range(-cfg.radius_px, cfg.radius_px + 1))
    norm = 1.0 + cfg.lam * 2.0 * (s1 * s1 - 1.0)
    # the descent on z extended by its odd reflection where a surface steps across the border
    ze = _reflected_numpy(z, cfg.radius_px, scale, REFLECTION_SIGNIFICANCE * beta)
    my, mx = (ze.shape[0] - z.shape[0]) // 2, (ze.shape[1] - z.shape[1]) // 2
    valid = ze > 0
    x = ze.copy()
    scales = np.float32(1.0)
    if noise_profile is not None and noise_profile[1] > 0:
        sigma = noise_at_depth(ze, *noise_profile)
        scales = (sigma / np.float32(np.median(sigma[valid]))).astype(np.float32)
    for _ in range(cfg.iterations):
        step = np.float32(beta / norm) * scales
        d = x - ze
        data = (d > 0).astype(np.float32) - (d < 0).astype(np.float32)
        reg = btv_subgradient_numpy(
            x, ze, radius_px=cfg.radius_px, alpha=cfg.alpha, edge_mm=cfg.edge_mm
        )
        x = x - step * (data + np.float32(cfg.lam) * reg)
        x[~valid] = 0.0
        beta *= cfg.step_decay
    x = x[my : my + z.shape[0], mx : mx + z.shape[1]].copy()
    np.maximum(x, np.float32(1e-3), out=x, where=mask)
    return smooth_output(x, cfg, scale) if smooth else x


def super_resolve_straightforward(frames: npt.ArrayLike, config: UPSRConfig) -> np.ndarray:
    """UP-SR (paper Table 1) done the straightforward way, as the speed benchmark's baseline.

    For every reference frame its window is processed from scratch: each frame is upsampled
    by r, prefiltered and mapped to 8 bit, and the N−1 consecutive flows of the window are
    estimated in both directions at the full r (the paper's; ``flow_scale``, ``refine_preset``
    and ``camera_motion`` ignored: DIS ``flow_preset`` everywhere); cumulative motion with
    eq. 19, :func:`~upsr.method.registration.warp_nearest` per frame, vote weights from
    :func:`~upsr.method.registration.sample_offsets`, the splat guide from dense motion fields
    (:func:`~upsr.method.fusion.splat_nearest`), :func:`temporal_median_numpy` and
    :func:`deblur_numpy`. Nothing is shared between windows. The per-video depth range and
    noise are fixed from the first N frames, as in :class:`upsr.UPSR`.

    Parameters
    ----------
    frames : array_like (T, h, w)
        Depth in mm (0 = no measurement).
    config : UPSRConfig
        Parameters (deblurring with ``blur="none"`` only).

    Returns
    -------
    ndarray float32 (T, r·h, r·w)
    """
    from upsr.method.finishing import finish_frame, settle_fused
    from upsr.method.frontend import MotionFrontEnd
    from upsr.method.fusion import splat_nearest
    from upsr.method.memory import state_caps
    from upsr.method.motion import make_flow_backend
    from upsr.method.registration import (
        cumulative_flows,
        flows_to_reference,
        sample_offsets,
        warp_nearest,
    )
    from upsr.method.statistics import fix_video_statistics
    from upsr.method.upsampling import upsample_nearest
    from upsr.method.validation import as_depth_video
    from upsr.method.windowed import window_start

    cfg = config
    video = as_depth_video(frames, valid_range_mm=cfg.valid_range_mm)
    t_total, h, w = video.shape
    r, n = cfg.scale, cfg.n_frames
    # UP-SR's motion front-end on the full r grid, DIS flow_preset everywhere, the prefilter
    # on the upsampled frames (OpenCV) and the NumPy noise estimate
    flow = make_flow_backend(cfg.flow, cfg.flow_preset)
    front = MotionFrontEnd(
        cfg, w, grid_scale=r, flow_backend=flow, residual_flow_backend=flow, blockwise=False
    )
    front.fix_statistics(video[:n], estimate_noise=estimate_noise_mm_numpy)
    edge_mm = front.edge_mm
    stats = fix_video_statistics(front, video[:n], cfg)  # (fixed_config: thresholds as fixed)
    trust_mm, reach_mm, fixed = stats.trust_noise_mm, stats.reach_noise_mm, front.fixed_config
    profile = stats.trust_noise_profile
    out = np.empty((t_total, h * r, w * r), np.float32)
    for t in range(t_total):
        s = window_start(t, t_total, cfg)
        ref = t - s
        measured = video[s : s + n]
        lowres, anchor, tol, mixes = _abstaining(
            measured, ref, stats.remove_mixed, cfg, edge_mm, trust_mm, profile
        )
        caps = None if anchor is None else state_caps(anchor, tol, float(n), reach_mm, cfg.trust_k,
            noise_profile=profile, tolerance_sigma_mm=trust_mm)  # fmt: skip
        up = [upsample_nearest(f, r) for f in lowres]
        pre = [front.prefilter(video[k]) for k in range(s, s + n)]
        guides = [front.guide(p) for p in pre]
        fwd: list[np.ndarray | None] = [None] * n
        bwd: list[np.ndarray | None] = [None] * n
        for j in range(n - 1):
            fwd[j], bwd[j + 1] = front.flow_pair(pre[j], pre[j + 1], guides[j], guides[j + 1])
        refine = front.residual_flow if cfg.refine else None
        maps = cumulative_flows(ref, bwd, fwd, (h * r, w * r), refine=refine, guides=guides)
        stack = np.stack([warp_nearest(u, m) for u, m in zip(up, maps, strict=True)])
        stack[stack < 0] = np.nan  # removed mixed pixels abstain like samples outside
        weights = None
        if cfg.edge_weight_px:
            d = np.stack([sample_offsets(m, r) for m in maps])
            s2 = 2.0 * (cfg.edge_weight_px * r) ** 2
            weights = cfg.edge_weight_floor + (1.0 - cfg.edge_weight_floor) * np.exp(-d * d / s2)
        guide = None
        if cfg.splat_radius_px and n > 1:
            back = flows_to_reference(ref, bwd, fwd, (h * r, w * r))
            guide = splat_nearest(lowres, np.stack(back), r, cfg.splat_radius_px)
        stack, offsets, followed = _checked_stack(
            stack, lowres, maps, ref, cfg, edge_mm, reach_mm, anchor, profile,
            caps, tol, stats.remove_mixed,
        )  # fmt: skip
        fallback = only_own = None
        if anchor is not None:
            stack, anchor_hr, fallback, only_own = _trusted_stack(
                stack, anchor, tol, offsets, cfg, edge_mm, mixes, followed, stats.remove_mixed
            )
        fuse = functools.partial(
            temporal_median_numpy, stack, ref, weights=weights, guide=guide,
            min_valid_fraction=cfg.min_valid_fraction, use_mean=stats.estimator == "mean",
        )  # fmt: skip
        fused = fuse(edge_mm=edge_mm)
        if fallback is not None:
            # the reference measured depth: its own surface's samples alone, or the anchor
            fused = np.where(only_own, fuse(edge_mm=np.inf), fused)
            fused = np.where(fallback, anchor_hr, fused)
        fused[~upsample_nearest((lowres > 0).any(axis=0), r)] = 0.0
        fused = edge_votes_numpy(lowres, maps, offsets, stack, fused, ref, cfg, edge_mm)
        fused = settle_fused(
            fused, lowres[ref], measured[ref], anchor, caps, cfg, edge_mm=edge_mm,
            keep_mean=stats.remove_mixed,
        )  # fmt: skip
        res = remove_speckles_opencv(
            deblur_numpy(fused, fixed.deblur, scale=r, noise_profile=profile, smooth=False),
            cfg.speckle_size_px,
            fixed.edge_mm,
        )
        # the rules beyond the paper after the deblurring, as the engine applies them
        out[t] = finish_frame(
            res, fused, lowres[ref], anchor, fixed, edge_mm=edge_mm, noise_mm=reach_mm,
            measured=measured[ref],
        )  # fmt: skip
    return out
