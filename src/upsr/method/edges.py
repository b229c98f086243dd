"""Sub-pixel depth edges: which surface a pixel near a depth edge belongs to (beyond the paper).

The fusion (eq. 20, 28) reads one sample per frame at each pixel: the low-res pixel nearest
to its registered position. Near a depth edge that is nearest-neighbour upsampling of each
frame, so its edges run along the r×r block grid of the frames (a staircase); the median of
N such samples moves them only where the frames' grids fall differently across the edge.

Here every frame that votes at a pixel gives the four low-res samples around the registered
position, with their bilinear weights; the samples are grouped into surfaces (gaps beyond
``edge_mm``; "no depth" is a surface of its own) and the surface with the largest weight
wins. In one frame this is the contour of the bilinear interpolation of each surface's
indicator at one half, which cuts the corners of the staircase the way a straight or curved
edge does; over the N frames of a window the weights of N registered grids add up. Depth is
never interpolated: the pixel takes the weighted median of the winning surface's samples,
and only when the fusion's own value lies on another surface, more than
:data:`SURFACE_GAP` edge thresholds away (a pixel the fusion left without depth keeps none;
one it gave depth is never emptied).

Measured (``benchmarks/realistic_eval.py --quick --no-oracle``, seeds 0–2): see the README's
depth rules.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr._numba import SAFE_FASTMATH
from upsr.method.slopes import edge_ends
from upsr.method.sorting import _heaviest_run

__all__ = [
    "REVERT_MIN_SHARE",
    "SURFACE_GAP",
    "VOTE_FRAMES",
    "cell_ranges",
    "edge_band",
    "state_votes",
    "vote_surface",
    "votes_may_move",
]

#: :func:`vote_surface` moves a pixel to the winning surface only if the fusion's value lies
#: more than this many ``edge_mm`` from it: a floor at a grazing angle steps by about the edge
#: threshold per pixel, and its bilinear neighbours are no two surfaces (realistic room,
#: Laplace σ = 0, seed 0: surface rmse 9.97 → 10.30 mm with 1, unchanged with 2; the
#: occlusion edges of the scenes step by 300 mm and more).
SURFACE_GAP = 2.0


def edge_band(reference: npt.ArrayLike, edge_mm: float, *, slopes: bool = False) -> np.ndarray:
    """The low-res pixels where :func:`vote_surface` may change the fusion's decision.

    The pixels whose 3×3 neighbourhood in the reference spans a depth edge (depths more than
    ``edge_mm`` apart): the four samples around a pixel's position in the reference lie in
    it (and in another frame, where the registration holds, on the same scene edge; adding
    their 8-neighbours changed the realistic scenes' rmse by at most 1 % and cost 3 ms more
    per ToF frame, the band then covering 46 % of the pixels instead of 21 %). Not the edges
    between depth and no depth alone: the votes never add nor remove depth, so with one
    surface they change nothing.

    Parameters
    ----------
    reference : array_like (h, w)
        The reference frame (mm; ≤ 0 or NaN: no depth).
    edge_mm : float
        Depth step that separates two surfaces.
    slopes : bool
        Leave out the pixels whose span comes from a steep slope or a face seen obliquely
        only (within one pixel of no end of a depth edge: :func:`upsr.method.slopes.edge_ends`).

    Returns
    -------
    ndarray bool (h, w)
    """
    z = np.ascontiguousarray(reference, np.float32)
    ends = edge_ends(z, edge_mm) if slopes else np.zeros((0, 0), np.bool_)
    band = np.empty(z.shape, np.bool_)
    _band_kernel(z, float(edge_mm), ends, bool(slopes), band)
    return band


@nb.njit(cache=True, nogil=True, inline="always")
def _band_at(z, i, j, edge, ends, use_ends):  # pragma: no cover - numba
    """:func:`_band_kernel`'s test at one pixel (the 3×3 clipped at the border)."""
    h, w = z.shape
    hi = 0.0
    lo = np.inf
    near_end = not use_ends
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            v = z[a, b]
            if v > 0:  # (False for NaN and removed samples)
                hi = max(hi, v)
                lo = min(lo, v)
            if use_ends and ends[a, b]:
                near_end = True
    return hi > 0 and hi - lo > edge and near_end


