"""Fusion of the registered frames by an invalid-aware temporal median (paper eq. 26–28).

Under i.i.d. Laplacian noise the pixel-wise median of the registered upsampled frames is the
maximum-likelihood estimate of z_t0 = B x_t0 (eq. 28). Depth sensors add two kinds of missing
samples, kept apart here:

* **no return** (0 or NaN in the frame, e.g. background out of range, random dropout): these do
  not vote on the depth, but they do vote on *whether there is depth*: a pixel is valid only if
  more than ``min_valid_fraction`` of its in-frame samples are valid (a tie follows the
  reference frame). A random dropout is therefore filled from the other frames, while one stray
  valid sample among "no return"s never invents depth.
* **outside** (the motion points outside the frame, marked NaN in the warped stack by
  :func:`upsr.method.registration.warp_nearest`): abstains entirely.

Where the valid samples come from several surfaces (sorted samples separated by gaps larger than
``edge_mm``: a depth edge, an occlusion), the surface with the largest vote wins and the output
is the median of its samples only. The fusion therefore never averages foreground with
background, even for an even number of samples: no flying pixels.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr._numba import SAFE_FASTMATH
from upsr.errors import InputError
from upsr.method.edges import cell_ranges, edge_band, vote_surface, votes_may_move
from upsr.method.registration import interpolation_tables, weight_table
from upsr.method.sorting import (
    _centre_sorted,
    _heaviest_run,
    _network,
    _sort_columns,
    sorting_network,
)
from upsr.method.splat import splat_nearest, splat_points
from upsr.method.trust import fusion_inputs
from upsr.method.validation import check_ref, nan_as_zero

__all__ = [
    "register_and_fuse",
    "sorting_network",
    "splat_nearest",
    "splat_points",
    "temporal_median",
]


@nb.njit(cache=True, nogil=True, inline="always")
def _too_few_valid(w_valid, w_in, ref_value, min_valid_fraction):  # pragma: no cover - numba
    """Whether a pixel is unknown: at most ``min_valid_fraction`` of the weight of its
    in-frame samples is valid (a tie follows the reference: unknown if its sample is)."""
    frac = w_valid / w_in
    return frac < min_valid_fraction or (frac == min_valid_fraction and ref_value == 0.0)


@nb.njit(cache=True, nogil=True, inline="always")
def _fuse_pixel(
    vals,
    wts,
    nv,
    w_in,
    w_valid,
    ref_value,
    g,
    guide_bonus,
    min_valid_fraction,
    edge_mm,
    network,
    use_mean=False,
):  # pragma: no cover - numba
    """The fused depth of one pixel from its samples: vals[k] > 0 valid (else +inf) with vote
    weights wts[k] (0 for invalid ones); nv valid samples; w_in, w_valid the weight of the
    in-frame and of the valid samples; ref_value the reference's sample (0 if none); g the
    guide (≤ 0 or NaN: none). Sorts vals/wts in place."""
    if _too_few_valid(w_valid, w_in, ref_value, min_valid_fraction):
        return np.float32(0.0)
    # sort the keys (invalid ones are +inf and end up last), weights alongside; branch-free
    # (the order of the samples of an edge pixel is random: a branch would mispredict)
    for c in range(network.shape[0]):
        a = network[c, 0]
        b = network[c, 1]
        va = vals[a]
        vb = vals[b]
        wa = wts[a]
        wb = wts[b]
        swap = va > vb
        vals[a] = vb if swap else va
        vals[b] = va if swap else vb
        wts[a] = wb if swap else wa
        wts[b] = wa if swap else wb
    if vals[nv - 1] - vals[0] <= edge_mm:
        return _centre_sorted(vals, 0, nv, use_mean)
    # samples from several surfaces (a depth edge): the surface with the largest vote
    # weight wins (a tie: the reference's surface); the surface of the guide (the nearest
    # forward-registered sample) gets a bonus; its median is the output
    lo, hi, _ = _heaviest_run(vals, wts, nv, edge_mm, g, guide_bonus * w_valid, ref_value)
    return _centre_sorted(vals, lo, hi, use_mean)


@nb.njit(cache=True, nogil=True, parallel=True)
def _median_kernel(
    stack, weights, guide, guide_bonus, ref, min_valid_fraction, edge_mm, network, out
):  # pragma: no cover - numba
    n, h, w = stack.shape
    inf = np.float32(np.inf)
    for i in nb.prange(h):
        vals = np.empty(n, np.float32)
        wts = np.empty(n, np.float32)
        for j in range(w):
            nv = 0
            w_in = 0.0
            w_valid = 0.0
            for k in range(n):
                v = stack[k, i, j]
                wk = weights[k, i, j]
                vals[k] = inf
                wts[k] = 0.0
                if v != v:  # NaN: outside the frame, abstains
                    continue
                w_in += wk
                if v > 0:
                    w_valid += wk
                    vals[k] = v
                    wts[k] = wk
                    nv += 1
            if nv == 0:
                out[i, j] = 0.0
                continue
            r = stack[ref, i, j]
            ref_value = r if (r == r and r > 0) else 0.0
            out[i, j] = _fuse_pixel(
                vals,
                wts,
                nv,
                w_in,
                w_valid,
                ref_value,
                guide[i, j],
                guide_bonus,
                min_valid_fraction,
                edge_mm,
                network,
            )


@nb.njit(cache=True, nogil=True, parallel=True, fastmath=SAFE_FASTMATH)
def _register_fuse_kernel(
    lowres, maps, scale, ratio, cols, fx, rows, fy, table, step, floor, guide, guide_bonus, ref,
    min_valid_fraction, edge_mm, measured, network, still, anchor, tol, offsets, alt_lo, alt_tlo,
    alt_hi, alt_thi, untrusted, hole_floor, mix_raw, mix_tol, min_trusted, use_mean, band,
    cell_lo, cell_hi, out,
):  # fmt: skip
    # pragma: no cover - numba
    n = lowres.shape[0]
    hh, ww = out.shape
    grid_w = maps.shape[2]
    inf = np.float32(np.inf)
    nan = np.float32(np.nan)
    last = table.size - 1
    # low-res index of a high-res index, and the high-res coordinate of that pixel's centre
    big = max(hh, ww)
    low_of = np.empty(big, np.int64)
    centre_of = np.empty(big, np.float32)
    side_of = np.empty(big, np.int64)  # 1 + the side (−1, 0, 1) of that centre
    for x in range(big):
        low_of[x] = x // scale
        centre_of[x] = (x // scale + 0.5) * scale - 0.5
        side_of[x] = 1 + (1 if x > centre_of[x] else (-1 if x < centre_of[x] else 0))
    half = np.float32(0.5)
    inv_r = np.float32(1.0 / scale)
    w_low = lowres.shape[2]
    for li in nb.prange(lowres.shape[1]):
        # the pixels of the rows whose low-res pixel some frame of the window measured; all
        # others are 0 (never invent depth where the camera saw nothing)
        mrow = measured[li]
        on = np.empty(ww, np.int64)
        m_on = 0
        for j in range(ww):
            if mrow[low_of[j]]:
                on[m_on] = j
                m_on += 1
            else:
                out[li * scale : (li + 1) * scale, j] = 0.0
        if m_on == 0:
            continue
        # the r output rows of low-res row li at a time, what depends on the columns only
        # gathered once for them (10 % faster at 1024×592 than per output row): their
        # interpolation columns (contiguous in the loops below), ...
        on_a = np.empty(m_on, np.int64)
        on_b = np.empty(m_on, np.int64)
        on_fx = np.empty(m_on, np.float32)
        on_low = np.empty(m_on, np.int64)
        on_jd = np.empty(m_on, np.float64)
        on_anc = np.empty(m_on, np.float32)  # the reference's anchor (0: none, no trust test)
        on_tol = np.empty(m_on, np.float32)
        # the nearest depth a sample may have (a hole of the reference beside an edge: the
        # farthest depth measured around it − edge_mm; −inf elsewhere)
        on_floor = np.empty(m_on, np.float32)
        # at a depth edge: the nearest and the farthest other surface among the low-res
        # neighbours on the pixel's side of the centre (0: none), whose samples compete
        # (alternatives.surface_alternatives)
        on_ax = np.empty(m_on, np.float32)
        on_tx = np.empty(m_on, np.float32)
        on_ay = np.empty(m_on, np.float32)
        on_ty = np.empty(m_on, np.float32)
        on_mix = np.empty(m_on, np.float32)  # a removed mixed pixel's depth, its tolerance
        on_mtol = np.empty(m_on, np.float32)  # (0: none, no rule)
        anc_row = anchor[li]
        tol_row = tol[li]
        floor_row = hole_floor[li]
        mix_row = mix_raw[li]
        mtol_row = mix_tol[li]
        for q in range(m_on):
            j = on[q]
            on_jd[q] = np.float64(j)
            on_a[q] = cols[j, 0]
            on_b[q] = cols[j, 1]
            on_fx[q] = fx[j]
            lj = low_of[j]
            on_low[q] = lj
            on_anc[q] = anc_row[lj]
            on_tol[q] = tol_row[lj]
            on_floor[q] = floor_row[lj]
            on_mix[q] = mix_row[lj]
            on_mtol[q] = mtol_row[lj]
        # each output row in turn, every frame's sample of each pixel: loops over the row (SIMD)
        raw = np.empty((n, m_on), np.float32)  # the sample; NaN: outside its frame (abstains)
        srt = np.empty((n, m_on), np.float32)  # the valid samples (+inf for the others), sorted
        n_in = np.empty(m_on, np.int64)
        nv = np.empty(m_on, np.int64)
        total = np.empty(m_on, np.float32)  # sum of the valid (trusted) samples
        n_own = np.empty(m_on, np.int64)  # samples trusted by the pixel's own anchor
        # where each sample lies (output px): its pixel's position + (dx, dy) (in float64;
        # float32 shifts: half the memory of the positions, the kernel 5 % faster at 1024×592)
        dx = np.empty((n, m_on), np.float32)
        dy = np.empty((n, m_on), np.float32)
        pxq, pyq = np.empty(n, np.float64), np.empty(n, np.float64)  # (one pixel's positions)
        at = np.empty(m_on, np.int64)  # its low-res pixel (flat index; -1: outside)
        # its value and whether the frame may vote there (a loop of their own: the trust
        # rules' loop then reads contiguously and vectorises, 28 % faster at 1024×592); each
        # frame's radial offset at the pixel's low-res pixel, whether it is trusted there
        at_value = np.empty(m_on, np.float32)
        at_ok = np.empty(m_on, np.bool_)
        on_off = np.empty((n, m_on), np.float32)
        on_good = np.empty((n, m_on), np.bool_)
        for k in range(n):
            off_k = offsets[k, li]
            bad_k = untrusted[k, li]
            ofk = on_off[k]
            gdk = on_good[k]
            for q in range(m_on):
                ofk[q] = off_k[on_low[q]]
                gdk[q] = ~bad_k[on_low[q]]
        vxk = np.empty(grid_w, np.float32)
        vyk = np.empty(grid_w, np.float32)
        vals = np.empty(n, np.float32)
        wts = np.empty(n, np.float32)
        vals_4 = np.empty(4 * n, np.float32)
        wts_4 = np.empty(4 * n, np.float32)
        for i in range(li * scale, (li + 1) * scale):
            y0 = rows[i, 0]
            y1 = rows[i, 1]
            gy = fy[i]
            fi = np.float64(i)
            # the side of its low-res pixel's centre the row lies on (the alternatives of
            # the row's pixels gathered again where it changes: 2 or 3 times for the r rows)
            sy = side_of[i]
            for q in range(m_on if i == li * scale or sy != side_of[i - 1] else 0):
                lj = on_low[q]
                sx = side_of[on[q]]
                on_ax[q] = alt_lo[sy, sx, li, lj]
                on_tx[q] = alt_tlo[sy, sx, li, lj]
                on_ay[q] = alt_hi[sy, sx, li, lj]
                on_ty[q] = alt_thi[sy, sx, li, lj]
            n_in[:] = 0
            nv[:] = 0
            total[:] = 0.0
            n_own[:] = 0
            for k in range(n):
                if k == still:
                    # a frame that does not move (the reference): the sample of each pixel is
                    # its own low-res pixel, as the general case below gives for a zero flow
                    dx[k] = 0.0  # (read where the vote weights are needed)
                    dy[k] = 0.0
                    own = lowres[k, li]
                    off_k = on_off[k]
                    raw_k = raw[k]
                    srt_k = srt[k]
                    for q in range(m_on):
                        v = own[on_low[q]]
                        a = on_anc[q]
                        vc = v - off_k[q]
                        own_k = (v > 0) & (a > 0) & (abs(vc - a) <= on_tol[q])
                        side = (abs(vc - on_ax[q]) <= on_tx[q]) | (abs(vc - on_ay[q]) <= on_ty[q])
                        fits = ~((v > 0) & (vc < on_floor[q]))  # (not nearer than a hole allows)
                        ok = (v > 0) & ((a <= 0) | own_k | side) & fits
                        # an untrusted sample abstains entirely (neither depth nor "no depth"),
                        # and so does a removed mixed pixel (mixed.ABSTAIN)
                        vote = ((a <= 0) | ok) & (v >= 0) & fits
                        n_own[q] += 1 if own_k else 0
                        raw_k[q] = (vc if v > 0 else v) if vote else nan
                        srt_k[q] = vc if ok else inf
                        total[q] += vc if ok else 0.0
                        n_in[q] += 1 if vote else 0
                        nv[q] += 1 if ok else 0
                    continue
                # the flow-grid row interpolated to this output row, in output px (times r/s)
                m0 = maps[k, y0]
                m1 = maps[k, y1]
                for c in range(grid_w):
                    vxk[c] = ((1 - gy) * m0[c, 0] + gy * m1[c, 0]) * ratio
                    vyk[c] = ((1 - gy) * m0[c, 1] + gy * m1[c, 1]) * ratio
                lk = lowres[k].ravel()
                off_k = on_off[k]
                good_k = on_good[k]
                rk = raw[k]
                sk = srt[k]
                dxk = dx[k]
                dyk = dy[k]
                # where each pixel's sample lies, which low-res pixel that is, its value, then the
                # trust rules: four loops over few arrays each (so that they vectorise)
                for q in range(m_on):
                    a = on_a[q]
                    b = on_b[q]
                    gx = on_fx[q]
                    dxk[q] = vxk[a] + gx * (vxk[b] - vxk[a])
                    dyk[q] = vyk[a] + gx * (vyk[b] - vyk[a])
                for q in range(m_on):
                    qx = on_jd[q] + dxk[q]
                    qy = fi + dyk[q]
                    inside = (-0.5 <= qx) & (qx < ww - 0.5) & (-0.5 <= qy) & (qy < hh - 0.5)
                    xi = min(max(np.int64(qx + 0.5), 0), ww - 1)  # qx + 0.5 >= 0 inside: the floor
                    yi = min(max(np.int64(qy + 0.5), 0), hh - 1)
                    # x // r exactly, without a division: (x + 0.5)/r is ≥ 0.5/r from an integer
                    xl = np.int64((np.float32(xi) + half) * inv_r)
                    yl = np.int64((np.float32(yi) + half) * inv_r)
                    at[q] = (yl * w_low + xl) if inside else np.int64(-1)
                for q in range(m_on):
                    t = at[q]
                    at_value[q] = lk[max(t, 0)]
                    at_ok[q] = (t >= 0) & good_k[q]
                for q in range(m_on):
                    v = at_value[q]
                    a = on_anc[q]
                    vc = v - off_k[q]  # radial motion compensated
                    # outside, frame k misregistered around this pixel, a removed mixed pixel
                    # (mixed.ABSTAIN), or nearer than a hole of the reference allows: abstains
                    fits = ~((v > 0) & (vc < on_floor[q]))
                    inside = at_ok[q] & (v >= 0) & fits
                    own_k = inside & (v > 0) & (a > 0) & (abs(vc - a) <= on_tol[q])
                    side = (abs(vc - on_ax[q]) <= on_tx[q]) | (abs(vc - on_ay[q]) <= on_ty[q])
                    # at a removed mixed pixel: not on a surface around it nor near its depth
                    stray = (on_mtol[q] > 0) & ~side & (abs(vc - on_mix[q]) > on_mtol[q])
                    free = (a <= 0) & ~((v > 0) & stray)
                    valid = inside & (v > 0) & (free | own_k | side)
                    n_own[q] += 1 if own_k else 0
                    # not inside, or valid but not trusted by the reference's anchor: abstains
                    vote = inside & (free | valid)
                    rk[q] = (vc if v > 0 else v) if vote else nan
                    sk[q] = vc if valid else inf
                    total[q] += vc if valid else 0.0
                    n_in[q] += 1 if vote else 0
                    nv[q] += 1 if valid else 0
            _sort_columns(srt, network)
            # the common case, branch-free (SIMD): every sample valid and one surface (a span
            # of at most edge_mm): the plain median; the other pixels go through the loop below
            plain = np.empty(m_on, np.float32)
            other = np.empty(m_on, np.bool_)
            lo_row = srt[0]
            hi_row = srt[n - 1]
            mid_a = srt[(n - 1) // 2]
            mid_b = srt[n // 2]
            inv_n = np.float32(1.0 / n)
            for q in range(m_on):
                med = np.float32(0.5) * (mid_a[q] + mid_b[q]) if n % 2 == 0 else mid_b[q]
                plain[q] = total[q] * inv_n if use_mean else med
                few_own = (on_anc[q] > 0) & (n_own[q] < min_trusted)
                other[q] = (nv[q] < n) | (hi_row[q] - lo_row[q] > edge_mm) | few_own
            for q in range(m_on):
                j = on[q]
                if not other[q]:
                    out[i, j] = plain[q]
                    continue
                m = nv[q]
                if on_anc[q] > 0:
                    # the reference measured depth here: never 0; with too few trusted samples,
                    # the anchor (the reference denoised on its surface); else the estimate of
                    # the samples trusted by the anchor, or, with samples of a neighbouring
                    # surface at an edge too, the competition of the surfaces below
                    if m < min_trusted or (m == n_own[q] and n_own[q] < min_trusted):
                        out[i, j] = on_anc[q]
                        continue
                    if m == n_own[q]:
                        if use_mean:
                            out[i, j] = total[q] / m
                        else:
                            mid = m // 2
                            odd = m % 2 == 1
                            out[i, j] = (
                                srt[mid, q] if odd else 0.5 * (srt[mid - 1, q] + srt[mid, q])
                            )
                        continue
                if m == 0:
                    out[i, j] = 0.0  # no valid sample
                    continue
                one_surface = srt[m - 1, q] - srt[0, q] <= edge_mm
                mid = m // 2
                median = srt[mid, q] if m % 2 == 1 else 0.5 * (srt[mid - 1, q] + srt[mid, q])
                if use_mean and one_surface:
                    median = total[q] / m  # the mean of the (all) valid samples
                if m == n_in[q] and one_surface:
                    # the common case: every in-frame sample valid, one surface: the plain median
                    out[i, j] = median
                    continue
                # some samples invalid, or samples from several surfaces: the vote weights
                # matter (and are only computed) here, from the distance (px) of the registered
                # position to the centre of the low-res pixel sampled there
                w_in = 0.0
                w_valid = 0.0
                for k in range(n):
                    v = raw[k, q]
                    vals[k] = inf
                    wts[k] = 0.0
                    if v != v:
                        continue
                    qx = on_jd[q] + dx[k, q]
                    qy = fi + dy[k, q]
                    ex = abs(qx - centre_of[int(qx + 0.5)])
                    ey = abs(qy - centre_of[int(qy + 0.5)])
                    gx_k = table[min(int(ex * step + 0.5), last)]
                    gy_k = table[min(int(ey * step + 0.5), last)]
                    wk = floor + (1.0 - floor) * gx_k * gy_k
                    w_in += wk
                    if v > 0:
                        w_valid += wk
                        vals[k] = v
                        wts[k] = wk
                r = raw[ref, q]
                ref_value = r if (r == r and r > 0) else 0.0
                if one_surface:
                    # what _fuse_pixel gives on one surface, without sorting again
                    few = _too_few_valid(w_valid, w_in, ref_value, min_valid_fraction)
                    out[i, j] = 0.0 if few else median
                    continue
                out[i, j] = _fuse_pixel(
                    vals,
                    wts,
                    m,
                    w_in,
                    w_valid,
                    ref_value,
                    guide[i, j],
                    guide_bonus,
                    min_valid_fraction,
                    edge_mm,
                    network,
                    use_mean,
                )
            # near a depth edge: the surface of the bilinear votes (edges.vote_surface), where
            # some frame's samples around the position reach beyond the surface gap (a cheaper
            # test with the same outcome first, edges.votes_may_move: most band pixels stop there)
            band_row = band[li]
            for q in range(m_on):
                if not band_row[on_low[q]]:
                    continue
                j = on[q]
                for k in range(n):
                    pxq[k] = on_jd[q] + dx[k, q]
                    pyq[k] = fi + dy[k, q]
                if votes_may_move(
                    cell_lo, cell_hi, offsets[:, li, on_low[q]], raw[:, q], pxq, pyq,
                    scale, edge_mm, out[i, j],
                ):  # fmt: skip
                    out[i, j] = vote_surface(
                        lowres, offsets[:, li, on_low[q]], raw[:, q], pxq, pyq, scale,
                        edge_mm, on_floor[q], out[i, j], vals_4, wts_4,
                    )  # fmt: skip


def temporal_median(
    stack: npt.ArrayLike,
    ref: int | None = None,
    *,
    weights: npt.ArrayLike | None = None,
    guide: npt.ArrayLike | None = None,
    guide_bonus: float = 0.35,
    min_valid_fraction: float = 0.5,
    edge_mm: float = 100.0,
) -> np.ndarray:
    """Invalid-aware pixel-wise temporal median of registered frames (eq. 28).

    Parameters
    ----------
    stack : array_like, (N, H, W)
        Registered frames y_t^{t0}↑ in mm: > 0 valid, 0 = no return, NaN = outside the frame.
    ref : int, optional
        Index of the reference frame in the stack (tie-breaks); default the middle one.
    weights : array_like (N, H, W), optional
        Vote weight of each sample (default 1). They decide whether a pixel is valid (weighted
        share of valid samples) and, where the samples come from several surfaces (spread >
        ``edge_mm``), which surface the pixel belongs to; the depth itself is always the plain
        median of the samples of that surface.
    guide : array_like (H, W), optional
        Where > 0 and the samples come from several surfaces, the surface holding this depth
        gets ``guide_bonus`` × the total valid weight added to its vote (see
        :func:`splat_nearest`).
    guide_bonus : float
        Weight of the guide, as a share of the total valid vote weight.
    min_valid_fraction : float
        A pixel is valid if the share of valid samples among in-frame samples is larger than
        this (equal: valid if the reference sample is).
    edge_mm : float
        Samples further apart than this (mm, a gap in their sorted order) belong to different
        surfaces; only the winning surface's samples form the median.

    Returns
    -------
    ndarray float32 (H, W): the fused depth, 0 where nothing is known.
    """
    arr = _registered_stack(stack)
    n = arr.shape[0]
    ref = check_ref(ref, n)
    try:
        wts = (
            np.ones(arr.shape, np.float32)
            if weights is None
            else np.ascontiguousarray(np.broadcast_to(np.asarray(weights, np.float32), arr.shape))
        )
    except (ValueError, TypeError):
        raise InputError(
            f"weights must broadcast to the stack's shape {arr.shape}, got {np.shape(weights)}"
        ) from None
    gd = np.zeros(arr.shape[1:], np.float32) if guide is None else np.asarray(guide, np.float32)
    if gd.shape != arr.shape[1:]:
        raise InputError(f"guide must be one frame {arr.shape[1:]}, got shape {gd.shape}")
    gd = np.ascontiguousarray(np.nan_to_num(gd, nan=0.0))
    out = np.empty(arr.shape[1:], np.float32)
    _median_kernel(
        arr,
        wts,
        gd,
        float(guide_bonus),
        ref,
        float(min_valid_fraction),
        float(edge_mm),
        _network(n),
        out,
    )
    return out


def _registered_stack(stack: npt.ArrayLike) -> np.ndarray:
    """``stack`` as float32 (N, H, W), checked: numeric, finite or NaN (outside the frame),
    no negative depth (:class:`~upsr.errors.InputError` otherwise)."""
    arr = np.asarray(stack)
    if arr.dtype == object or not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
        raise InputError(f"stack must be a numeric array of depth, got dtype {arr.dtype}")
    arr = np.ascontiguousarray(arr, dtype=np.float32)
    if arr.ndim != 3 or arr.size == 0:
        raise InputError(f"stack must be a non-empty (N, H, W) array, got shape {arr.shape}")
    if np.isinf(arr).any():
        raise InputError("stack contains ±inf (use 0 for no return, NaN for outside the frame)")
    if (arr < 0).any():
        raise InputError(f"stack contains negative depth (min {float(np.nanmin(arr)):g} mm)")
    return arr


def register_and_fuse(
    lowres: npt.ArrayLike,
    maps: npt.ArrayLike,
    scale: int,
    ref: int | None = None,
    *,
    weight_sigma_px: float | None = None,
    weight_floor: float = 0.25,
    guide: npt.ArrayLike | None = None,
    guide_bonus: float = 0.35,
    min_valid_fraction: float = 0.5,
    edge_mm: float = 100.0,
    measured_only: bool = True,
    anchor: npt.ArrayLike | None = None,
    tolerance: npt.ArrayLike | None = None,
    offsets: npt.ArrayLike | None = None,
    min_trusted: int = 1,
    estimator: str = "median",
    untrusted: npt.ArrayLike | None = None,
    hole_floors: bool = False,
    edge_votes: bool = False,
    mixes_mm: npt.ArrayLike | None = None,
    followed: npt.ArrayLike | None = None,
    border_strips: bool = False,
) -> np.ndarray:
    """Registration (eq. 20) and invalid-aware median fusion (eq. 28) in one compiled pass.

    With a flow grid of the output size (s = r) this equals
    ``temporal_median(stack, ref, weights=w, ...)`` with ``stack[k] =
    warp_nearest(upsample_nearest(lowres[k], r), maps[k])`` and ``w = floor + (1 − floor)·
    exp(−d²/(2σ²))``, d from :func:`upsr.method.registration.sample_offsets` (the Gaussian is
    tabulated every 1/64 px), without building those (N, r·h, r·w) stacks: each output pixel
    reads its N samples straight from the low-res frames, with vote weights only where they
    matter (samples invalid, or from several surfaces). A coarser flow grid (s < r) is
    interpolated bilinearly (pixel centres aligned, like ``cv2.resize``).

    Parameters
    ----------
    lowres : array_like (N, h, w)
        Low-res frames of the window (mm; 0 or NaN = no return).
    maps : array_like (N, s·h, s·w, 2)
        Motion from the reference to each frame on the flow grid (flow px).
    scale : int
        SR factor r.
    ref : int, optional
        Index of the reference frame (default the middle one).
    weight_sigma_px, weight_floor : float or None, float
        σ of the vote weights (high-res px; ``None``: equal votes) and the smallest weight.
    guide, guide_bonus, min_valid_fraction, edge_mm
        As in :func:`temporal_median`.
    measured_only : bool
        Output 0 wherever no frame of the window measured the low-res pixel the output pixel
        belongs to (never invent depth where the camera saw nothing, whatever the motion).
    anchor, tolerance : array_like (h, w), optional
        Trust (beyond the paper, :func:`upsr.method.trust.reference_anchor`): where
        ``anchor`` > 0 (the reference measured depth), a sample is trusted only if it lies
        within ``tolerance`` of it; untrusted samples vote neither on the depth nor on whether
        there is depth, and the output is never 0 there: the estimate of the trusted samples,
        or the anchor itself with fewer than ``min_trusted`` of them. Where ``anchor`` is 0
        the rules above apply. ``None``: no trust test (eq. 28 as before).
    offsets : array_like (N, h, w), optional
        Depth offset (mm) subtracted from frame k's samples that land on reference low-res
        pixel (i, j), before the trust test and the fusion (radial motion,
        :func:`upsr.method.trust.radial_offsets`). ``None``: none.
    min_trusted : int
        Fewest trusted samples whose estimate replaces the anchor.
    estimator : {"median", "mean"}
        Estimate of the samples of the winning surface: their median (eq. 28, ML for Laplace
        noise) or their mean (ML for Gaussian noise; between quantisation steps).
    untrusted : array_like bool (N, h, w), optional
        Frame k misregistered around reference pixel (i, j) (:mod:`upsr.method.consistency`):
        its samples there abstain like samples outside the frame. ``None``: none.
    hole_floors : bool
        Where the reference has no depth, samples over ``edge_mm`` nearer than the farthest
        depth around it (:func:`upsr.method.consistency.hole_backgrounds`) abstain.
    edge_votes : bool
        Near the reference's depth edges (:func:`upsr.method.edges.edge_band`), each pixel's
        surface from the bilinear votes of the four samples around every frame's registered
        position (:func:`upsr.method.edges.vote_surface`: sub-pixel edges).
    mixes_mm, followed, border_strips : array_like (h, w) or None, bool (h, w) or None, bool
        The reference's removed mixed pixels' depth (0 elsewhere), thin parts followed
        (:func:`~upsr.method.consistency.thin_parts_followed`, frames in ``untrusted``), strips
        at the border as thin parts: :func:`~upsr.method.alternatives.surface_alternatives`.

    Returns
    -------
    ndarray float32 (r·h, r·w): fused depth (mm), 0 where nothing is known.
    """
    lr = nan_as_zero(np.ascontiguousarray(lowres, np.float32))
    mp = np.ascontiguousarray(maps, np.float32)
    n, h, w = lr.shape
    ref = check_ref(ref, n)
    if estimator not in ("median", "mean"):
        raise InputError(f"estimator must be 'median' or 'mean', not {estimator!r}")
    hh, ww = h * scale, w * scale
    (cols, fx), (rows, fy), ratio = interpolation_tables((hh, ww), mp.shape[1:3])
    gd = np.zeros((hh, ww), np.float32) if guide is None else np.asarray(guide, np.float32)
    measured = (lr > 0).any(axis=0) if measured_only else np.ones((h, w), np.bool_)
    geometry = (lr, mp, int(scale), ratio, cols, fx, rows, fy)
    votes = (*weight_table(scale, weight_sigma_px), float(weight_floor))
    rules = (np.ascontiguousarray(gd), float(guide_bonus), ref, float(min_valid_fraction))
    rules += (float(edge_mm), measured, _network(n))
    trust = (anchor, tolerance, offsets, untrusted, lr, edge_mm)
    trust += (ref if hole_floors else None, mixes_mm, followed, border_strips)
    anc, tol, offs, alts, bad, nearest, mixes, mtol = fusion_inputs(*trust)
    # the reference's map is zero and none of its samples abstains: a shortcut
    still = ref if not (mp[ref].any() or bad[ref].any()) else -1
    band = edge_band(lr[ref], edge_mm) if edge_votes else np.zeros((h, w), np.bool_)
    cell_lo, cell_hi = cell_ranges(lr) if band.any() else (np.zeros((n, 1, 1), np.float32),) * 2
    out = np.empty((hh, ww), np.float32)
    _register_fuse_kernel(
        *geometry, *votes, *rules, still, anc, tol, offs, *alts, bad, nearest, mixes, mtol,
        max(int(min_trusted), 1), estimator == "mean", band, cell_lo, cell_hi, out,
    )  # fmt: skip
    return out
