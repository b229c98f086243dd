"""The recursive mode's state update: one frame (step 3–5 of :mod:`upsr.method.recursive`).

Beyond the paper. The high-res state of the previous output (depth and count) is looked up
along the current frame's flow, never interpolated across a depth edge; its offset along the
viewing ray against the frame is subtracted (radial compensation, the rule of
:func:`upsr.method.trust.radial_offsets` with the state's lower noise); each pixel is then
updated with the frame's measurement under the trust rules of the windowed fusion (a sample
beyond the tolerance of the anchor restarts the pixel), kept with its count halved where the
frame measured nothing, and forgotten where nothing supports it. :mod:`upsr.method.recursive`
has the rules in full and the engine around them.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from upsr._numba import SAFE_FASTMATH
from upsr.method.consistency import _block_side, _block_sides, _nearer_beside, hole_backgrounds
from upsr.method.edges import state_votes
from upsr.method.memory import innovation_caps
from upsr.method.registration import _registered_state_kernel, flow_positions
from upsr.method.trust import (
    NO_WEAK_OFFSETS,
    OFFSET_GRID,
    _offset_at,
    _offset_kernel,
    _sigma_and_power,
    _with_wide_offsets,
    far_offsets,
    state_significance,
)

__all__ = [
    "RECENTRE_SIGNIFICANCE",
    "STATE_CONFIRMED_SIGNIFICANCE",
    "STATE_NOISE_FACTOR",
    "STATE_SIGNIFICANCE",
    "recursive_update",
]

#: Standard errors beyond which the correction of an offset measured again around itself
#: (``_recentred``) is kept: the first measurement found the offset significant; its
#: correction is kept beyond its own noise (``benchmarks/realistic_eval.py --quick
#: --no-oracle --scenes toward_wall --scene-option speed_mm=S --seed 1``, recursive, Laplace
#: σ = 30: at S = 50 mean bias −0.42 mm with 0, 0.00 with 1, +0.48 with 2; at S = 100 −0.06 /
#: +0.30 / +1.89, and +21.6 measured once).
RECENTRE_SIGNIFICANCE = 1.0
#: Std of (sample − state) in units of σ in the radial significance test (the state of ≈ N
#: samples is far less noisy than a frame): √((1 + 1/N)/2) of the two-sample test ≈ 0.75.
STATE_NOISE_FACTOR = 0.75
#: Standard errors beyond which the state's radial offset is kept where the frame's flow is
#: zero while the state as a whole came nearer or went farther (trust.OFFSET_SIGNIFICANCE = 4
#: is for frames that did not move): a camera walking towards a wall leaves zero flow around
#: the point it walks towards while every frame comes 25 mm nearer, and offsets cut there
#: accumulate in the state as a lag (realistic_eval --quick, seed 0, the approaching camera:
#: bias 4.29 → 2.22 mm at Laplace σ = 30, 2.78 → 0.91 at Gauss 20; 2 standard errors: 1.04
#: and 0.23 mm, but static walls 3–12 % worse). A static camera keeps 4: on a static scene
#: the state stays the running mean of the samples. There too, where the offset over 5×5
#: pixels is not significant, that of the wide neighbourhood of
#: :func:`~upsr.method.trust.radial_offsets` (its 4 standard errors) is taken: seeds 0–2,
#: bias at Laplace 30 2.22 / 1.51 / 1.88 → 0.07 / −0.70 / −0.66 mm, Gauss 20 0.91 / 0.53 /
#: 0.94 → −0.36 / −0.72 / −0.53, the approaching camera's surface rmse 6–13 % lower at
#: both, the rooms' 1–2 % higher at Laplace 10.
STATE_SIGNIFICANCE = 3.0
#: Standard errors from which an offset where the frame did not move is kept when the same
#: pixel's offset of the previous frame went the same way from as many and the state is at
#: its cap (else from trust.OFFSET_SIGNIFICANCE = 4): a state lags a surface that changes
#: depth by less than 4 standard errors per frame (a body coming nearer, a camera's slow
#: approach) until the lag is significant, while a noise offset of 2 standard errors seldom
#: comes twice in a row the same way (recursive_eval --sizes vga --frames 18, after the
#: first N: the animal 1.062 → 0.978 mm, the room 3.60 → 3.55, the approaching camera 3.10
#: → 3.05; realistic_eval --quick, 240 recursive rows of 9–10 frames: moving surfaces
#: −0.13 %, static +0.005 %; 2 everywhere: moving −1.6 %, static +6.1 %).
STATE_CONFIRMED_SIGNIFICANCE = 2.0


# ---------------------------------------------------------------------------------------------
# compiled kernels
# ---------------------------------------------------------------------------------------------
@nb.njit(cache=True, nogil=True, inline="always", fastmath=SAFE_FASTMATH, error_model="numpy")
def _step(d, m, n, use_mean, sigma):  # pragma: no cover - numba
    e = m - d
    if use_mean:
        return d + e / n
    a = 1.4142135 * max(sigma, 1.0) / n  # (noise-free data still converge)
    return d + min(abs(e), a) * (1.0 if e > 0 else -1.0)


@nb.njit(cache=True, nogil=True, inline="always", fastmath=SAFE_FASTMATH, error_model="numpy")
def _same_surface(depth, count, qx, qy, x0, y0, c0, thr):  # pragma: no cover - numba
    """The state at q, bilinear among the (at most 4) state pixels around q that lie within
    ``thr`` of ``c0`` (never across a depth edge): (depth, count)."""
    hh, ww = depth.shape
    fx = qx - x0
    fy = qy - y0
    sw = 0.0
    sd = 0.0
    sn = 0.0
    for ya in range(y0, y0 + 2):
        wy = fy if ya > y0 else 1.0 - fy
        for xa in range(x0, x0 + 2):
            if 0 <= xa < ww and 0 <= ya < hh:
                v = depth[ya, xa]
                if v > 0 and abs(v - c0) <= thr:
                    wk = wy * (fx if xa > x0 else 1.0 - fx) + 1e-6
                    sw += wk
                    sd += wk * v
                    sn += wk * count[ya, xa]
    return sd / sw, sn / sw


@nb.njit(cache=True, nogil=True, inline="always")
def _seen_around(meas, i, j, value, edge):  # pragma: no cover - numba
    """Some pixel of the 3×3 around (i, j) measured a depth within ``edge`` of ``value``: the
    surface a state holds in a hole of the frame is still seen beside the hole."""
    h, w = meas.shape
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            u = meas[a, b]
            if u > 0 and abs(u - value) <= edge:
                return True
    return False


@nb.njit(cache=True, nogil=True, parallel=True, fastmath=SAFE_FASTMATH, error_model="numpy")
def _update_kernel(
    depth,
    count,
    qxs,
    qys,
    meas,
    anchor,
    tol,
    offsets,
    scale,
    cap,
    use_mean,
    sigma,
    edge,
    holes,
    enclosed,
    around,
    around_tol,
    kept,
    out_d,
    out_n,
):  # pragma: no cover - numba
    hh, ww = out_d.shape
    js, djs = _block_sides(ww, scale)  # (not an integer division per pixel)
    for y in nb.prange(hh):
        i, di = _block_side(y, scale)
        for x in range(ww):
            j = js[x]
            dj = djs[x]
            m = meas[i, j]
            a = anchor[i, j]
            tl = tol[i, j]
            off = offsets[i, j]
            qx = qxs[y, x]
            qy = qys[y, x]
            xn = math.floor(qx + 0.5)
            yn = math.floor(qy + 0.5)
            x0 = math.floor(qx)
            y0 = math.floor(qy)
            # the state pixel that continues this pixel's surface: the nearest, or (when the
            # nearest lies beyond the tolerance) the closest to the anchor of the other 3
            c0 = 0.0
            if 0 <= xn < ww and 0 <= yn < hh:
                c0 = depth[yn, xn]
            c = around[i, j]
            if (
                c > 0
                and c0 > 0
                and abs(c0 - off - c) <= around_tol[i, j]
                and abs(c0 - off - c) < abs(c0 - off - m)
            ):
                # a noise outlier of the frame (a surface of at most two pixels off the one
                # around it) is outvoted by a state on the surface around, as by a window's
                # other frames; the state's count halves, and one that persists (a small
                # object) restarts the pixel once the count has run out
                s, n = _same_surface(depth, count, qx, qy, x0, y0, c0, edge)
                n *= 0.5
                if n >= 1.0:
                    out_d[y, x] = s - off
                    out_n[y, x] = n
                    kept[i, j] = True  # (only ever set: the threads of a block agree)
                else:
                    out_d[y, x] = m
                    out_n[y, x] = 1.0
                continue
            if not m > 0:
                # no measurement: keep what is known, less and less confidently, unless it is
                # nearer than all the frame measured around the hole (the projector shadow
                # beside a moving body: the body is not there) or, in an open hole of the
                # frame, its surface is not seen around the hole (a leg that moved away from
                # where nothing returns: no wall behind it)
                if c0 > 0:
                    s, n = _same_surface(depth, count, qx, qy, x0, y0, c0, edge)
                    n *= 0.5
                    bg = holes[i, j]
                    if (
                        n >= 1.0
                        and not (bg > 0 and s - off < bg - edge)
                        and not _nearer_beside(meas, i, j, di, dj, s - off - edge)
                        and (enclosed[i, j] or _seen_around(meas, i, j, s - off, edge))
                    ):
                        out_d[y, x] = s - off
                        out_n[y, x] = n
                        continue
                out_d[y, x] = 0.0
                out_n[y, x] = 0.0
                continue
            thr = edge
            if tl > 0:
                thr = min(tl, edge)
                if not (c0 > 0 and abs(c0 - off - a) <= tl):
                    best = tl
                    c0 = 0.0
                    for ya in range(y0, y0 + 2):
                        for xa in range(x0, x0 + 2):
                            if 0 <= xa < ww and 0 <= ya < hh and depth[ya, xa] > 0:
                                e = abs(depth[ya, xa] - off - a)
                                if e <= best:
                                    best = e
                                    c0 = depth[ya, xa]
            if c0 > 0:
                s, n = _same_surface(depth, count, qx, qy, x0, y0, c0, thr)
                n = min(n + 1.0, cap[i, j])
                out_d[y, x] = _step(s - off, m, n, use_mean, sigma)
                out_n[y, x] = n
            elif a > 0:
                # restart, counting 2: the mean of the anchor (a median of up to 9 samples of
                # the surface, whose error a quantised sensor's steps or a slope's crease leave
                # in it) and the measurement, whose pull is limited to τ/3 (about σ: a
                # heavy-tailed sample moves it by half a σ at most); the anchor alone where
                # the measurement lies beyond τ of it (an outlier)
                out_d[y, x] = (
                    a + np.float32(0.5) * min(max(m - a, -tl / 3), tl / 3)
                    if abs(m - a) <= tl
                    else a
                )
                out_n[y, x] = min(2.0, cap[i, j])
            else:
                out_d[y, x] = m
                out_n[y, x] = 1.0


def _state_offsets(
    registered: np.ndarray,
    flow: np.ndarray,
    meas: np.ndarray,
    anchor: np.ndarray,
    outliers: np.ndarray | None,
    *,
    scale: int,
    sigma_mm: float,
    edge_mm: float,
    radius_px: int,
    noise_profile: tuple[float, float] | None,
    centres: np.ndarray | None,
    signs: np.ndarray | None = None,
    counts: tuple[np.ndarray, float | np.ndarray] | None = None,
) -> np.ndarray:
    """The radial offset (h, w) of the ``registered`` state (h, w: at each low-res pixel's
    centre) against the frame (step 4 of the module): the significance-tested median of
    :func:`upsr.method.trust.radial_offsets`, without the frame's ``outliers`` (bool (h, w),
    or None). With ``signs`` (int8 (h, w): the signs of the previous frame's offsets from
    :data:`STATE_CONFIRMED_SIGNIFICANCE` standard errors, 0 where none; updated with this
    frame's), an offset from that many standard errors is kept where the previous one there
    went the same way and the state (``counts``: its count (r·h, r·w) and cap, a float or
    (h, w)) is at its cap."""
    if outliers is not None:
        meas = np.where(outliers, np.float32(0.0), meas)
        anchor = np.where(outliers, np.float32(0.0), anchor)
    h, w = meas.shape
    sigma, power = _sigma_and_power(sigma_mm, noise_profile)
    reg = registered[None]
    off = np.empty((1, h, w), np.float32)
    # the state is far less noisy than a frame: the significance test of
    # trust.radial_offsets (made for the difference of two noisy samples) with the std of
    # the difference of a sample and a state of about N samples, ≈ 0.75 σ
    # (-1: no frame of reg is the reference)
    args = (reg, meas, anchor, -1, float(edge_mm), STATE_NOISE_FACTOR * sigma, power)
    signif, along = state_significance(
        flow, reg, meas, sigma_mm=sigma_mm, edge_mm=edge_mm, radius_px=radius_px,
        noise_factor=STATE_NOISE_FACTOR, along_significance=STATE_SIGNIFICANCE,
        centres=centres,
    )  # fmt: skip
    if signs is None:
        _offset_kernel(*args, signif, radius_px, off, *OFFSET_GRID, *NO_WEAK_OFFSETS)
    else:
        weak = np.empty_like(off)
        low = STATE_CONFIRMED_SIGNIFICANCE
        _offset_kernel(*args, signif, radius_px, off, *OFFSET_GRID, low, weak)
        now = np.sign(weak[0]).astype(np.int8)
        # (where the state summarises all the frames its cap allows, read at each block's
        # first pixel: the error of a young state, common to the offsets of consecutive
        # frames, would confirm itself)
        count, cap = counts
        settled = count[::scale, ::scale] >= np.asarray(cap) - 0.5
        confirmed = (off[0] == 0) & (now != 0) & (now == signs) & settled
        off[0] = np.where(confirmed, weak[0], off[0])
        signs[...] = now
    if along:
        # the state as a whole moved along the viewing ray (a camera walking): where the
        # offset is not significant, that of the wide neighbourhood
        off = _with_wide_offsets(off, args, radius_px)
    return _recentred(off[0], registered, args[1:], radius_px)


@nb.njit(cache=True, nogil=True)
def _again_kernel(shifted, meas, anchor, edge, sigma, power, radius, signif, ys, xs, out):
    # pragma: no cover - numba
    """``_offset_at`` of the ``shifted`` state at the pixels (ys[q], xs[q]) only, into out[q]."""
    size = (2 * radius + 1) ** 2
    buf, us = np.empty(size, np.float32), np.empty(size, np.float32)
    rows, cols = np.empty(size, np.int64), np.empty(size, np.int64)
    for q in range(ys.size):
        out[q] = _offset_at(
            shifted, meas, anchor, 0, ys[q], xs[q], edge, sigma, power, radius, 1, buf, rows,
            cols, us, signif, np.inf,
        )[0]  # fmt: skip


def _recentred(off: np.ndarray, registered: np.ndarray, args: tuple, radius_px: int) -> np.ndarray:
    """``off`` (h, w) where it lies within half the edge threshold; beyond it (``far_offsets``:
    the windowed mode's samples abstain there), ``off`` plus the median of the differences
    measured again on the state less ``off``, at those pixels only (``args``:
    ``_offset_kernel``'s after its first; kept beyond :data:`RECENTRE_SIGNIFICANCE` standard
    errors). An offset is measured from the differences within the edge threshold of 0,
    which cuts off the far half of their spread once it nears the threshold, so it fell
    short: a ball 100 mm nearer per frame (``benchmarks/outside_eval.py``, Laplace σ = 30)
    had the state 20 mm behind it on every frame, its moving surface 25.2 mm against the
    per-frame bilateral filter's 13.1."""
    far = far_offsets(off, args[3])
    if not far.any():
        return off
    ys, xs = np.nonzero(far)
    shifted = np.where(registered > 0, registered - off, registered)[None]
    again = np.empty(ys.size, np.float32)
    meas, anchor, _, edge, sigma, power = args
    signif = np.full((1, *off.shape), RECENTRE_SIGNIFICANCE, np.float32)
    _again_kernel(shifted, meas, anchor, edge, sigma, power, radius_px, signif, ys, xs, again)
    out = off.copy()
    out[ys, xs] += again
    return out


def _offsets_and_caps(
    d: np.ndarray,
    c: np.ndarray,
    positions: tuple[np.ndarray, np.ndarray],
    flow: np.ndarray,
    meas: np.ndarray,
    anchor: np.ndarray,
    outliers: np.ndarray | None,
    cap: float | np.ndarray,
    sloped: np.ndarray | None,
    *,
    scale: int,
    sigma_mm: float,
    edge_mm: float,
    radius_px: int | None,
    noise_profile: tuple[float, float] | None,
    centres: np.ndarray | None,
    signs: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """The radial offsets (h, w) of the state (``d``, ``c``) registered along ``positions``
    against the frame (:func:`_state_offsets`; 0 without a state or a ``radius_px``) and the
    caps (h, w): ``cap``, lowered on the ``sloped`` pixels where the registered state strays
    from the frame (:func:`upsr.method.memory.innovation_caps`)."""
    h, w = meas.shape
    offsets = np.zeros((h, w), np.float32)
    caps = np.ascontiguousarray(np.broadcast_to(np.asarray(cap, np.float32), (h, w)))
    if not ((radius_px or sloped is not None) and (d > 0).any()):
        return offsets, caps
    registered = np.empty((h, w), np.float32)  # the state at the low-res pixel centres
    _registered_state_kernel(d, *positions, int(scale), registered)
    if radius_px:
        offsets = _state_offsets(
            registered, flow, meas, anchor, outliers, scale=scale, sigma_mm=sigma_mm,
            edge_mm=edge_mm, radius_px=int(radius_px), noise_profile=noise_profile,
            centres=centres, signs=signs, counts=(c, cap),
        )  # fmt: skip
    if sloped is not None:
        caps = innovation_caps(
            caps, registered, meas, offsets, c[::scale, ::scale], sloped, sigma_mm,
            noise_profile=noise_profile,
        )  # fmt: skip
    return offsets, caps


def recursive_update(
    depth: np.ndarray,
    count: np.ndarray,
    flow: np.ndarray,
    measurement: np.ndarray,
    anchor: np.ndarray,
    tolerance: np.ndarray,
    *,
    scale: int,
    cap: float | np.ndarray,
    estimator: str = "mean",
    sigma_mm: float = 0.0,
    edge_mm: float = 100.0,
    radial_radius_px: int | None = 2,
    noise_profile: tuple[float, float] | None = None,
    holes: np.ndarray | None = None,
    enclosed: np.ndarray | None = None,
    share: np.ndarray | None = None,
    centres: np.ndarray | None = None,
    outliers: tuple[np.ndarray, np.ndarray] | None = None,
    kept: np.ndarray | None = None,
    offset_signs: np.ndarray | None = None,
    sloped: np.ndarray | None = None,
) -> tuple[np.ndarray, ...]:
    """One step of the recursive fusion (see the module): the state (``depth``, ``count``) of
    the previous frame, registered and updated with the current frame's ``measurement``.

    Parameters
    ----------
    depth, count : ndarray float32 (r·h, r·w)
        The previous state (mm, 0 = unknown; confidence in frames).
    flow : ndarray float32 (s·h, s·w, 2)
        Motion from the current frame to the previous one on the flow grid (flow px).
    measurement : ndarray float32 (h, w)
        The current low-res frame (mm, 0 = no measurement), mixed pixels removed.
    anchor, tolerance : ndarray float32 (h, w)
        :func:`upsr.method.trust.reference_anchor` of the measurement; a tolerance of 0
        everywhere trusts every state sample.
    scale : int
        SR factor r.
    cap : float or ndarray float32 (h, w)
        Largest count (the state summarises at most about this many frames), or per low-res
        pixel (:func:`~upsr.method.memory.state_caps`).
    estimator : {"mean", "median"}
    sigma_mm : float
        Noise std (mm): the step of the recursive median and the radial significance test.
    edge_mm : float
        Depth step that separates two surfaces (radial offsets).
    radial_radius_px : int or None
        Half-size of the radial-offset neighbourhood (low-res px); None: no compensation.
    noise_profile : (float, float), optional
        (σ₁, p): the radial significance test with σ(z) = σ₁·(z / 1 m)^p (p > 0) for
        ``sigma_mm`` (:func:`upsr.method.noise.noise_profile`).
    holes : ndarray float32 (h, w), optional
        :func:`upsr.method.consistency.hole_backgrounds` of the current frame: where it
        measured nothing, a state more than ``edge_mm`` nearer than this is forgotten.
        Default: those of ``measurement``.
    enclosed : ndarray bool (h, w), optional
        The pixels of ``measurement`` without depth that lie inside what the frame measured:
        its removed mixed pixels and :func:`upsr.method.consistency.enclosed_holes` (dropouts,
        projector shadows), where a state is kept while its count allows. Elsewhere (an open
        region where nothing returns) it is kept only where its surface (within
        ``edge_mm``) was measured in the 3×3 pixels around. Default: none.
    share : ndarray float32 (r·h, r·w), optional
        The previous state's surface shares: with it, the sub-pixel edge votes
        (:func:`upsr.method.edges.state_votes`) follow the update.
    centres : ndarray (1, h, w, 2), optional
        :func:`upsr.method.consistency.maps_at_centres` of ``flow[None]``, when already
        computed.
    outliers : (ndarray, ndarray) float32 (h, w), optional
        :func:`upsr.method.anchor.noise_outliers` of the frame: a state on the surface around
        an outlier (nearer to it than to the sample) is kept there, its count halved (the
        sample, counting 1, once the count runs out), as a window's other frames outvote it;
        they take no part in the radial offsets. Default: none.
    kept : ndarray bool (h, w), optional
        Filled with the outliers where the state was kept.
    offset_signs : ndarray int8 (h, w), optional
        The signs of the last frame's offsets of :func:`_state_offsets` (zeros after a
        start), updated in place: offsets from :data:`STATE_CONFIRMED_SIGNIFICANCE` kept.
    sloped : ndarray bool (h, w), optional
        The frame's pixels on a significant slope (:func:`upsr.method.slopes.sloped_pixels`),
        whose caps follow the state's differences from the frame (:func:`_offsets_and_caps`).

    Returns
    -------
    (depth, count): the new state, float32 (r·h, r·w); with ``share``, (depth, count, share).
    """
    d = np.ascontiguousarray(depth, np.float32)
    c = np.ascontiguousarray(count, np.float32)
    fl = np.ascontiguousarray(flow, np.float32)
    meas = np.ascontiguousarray(measurement, np.float32)
    h, w = meas.shape
    qx, qy = flow_positions(fl, d.shape)
    zero = np.zeros((h, w), np.float32)
    around, around_tol = (zero, zero) if outliers is None else outliers
    kept = np.empty((h, w), np.bool_) if kept is None else kept
    kept[...] = False
    offsets, caps = _offsets_and_caps(
        d, c, (qx, qy), fl, meas, anchor, None if outliers is None else around > 0, cap,
        sloped, scale=scale, sigma_mm=sigma_mm, edge_mm=edge_mm, radius_px=radial_radius_px,
        noise_profile=noise_profile, centres=centres, signs=offset_signs,
    )  # fmt: skip
    holes = hole_backgrounds(meas) if holes is None else holes
    enclosed = np.zeros((h, w), np.bool_) if enclosed is None else enclosed
    out_d = np.empty_like(d)
    out_n = np.empty_like(c)
    _update_kernel(
        d, c, qx, qy, meas,
        np.ascontiguousarray(anchor, np.float32), np.ascontiguousarray(tolerance, np.float32),
        offsets, int(scale), caps, estimator == "mean", float(sigma_mm), float(edge_mm),
        np.ascontiguousarray(holes, np.float32), np.ascontiguousarray(enclosed, np.bool_),
        np.ascontiguousarray(around, np.float32), np.ascontiguousarray(around_tol, np.float32),
        kept, out_d, out_n,
    )  # fmt: skip
    if share is None:
        return out_d, out_n
    previous = (d, c, np.ascontiguousarray(share, np.float32))
    edge = float(edge_mm)
    votes = state_votes(out_d, out_n, previous, (qx, qy), meas, offsets, scale=scale, edge_mm=edge)
    return out_d, out_n, votes