@nb.njit(cache=True, nogil=True, inline="always")
def _valid_max(hi, v):  # pragma: no cover - numba
    """max(hi, v) where v > 0, else hi (hi ≥ 0), without a branch."""
    return max(hi, v if v > 0 else np.float32(0.0))


@nb.njit(cache=True, nogil=True, inline="always")
def _valid_min(lo, v):  # pragma: no cover - numba
    """min(lo, v) where v > 0, else lo, without a branch."""
    return min(lo, v if v > 0 else np.float32(np.inf))


@nb.njit(cache=True, nogil=True, parallel=True)
def _band_kernel(z, edge, ends, use_ends, out):  # pragma: no cover - numba
    """out[i, j]: the valid depths of the 3×3 neighbourhood of (i, j) (clipped at the border)
    span more than ``edge``, and (with ``use_ends``) one of its pixels is in ``ends``. The
    interior of a row: branch-free passes over shifted row slices (SIMD)."""
    h, w = z.shape
    for i in nb.prange(h):
        if i == 0 or i == h - 1 or w < 3:
            for j in range(w):
                out[i, j] = _band_at(z, i, j, edge, ends, use_ends)
            continue
        out[i, 0] = _band_at(z, i, 0, edge, ends, use_ends)
        out[i, w - 1] = _band_at(z, i, w - 1, edge, ends, use_ends)
        n = w - 2
        u0, u1, u2 = z[i - 1, 0:n], z[i - 1, 1 : n + 1], z[i - 1, 2 : n + 2]
        m0, m1, m2 = z[i, 0:n], z[i, 1 : n + 1], z[i, 2 : n + 2]
        d0, d1, d2 = z[i + 1, 0:n], z[i + 1, 1 : n + 1], z[i + 1, 2 : n + 2]
        o = out[i, 1 : n + 1]
        for j in range(n):
            hi = _valid_max(_valid_max(_valid_max(0.0, u0[j]), u1[j]), u2[j])
            hi = _valid_max(_valid_max(_valid_max(hi, m0[j]), m1[j]), m2[j])
            hi = _valid_max(_valid_max(_valid_max(hi, d0[j]), d1[j]), d2[j])
            lo = _valid_min(_valid_min(_valid_min(np.inf, u0[j]), u1[j]), u2[j])
            lo = _valid_min(_valid_min(_valid_min(lo, m0[j]), m1[j]), m2[j])
            lo = _valid_min(_valid_min(_valid_min(lo, d0[j]), d1[j]), d2[j])
            o[j] = (hi > 0) & (hi - lo > edge)
        if use_ends:
            e0, e1, e2 = ends[i - 1, 0:n], ends[i - 1, 1 : n + 1], ends[i - 1, 2 : n + 2]
            f0, f1, f2 = ends[i, 0:n], ends[i, 1 : n + 1], ends[i, 2 : n + 2]
            g0, g1, g2 = ends[i + 1, 0:n], ends[i + 1, 1 : n + 1], ends[i + 1, 2 : n + 2]
            for j in range(n):
                near = e0[j] | e1[j] | e2[j] | f0[j] | f1[j] | f2[j] | g0[j] | g1[j] | g2[j]
                o[j] &= near


@nb.njit(cache=True, nogil=True, inline="always")
def _cell(u, t):  # pragma: no cover - numba
    """The cell of the low-res position (u, t) (row, column; pixel centres at integers): the
    indices of the sample above and left of it and the fractions towards the next row and
    column, for :func:`_corner` (once per position, not once per corner: the edge votes
    visit 4N corners per pixel)."""
    i0 = int(np.floor(u))
    j0 = int(np.floor(t))
    return i0, j0, u - i0, t - j0


@nb.njit(cache=True, nogil=True, inline="always")
def _corner(i0, j0, fy, fx, h, w, c):  # pragma: no cover - numba
    """The c-th (0–3) of the four low-res samples around the cell (i0, j0, fy, fx) of
    :func:`_cell`: its indices, clamped to the frame, and its bilinear weight."""
    di = c >> 1
    dj = c & 1
    wy = fy if di == 1 else 1.0 - fy
    return (
        min(max(i0 + di, 0), h - 1),
        min(max(j0 + dj, 0), w - 1),
        wy * (fx if dj == 1 else 1.0 - fx),
    )


@nb.njit(cache=True, nogil=True, parallel=True)
def _cell_ranges_kernel(lowres, lo, hi):  # pragma: no cover - numba
    n, h, w = lowres.shape
    for kc in nb.prange(n * (h + 1)):
        k = kc // (h + 1)
        c = kc % (h + 1)
        for d in range(w + 1):
            a = np.float32(np.inf)
            b = np.float32(-np.inf)
            for ii in (min(max(c - 1, 0), h - 1), min(c, h - 1)):
                for jj in (min(max(d - 1, 0), w - 1), min(d, w - 1)):
                    z = lowres[k, ii, jj]
                    if z > 0:
                        a = min(a, z)
                        b = max(b, z)
            lo[k, c, d] = a
            hi[k, c, d] = b


def cell_ranges(lowres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The nearest and farthest depth (> 0) among the four low-res samples of each cell of
    :func:`vote_surface` (the cell whose top-left sample is (i0, j0), −1 ≤ i0 < h,
    −1 ≤ j0 < w, clamped to the frame as its corners are), at [k, i0 + 1, j0 + 1]; +inf /
    −inf where none has depth. For :func:`votes_may_move`.

    Parameters
    ----------
    lowres : ndarray float32 (N, h, w)

    Returns
    -------
    lo, hi : ndarray float32 (N, h + 1, w + 1)
    """
    n, h, w = lowres.shape
    lo = np.empty((n, h + 1, w + 1), np.float32)
    hi = np.empty((n, h + 1, w + 1), np.float32)
    _cell_ranges_kernel(lowres, lo, hi)
    return lo, hi


@nb.njit(cache=True, nogil=True, inline="always")
def votes_may_move(cell_lo, cell_hi, offsets, raw, px, py, scale, edge_mm, fused):
    # pragma: no cover - numba
    """False when :func:`vote_surface` keeps ``fused`` for certain: no frame that votes has,
    among the four samples around its position, a depth (less its offset) more than
    :data:`SURFACE_GAP` edge thresholds from it (``cell_lo``, ``cell_hi`` of
    :func:`cell_ranges`; a cheaper test than the votes' own, with the same outcome)."""
    if not (fused > 0):
        return False
    inv_r = 1.0 / scale
    gap = SURFACE_GAP * edge_mm
    for k in range(raw.shape[0]):
        if raw[k] != raw[k]:
            continue
        i0, j0, _, _ = _cell((py[k] + 0.5) * inv_r - 0.5, (px[k] + 0.5) * inv_r - 0.5)
        off = offsets[k]
        # (val − fused as vote_surface computes it, for the nearest and the farthest val:
        # float32 subtraction is monotonic, so no other sample of the cell lies further out)
        if (cell_lo[k, i0 + 1, j0 + 1] - off) - fused < -gap:
            return True
        if (cell_hi[k, i0 + 1, j0 + 1] - off) - fused > gap:
            return True
    return False


@nb.njit(cache=True, nogil=True, inline="always")
def vote_surface(lowres, offsets, raw, px, py, scale, edge_mm, floor, fused, vals, wts):
    # pragma: no cover - numba
    """The depth of one output pixel from the bilinear votes of its frames (see the module).

    ``lowres`` (N, h, w) the window's frames (< 0: a removed sample, which abstains);
    ``offsets`` (N,) each frame's radial offset at the pixel; ``raw`` (N,) the fusion's
    sample of each frame (NaN: the frame abstains at this pixel); ``px``, ``py`` (N,) where
    each frame's sample lies (output px); ``floor`` the nearest depth a sample may have (a
    hole of the reference beside an edge; −inf: none); ``fused`` the fusion's value;
    ``vals``, ``wts`` scratch of 4N. Returns ``fused`` unless it has depth and another
    surface wins. Most pixels are decided without sorting their samples: where those within
    half the edge threshold of ``fused`` outweigh all those beyond the gap on either side,
    no surface that would move the pixel can win (the same outcome; the fused kernel's
    time on the dense ToF room 9.2 → 6.4 ms per window)."""
    if not (fused > 0):
        return fused  # never depth where the fusion left none
    n, h, w = lowres.shape
    inv_r = 1.0 / scale
    inf = np.float32(np.inf)
    gap = SURFACE_GAP * edge_mm
    m = 0
    far = False  # some depth sample more than the gap from the fusion's value
    # the weight of the samples beyond the gap above and below the fusion's value, and of
    # those within half the edge threshold of it (one surface: no gap between them)
    w_above = 0.0
    w_below = 0.0
    w_near = 0.0
    half_edge = 0.45 * edge_mm
    for k in range(n):
        if raw[k] != raw[k]:
            continue
        i0, j0, fy, fx = _cell((py[k] + 0.5) * inv_r - 0.5, (px[k] + 0.5) * inv_r - 0.5)
        off = offsets[k]
        for c in range(4):
            ii, jj, wt = _corner(i0, j0, fy, fx, h, w, c)
            if wt <= 0.0:
                continue
            z = lowres[k, ii, jj]
            if z < 0:
                continue
            val = z - off if z > 0 else inf
            if val < floor:
                continue
            far |= (z > 0) & (abs(val - fused) > gap)
            vals[m] = val
            wts[m] = wt
            m += 1
            if z > 0:  # (the tests of the winning surface below, on this sample alone)
                w_above += wt if val - gap > fused else 0.0
                w_below += wt if val + gap < fused else 0.0
                w_near += wt if abs(val - fused) <= half_edge else 0.0
    if not far:
        # every depth sample within the gap of the fusion's value: so is the winning
        # surface, or "no depth" wins; either way the fusion's value stays (most pixels of
        # the band, which only the few beside an edge leave)
        return fused
    if w_near > 1.0001 * max(w_above, w_below):
        # a surface that moves the pixel lies wholly beyond the gap on one side, so it weighs
        # at most w_above or w_below; the surface holding the samples near the fusion's value
        # weighs at least w_near, more: it wins over them, and the fusion's value stays (the
        # outcome of the sort below; 97–99 % of the pixels that reach it end here)
        return fused
    for p in range(1, m):  # insertion sort (stable; at most 4N samples)
        val = vals[p]
        wt = wts[p]
        q = p
        while q > 0 and vals[q - 1] > val:
            vals[q] = vals[q - 1]
            wts[q] = wts[q - 1]
            q -= 1
        vals[q] = val
        wts[q] = wt
    # the surfaces (runs of the sorted samples without a gap beyond edge_mm; "no depth",
    # +inf, a run of its own) and their weights
    b_lo, b_hi, best = _heaviest_run(vals, wts, m, edge_mm, 0.0, 0.0, np.nan)
    if vals[b_lo] == inf:
        return fused  # never a hole where the fusion had depth
    if vals[b_lo] - gap <= fused <= vals[b_hi - 1] + gap:
        return fused  # on the winning surface, or on a slope beside it
    half = 0.5 * best
    c = 0.0
    for p in range(b_lo, b_hi):
        c += wts[p]
        if c >= half:
            return vals[p]
    return vals[b_hi - 1]


@nb.njit(cache=True, nogil=True, inline="always", fastmath=SAFE_FASTMATH, error_model="numpy")
def _centre_agrees(depth, qx, qy, i, j, scale, off, a, tl):  # pragma: no cover - numba
    """Whether the recursive state ``depth``, looked up (nearest) at the centre pixel of
    low-res block (i, j) moved by the positions ``qx``, ``qy``, less the radial offset
    ``off``, lies within ``tl`` of ``a``: the block's surface is where the state has it (the
    state is registered there, its edges known)."""
    hh, ww = depth.shape
    yc = i * scale + scale // 2
    xc = j * scale + scale // 2
    xn = math.floor(qx[yc, xc] + 0.5)
    yn = math.floor(qy[yc, xc] + 0.5)
    if 0 <= xn < ww and 0 <= yn < hh:
        v = depth[yn, xn]
        return v > 0 and abs(v - off - a) <= tl
    return False


#: The recursive state's surface share (:func:`state_votes`) is the running mean of at most
#: this many frames' bilinear weights (realistic scenes, ToF size, Laplace σ = 0 and 10,
#: seed 0: 4 and 8 within 0.5 % of rmse of each other, 2 better on the deforming body and
#: worse on the room).
VOTE_FRAMES = 4.0
#: ... and keeps the state's surface against the update only where the frame still gives it
#: at least this share of the four samples' weight (near the frame's own contour): where the
#: flow lags behind a motion (a camera approaching a wall: the bodies grow), the state's
#: surface would otherwise outlive the frame's evidence (realistic scenes, seed 2, the
#: approaching camera: ToF rmse +5.8 % with any weight, +0.4 % with 0.4; seed 0: the gains
#: on the other scenes −2.0 … −5.7 % with 0.4, −1.6 … −4.0 % with any weight).
REVERT_MIN_SHARE = 0.4


@nb.njit(cache=True, nogil=True, parallel=True)
def _state_vote_kernel(
    out_d, out_n, prev_d, prev_n, prev_s, qxs, qys, meas, offsets, band, scale, edge_mm, share
):  # pragma: no cover - numba
    hh, ww = out_d.shape
    h, w = meas.shape
    r = scale
    gap = SURFACE_GAP * edge_mm
    inv_r = 1.0 / r
    low_of = np.arange(ww) // r  # (each column's block once: not a division per pixel)
    for y in nb.prange(hh):
        i = y // r
        for x in range(ww):
            j = low_of[x]
            v = out_d[y, x]
            if not (v > 0 and band[i, j]):
                share[y, x] = 1.0 if v > 0 else 0.0
                continue
            # the state's surface at the pixel (its nearest registered pixel, as the update)
            xn = int(np.floor(qxs[y, x] + 0.5))
            yn = int(np.floor(qys[y, x] + 0.5))
            s = 0.0
            sh = 0.0
            n = 0.0
            if 0 <= xn < ww and 0 <= yn < hh:
                s = prev_d[yn, xn] - offsets[i, j]
                sh = prev_s[yn, xn]
                n = prev_n[yn, xn]
            # the frame's four samples around the pixel, bilinear: the weights of the update's
            # surface (w_v), of the others (w_o, and the heaviest other sample) and of the
            # state's surface (w_s)
            i0, j0, fy, fx = _cell((y + 0.5) * inv_r - 0.5, (x + 0.5) * inv_r - 0.5)
            w_v = 0.0
            w_o = 0.0
            w_s = 0.0
            other = 0.0
            heaviest = -1.0
            for c in range(4):
                ii, jj, wt = _corner(i0, j0, fy, fx, h, w, c)
                z = meas[ii, jj]
                if not z > 0:
                    continue  # no depth, or a removed mixed pixel: no vote
                if abs(z - s) <= gap:
                    w_s += wt
                if abs(z - v) <= gap:
                    w_v += wt
                else:
                    w_o += wt
                    if wt > heaviest:
                        heaviest = wt
                        other = z
            total = w_v + w_o
            if total <= 0.0:
                share[y, x] = 1.0
                continue
            k = min(n + 1.0, VOTE_FRAMES)
            if s > 0 and abs(s - v) <= gap:
                # the update kept the state's surface: it leaves it for the heaviest other
                # sample once its share over the frames falls below one half
                new = sh + (w_v / total - sh) / k
                if new < 0.5 and w_o > 0.0:
                    out_d[y, x] = other
                    out_n[y, x] = 1.0
                    new = 1.0 - new
                share[y, x] = new
                continue
            new = sh + (w_s / total - sh) / k
            if s > 0 and w_s >= REVERT_MIN_SHARE * total and new >= 0.5:
                # the update left the state's surface, which the frame still sees here and
                # whose share stays the larger: kept where the state is registered (it holds
                # the block's own surface at the block's centre; a thin part that the state
                # did not follow is not overwritten)
                if _centre_agrees(prev_d, qxs, qys, i, j, r, offsets[i, j], meas[i, j], gap):
                    out_d[y, x] = s
                    out_n[y, x] = n
                    share[y, x] = new
                    continue
            share[y, x] = w_v / total


def state_votes(
    depth: np.ndarray,
    count: np.ndarray,
    previous: tuple[np.ndarray, np.ndarray, np.ndarray],
    positions: tuple[np.ndarray, np.ndarray],
    measurement: np.ndarray,
    offsets: np.ndarray,
    *,
    scale: int,
    edge_mm: float,
) -> np.ndarray:
    """The recursive counterpart of :func:`vote_surface`: sub-pixel depth edges in the state.

    A recursive state cannot gather N frames' samples at a pixel; it carries instead, per
    output pixel, the **share** of its surface: the running mean (over at most
    :data:`VOTE_FRAMES` frames) of the bilinear weight that the frame's four samples around
    the pixel give that surface (:func:`vote_surface` with one frame). Near the frame's depth
    edges (:func:`edge_band`), after the update (:func:`upsr.method.state_update.recursive_update`):

    * where the update kept the state's surface, the pixel moves to the heaviest other
      sample once the share falls below one half (never to "no depth");
    * where the update left the state's surface (the frame's nearest sample lies on another),
      the pixel keeps the state's surface while its share stays at least one half, the frame
      still gives it :data:`REVERT_MIN_SHARE` of the four samples' weight, and the state is
      registered there (it holds the block's own surface at the block's centre: a thin part
      the state did not follow is not overwritten).

    The band is that of :func:`edge_band` without the steep slopes and faces
    (``slopes=True``): a floor seen at a grazing angle steps beyond the surface gap at ToF
    size, and its samples are no two surfaces. Not used where the frames' mixed pixels are
    removed (the samples beside the edges are the removed ones).

    Depth is never interpolated (a sample's or the state's value), never added or removed.

    Parameters
    ----------
    depth, count : ndarray float32 (r·h, r·w)
        The updated state (mm, frames); changed in place.
    previous : (depth, count, share), ndarray float32 (r·h, r·w)
        The state before the update and its shares (0 where none).
    positions : (qx, qy), ndarray float32 (r·h, r·w)
        Where each output pixel lies in the previous state (output px).
    measurement : ndarray float32 (h, w)
        The frame (mm; ≤ 0: no depth or a removed mixed pixel, which does not vote).
    offsets : ndarray float32 (h, w)
        Radial offset of the state at each low-res pixel (mm, subtracted from it).
    scale : int
        SR factor r.
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    ndarray float32 (r·h, r·w): the new shares (1 off the band, 0 without depth).
    """
    share = np.empty_like(depth)
    meas = np.ascontiguousarray(measurement, np.float32)
    band = edge_band(meas, edge_mm, slopes=True)
    _state_vote_kernel(
        depth, count, *previous, *positions, meas, offsets, band, int(scale), float(edge_mm), share
    )
    return share
