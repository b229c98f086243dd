"""Per-frame and per-pixel quantities that decide which registered samples the fusion trusts.

Beyond the paper. The temporal median of eq. 28 lets every registered sample vote, also the
ones the motion did not carry along (a thin fast leg: the other frames' samples there show the
wall behind it and vote it away), the ones that see another depth because the surface moved
along the viewing ray, and the mixed ("flying") pixels of ToF sensors. This module computes,
on the low-res grid:

* :func:`remove_mixed_pixels`: input pixels whose depth lies between two surfaces around them
  (more than the edge threshold from both their nearest and their farthest neighbour) are set
  to 0 = no measurement in every frame, before anything is fused;
* :func:`reference_anchor`: per reference pixel, an edge-aware robust estimate of its own depth
  (the median of its 3×3 neighbours on its surface) and the tolerance τ = k·σ + the local
  relief of that surface, against which each registered sample is trusted or not;
* :func:`radial_offsets`: per frame of the window, the depth offset of the frame registered to
  the reference (motion along the viewing ray), a masked median over a neighbourhood of one
  surface, subtracted from that frame's samples before trust and fusion;
* :func:`noise_shape`: the excess kurtosis and the std of the temporal differences of static
  pixels, which choose the estimator (median for heavy tails, mean of the trusted samples for
  Gaussian or quantised noise);
* :func:`fill_holes`: optional filling of pixels without depth from the background side.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import numpy.typing as npt

__all__ = [
    "TOLERANCE_FLOOR_MM",
    "choose_estimator",
    "fill_holes",
    "noise_shape",
    "radial_offsets",
    "reference_anchor",
    "remove_mixed_pixels",
    "surface_alternatives",
    "surface_support",
    "trust_arrays",
]

#: Smallest trust tolerance (mm): noiseless or coarsely quantised data still trust their own
#: surface's samples.
TOLERANCE_FLOOR_MM = 2.0

#: Excess kurtosis of the temporal differences above which the noise is heavy-tailed and the
#: median is kept (difference of two Laplace samples: 1.5; of two Gaussian ones: 0; of two
#: quantisation errors: −0.6).
KURTOSIS_MEDIAN = 0.75


@nb.njit(cache=True, nogil=True, inline="always")
def _median_inplace(buf, m):  # pragma: no cover - numba
    """Median of buf[:m], sorted in place (insertion sort: m is at most 25)."""
    for p in range(1, m):
        x = buf[p]
        q = p - 1
        while q >= 0 and buf[q] > x:
            buf[q + 1] = buf[q]
            q -= 1
        buf[q + 1] = x
    return buf[m // 2] if m % 2 == 1 else 0.5 * (buf[m // 2 - 1] + buf[m // 2])


@nb.njit(cache=True, nogil=True)
def _mixed_kernel(z, edge, out):  # pragma: no cover - numba
    h, w = z.shape
    for i in range(h):
        for j in range(w):
            v = z[i, j]
            out[i, j] = v
            if not v > 0:
                continue
            lo = np.inf
            hi = -np.inf
            same = 0
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    a = i + di
                    b = j + dj
                    if (di == 0 and dj == 0) or a < 0 or a >= h or b < 0 or b >= w:
                        continue
                    u = z[a, b]
                    if u > 0:
                        lo = min(lo, u)
                        hi = max(hi, u)
                        same += 1 if abs(u - v) <= edge else 0
            # between two surfaces, and on none of its own (at most a line of such pixels),
            # unless it continues a steep slope (a floor seen at a grazing angle)
            if v - lo > edge and hi - v > edge and same <= 2 and not _on_slope(z, i, j):
                out[i, j] = 0.0


@nb.njit(cache=True, nogil=True, inline="always")
def _steps_agree(s, t):  # pragma: no cover - numba
    """Two consecutive depth steps of one slope: same sign, within a factor of 3."""
    if s == 0.0 or t == 0.0 or (s > 0) != (t > 0):
        return False
    a, b = abs(s), abs(t)
    return max(a, b) <= 3.0 * min(a, b)


@nb.njit(cache=True, nogil=True)
def _on_slope(z, i, j):  # pragma: no cover - numba
    """True when, along a row, column or diagonal, the pixel (i, j) and its two neighbours on
    each side step through depth evenly (a slanted surface, whose steps between neighbours can
    exceed the edge threshold); a mixed pixel sits between two flat runs instead."""
    h, w = z.shape
    v = z[i, j]
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        ia, ja, ib, jb = i - di, j - dj, i + di, j + dj
        if min(ia, ib) < 0 or max(ia, ib) >= h or min(ja, jb) < 0 or max(ja, jb) >= w:
            continue
        a, b = z[ia, ja], z[ib, jb]
        if not (a > 0 and b > 0) or not _steps_agree(v - a, b - v):
            continue
        outer = 0  # the steps beyond the two neighbours (those inside the frame) must agree
        ok = True
        ic, jc, ie, je = i - 2 * di, j - 2 * dj, i + 2 * di, j + 2 * dj
        if 0 <= ic < h and 0 <= jc < w and z[ic, jc] > 0:
            outer += 1
            ok = ok and _steps_agree(a - z[ic, jc], v - a)
        if 0 <= ie < h and 0 <= je < w and z[ie, je] > 0:
            outer += 1
            ok = ok and _steps_agree(b - v, z[ie, je] - b)
        if outer > 0 and ok:
            return True
    return False


def remove_mixed_pixels(frames: npt.ArrayLike, edge_mm: float) -> np.ndarray:
    """Set the mixed ("flying") pixels of each frame to 0 = no measurement.

    A pixel is mixed when its depth lies more than ``edge_mm`` behind its nearest valid
    8-neighbour and more than ``edge_mm`` in front of its farthest one, and at most 2 of its
    8-neighbours lie within ``edge_mm`` of it (a mixed pixel belongs to no surface; a line of
    them along an edge still counts; a genuine surface between two others does not). A ToF
    pixel whose footprint straddles a depth edge returns a depth between the two surfaces,
    which belongs to neither. The other frames of the window fill it (their samples there are
    not mixed).

    Parameters
    ----------
    frames : array_like (..., h, w)
        Depth (mm), 0 or NaN = no measurement.
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    ndarray float32, same shape: the frames with mixed pixels set to 0 (NaN become 0).
    """
    z = np.asarray(frames, np.float32)
    z = np.where(np.isnan(z), np.float32(0.0), z)
    flat = z.reshape(-1, *z.shape[-2:])
    out = np.empty_like(flat)
    for k in range(flat.shape[0]):
        _mixed_kernel(np.ascontiguousarray(flat[k]), float(edge_mm), out[k])
    return out.reshape(z.shape)


@nb.njit(cache=True, nogil=True)
def _anchor_kernel(z, edge, sigma, k, floor, anchor, tol):  # pragma: no cover - numba
    h, w = z.shape
    buf = np.empty(9, np.float32)
    for i in range(h):
        for j in range(w):
            v = z[i, j]
            anchor[i, j] = 0.0
            if not v > 0:
                continue
            m = 0
            for a in range(max(i - 1, 0), min(i + 2, h)):
                for b in range(max(j - 1, 0), min(j + 2, w)):
                    u = z[a, b]
                    if u > 0 and abs(u - v) <= edge:
                        buf[m] = u
                        m += 1
            anchor[i, j] = _median_inplace(buf, m)
    for i in range(h):
        for j in range(w):
            a0 = anchor[i, j]
            tol[i, j] = 0.0
            if not a0 > 0:
                continue
            relief = 0.0
            for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                a = i + di
                b = j + dj
                if 0 <= a < h and 0 <= b < w:
                    u = anchor[a, b]
                    if u > 0 and abs(u - a0) <= edge:
                        relief = max(relief, abs(u - a0))
            tol[i, j] = max(k * sigma + relief, floor)


def reference_anchor(
    reference: npt.ArrayLike, sigma_mm: float, k: float, edge_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """The reference's own depth, robustly, and how far a trusted sample may lie from it.

    Parameters
    ----------
    reference : array_like (h, w)
        The reference low-res frame (mm, 0 = no measurement).
    sigma_mm : float
        Noise std of the video (mm).
    k : float
        Tolerance in units of the noise std.
    edge_mm : float
        Depth step that separates two surfaces: only the neighbours within it of a pixel take
        part in its anchor and relief (never across a depth edge).

    Returns
    -------
    anchor : ndarray float32 (h, w)
        Median of the pixel's 3×3 neighbours (itself included) within ``edge_mm`` of it; 0
        where the reference has no depth.
    tolerance : ndarray float32 (h, w)
        τ = k·σ + the largest difference to the anchor of a 4-neighbour on the same surface
        (the relief of a slanted surface over one low-res pixel), at least
        :data:`TOLERANCE_FLOOR_MM`; 0 where the reference has no depth.
    """
    z = np.ascontiguousarray(reference, np.float32)
    z = np.where(np.isnan(z), np.float32(0.0), z)
    anchor = np.empty(z.shape, np.float32)
    tol = np.empty(z.shape, np.float32)
    _anchor_kernel(z, float(edge_mm), float(sigma_mm), float(k), TOLERANCE_FLOOR_MM, anchor, tol)
    return anchor, tol


@nb.njit(cache=True, nogil=True, inline="always")
def _run(anchor, i, j, di, dj, a0, edge, reach):  # pragma: no cover - numba
    """How many pixels beyond (i, j) in direction (di, dj), up to ``reach``, lie on a0's
    surface (the image border counts as the surface going on)."""
    h, w = anchor.shape
    for s in range(1, reach + 1):
        a = i + s * di
        b = j + s * dj
        if a < 0 or a >= h or b < 0 or b >= w:
            return reach
        u = anchor[a, b]
        if not (u > 0 and abs(u - a0) <= edge):
            return s - 1
    return reach


@nb.njit(cache=True, nogil=True)
def _alternatives_kernel(anchor, tol, edge, lo, tlo, hi, thi):  # pragma: no cover - numba
    h, w = anchor.shape
    for i in range(h):
        for j in range(w):
            lo[i, j] = 0.0
            tlo[i, j] = 0.0
            hi[i, j] = 0.0
            thi[i, j] = 0.0
            a0 = anchor[i, j]
            if not a0 > 0:
                continue
            # a thin part (its surface at most 2 px wide across x or y) keeps its own samples
            wx = 1 + _run(anchor, i, j, 0, -1, a0, edge, 2) + _run(anchor, i, j, 0, 1, a0, edge, 2)
            wy = 1 + _run(anchor, i, j, -1, 0, a0, edge, 2) + _run(anchor, i, j, 1, 0, a0, edge, 2)
            if wx < 3 or wy < 3:
                continue
            best_lo = np.inf
            best_hi = -np.inf
            for a in range(max(i - 1, 0), min(i + 2, h)):
                for b in range(max(j - 1, 0), min(j + 2, w)):
                    u = anchor[a, b]
                    if not (u > 0 and abs(u - a0) > edge):
                        continue
                    if u < best_lo:
                        best_lo = u
                        lo[i, j] = u
                        tlo[i, j] = tol[a, b]
                    if u > best_hi:
                        best_hi = u
                        hi[i, j] = u
                        thi[i, j] = tol[a, b]


def surface_alternatives(
    anchor: npt.ArrayLike, tolerance: npt.ArrayLike, edge_mm: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The other surfaces next to each reference pixel at a depth edge, whose samples compete.

    At a depth edge of the reference the true edge lies somewhere inside the pixel's r×r
    block: the samples of the neighbouring surface are trusted too (within its own tolerance)
    and the surfaces compete in the fusion (vote weights, forward-splat guide), so the edge
    lands at a sub-pixel position. Not for thin parts: a pixel whose surface is at most 2
    low-res px wide across x or y keeps only its own samples (a thin fast leg the flow did
    not follow is not voted away by the wall behind it).

    Parameters
    ----------
    anchor, tolerance : array_like (h, w)
        From :func:`reference_anchor`.
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    near, near_tol, far, far_tol : ndarray float32 (h, w)
        The nearest and the farthest anchor among the 3×3 neighbours that lie more than
        ``edge_mm`` from the pixel's own, and their tolerances; 0 where there is none (no
        edge, a thin part, no depth in the reference).
    """
    anc = np.ascontiguousarray(anchor, np.float32)
    tol = np.ascontiguousarray(tolerance, np.float32)
    outs = [np.empty(anc.shape, np.float32) for _ in range(4)]
    _alternatives_kernel(anc, tol, float(edge_mm), *outs)
    return outs[0], outs[1], outs[2], outs[3]


@nb.njit(cache=True, nogil=True)
def _registered_kernel(lowres, maps, scale, ratio, out):  # pragma: no cover - numba
    """out[k, i, j]: frame k's low-res sample at reference pixel (i, j)'s centre, moved by the
    map (nearest flow-grid node); 0 outside or no depth."""
    n, h, w = lowres.shape
    gh = maps.shape[1]
    gw = maps.shape[2]
    s_y = gh / h
    s_x = gw / w
    hh = h * scale
    ww = w * scale
    for k in range(n):
        for i in range(h):
            yg = min(max(int((i + 0.5) * s_y), 0), gh - 1)
            cy = (i + 0.5) * scale - 0.5
            for j in range(w):
                xg = min(max(int((j + 0.5) * s_x), 0), gw - 1)
                cx = (j + 0.5) * scale - 0.5
                qx = cx + maps[k, yg, xg, 0] * ratio
                qy = cy + maps[k, yg, xg, 1] * ratio
                out[k, i, j] = 0.0
                if -0.5 <= qx < ww - 0.5 and -0.5 <= qy < hh - 0.5:
                    xl = int((qx + 0.5) / scale)
                    yl = int((qy + 0.5) / scale)
                    out[k, i, j] = lowres[k, yl, xl]


@nb.njit(cache=True, nogil=True, inline="always")
def _offset_at(reg, ref, k, i, j, edge, sigma, radius, buf):  # pragma: no cover - numba
    """The significant median of frame k's registered differences around (i, j), or 0."""
    h, w = ref.shape
    c = ref[i, j]
    m = 0
    for a in range(max(i - radius, 0), min(i + radius + 1, h)):
        for b in range(max(j - radius, 0), min(j + radius + 1, w)):
            u = ref[a, b]
            v = reg[k, a, b]
            if not (u > 0 and v > 0):
                continue
            if c > 0 and abs(u - c) > edge:
                continue  # another surface than the pixel's
            d = v - u
            if abs(d) <= edge:
                buf[m] = d
                m += 1
    if m < 5:
        return 0.0
    med = _median_inplace(buf, m)
    # significant only: beyond 4 standard errors of the median of m differences of two
    # noisy samples (a static scene stays unchanged)
    se = 1.2533 * math.sqrt(2.0) * sigma / math.sqrt(m)
    return med if abs(med) > 4.0 * se else 0.0


@nb.njit(cache=True, nogil=True)
def _offset_kernel(reg, ref, ref_index, edge, sigma, radius, out):  # pragma: no cover - numba
    n, h, w = reg.shape
    buf = np.empty((2 * radius + 1) ** 2, np.float32)
    for k in range(n):
        if k == ref_index:
            out[k] = 0.0
            continue
        # on every second pixel of each axis (the offsets are smooth); a pixel takes the
        # value of its grid pixel when that one lies on its surface, else its own
        for i in range(0, h, 2):
            for j in range(0, w, 2):
                out[k, i, j] = _offset_at(reg, ref, k, i, j, edge, sigma, radius, buf)
        for i in range(h):
            for j in range(w):
                gi = i - i % 2
                gj = j - j % 2
                if gi == i and gj == j:
                    continue
                c = ref[i, j]
                g = ref[gi, gj]
                if c > 0 and g > 0 and abs(c - g) <= edge:
                    out[k, i, j] = out[k, gi, gj]
                else:
                    out[k, i, j] = _offset_at(reg, ref, k, i, j, edge, sigma, radius, buf)


def radial_offsets(
    lowres: npt.ArrayLike,
    maps: npt.ArrayLike,
    scale: int,
    ref: int,
    *,
    sigma_mm: float,
    edge_mm: float,
    radius_px: int = 2,
) -> np.ndarray:
    """Depth offset of each frame registered to the reference (motion along the viewing ray).

    Frame k's sample at each reference pixel's centre (moved by its map) minus the reference
    there, where both have depth and differ by at most ``edge_mm``; the median of those
    differences over the (2·radius+1)² low-res neighbours on the pixel's surface. Kept only
    where it exceeds 4 standard errors of that median, from at least 5 differences (noise
    alone never shifts a frame).

    Parameters
    ----------
    lowres : array_like (N, h, w)
        The low-res frames of the window (mm, 0 = no depth).
    maps : array_like (N, s·h, s·w, 2)
        Motion from the reference to each frame on the flow grid (flow px).
    scale : int
        SR factor r.
    ref : int
        Index of the reference frame.
    sigma_mm : float
        Noise std (mm).
    edge_mm : float
        Depth step that separates two surfaces.
    radius_px : int
        Half-size of the neighbourhood (low-res px).

    Returns
    -------
    ndarray float32 (N, h, w): the offset (mm) to subtract from frame k's samples that land on
    reference pixel (i, j); 0 for the reference.
    """
    lr = np.ascontiguousarray(lowres, np.float32)
    lr = np.where(np.isnan(lr), np.float32(0.0), lr)
    mp = np.ascontiguousarray(maps, np.float32)
    n, h, w = lr.shape
    ratio = scale * w / mp.shape[2]
    reg = np.empty((n, h, w), np.float32)
    _registered_kernel(lr, mp, int(scale), float(ratio), reg)
    out = np.empty((n, h, w), np.float32)
    _offset_kernel(reg, lr[ref], int(ref), float(edge_mm), float(sigma_mm), int(radius_px), out)
    return out


def noise_shape(frames: npt.ArrayLike, edge_mm: float) -> tuple[float, float]:
    """Excess kurtosis and std (mm, per sample) of the temporal noise of static pixels.

    From the differences of consecutive frames where both have depth and the difference is
    within 8 robust stds (static pixels; moving edges left out). Std per sample = std of the
    differences / √2.

    Returns
    -------
    (kurtosis, std_mm); (nan, 0) with fewer than 50 differences.
    """
    z = np.asarray(frames, np.float32)
    z = np.where(np.isnan(z), np.float32(0.0), z)
    if z.shape[0] < 2:
        return math.nan, 0.0
    a, b = z[1:], z[:-1]
    d = (a - b)[(a > 0) & (b > 0)].astype(np.float64)
    d = d[np.abs(d) <= edge_mm]
    if d.size < 50:
        return math.nan, 0.0
    d = d - np.median(d)
    scale = 1.4826 * np.median(np.abs(d))
    if scale <= 0:
        scale = float(d.std())
    d = d[np.abs(d) <= 8.0 * scale] if scale > 0 else d
    var = float(d.var())
    if d.size < 50 or var <= 0:
        return math.nan, math.sqrt(max(var, 0.0) / 2.0)
    kurt = float(np.mean((d - d.mean()) ** 4) / var**2 - 3.0)
    return kurt, math.sqrt(var / 2.0)


def choose_estimator(kurtosis: float) -> str:
    """``"median"`` for heavy-tailed noise (or unknown), else ``"mean"`` of trusted samples."""
    if not math.isfinite(kurtosis) or kurtosis > KURTOSIS_MEDIAN:
        return "median"
    return "mean"


@nb.njit(cache=True, nogil=True)
def _fill_kernel(z, radius, out):  # pragma: no cover - numba
    h, w = z.shape
    for i in range(h):
        for j in range(w):
            out[i, j] = z[i, j]
            if z[i, j] > 0:
                continue
            best = 0.0
            for a in range(max(i - radius, 0), min(i + radius + 1, h)):
                for b in range(max(j - radius, 0), min(j + radius + 1, w)):
                    u = z[a, b]
                    if u > 0 and u > best:
                        best = u
            out[i, j] = best


def fill_holes(depth: npt.ArrayLike, radius_px: int, iterations: int = 8) -> np.ndarray:
    """Fill pixels without depth from the farther (background) side of their valid neighbours.

    INVENTED depth, as the hole filling of depth SDKs: each pass gives every pixel without
    depth the largest (farthest) depth within ``radius_px`` of it; ``iterations`` passes.
    Background-side filling never grows a foreground object into its shadow.
    """
    z = np.ascontiguousarray(depth, np.float32)
    z = np.where(np.isnan(z), np.float32(0.0), z)
    for _ in range(int(iterations)):
        if (z > 0).all() or not (z > 0).any():
            break
        out = np.empty_like(z)
        _fill_kernel(z, int(radius_px), out)
        z = out
    return z


def trust_arrays(
    anchor: npt.ArrayLike | None,
    tolerance: npt.ArrayLike | None,
    offsets: npt.ArrayLike | None,
    shape: tuple[int, int, int],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The anchor, tolerance (h, w) and offsets (N, h, w) as the fusion kernel reads them:
    float32, contiguous; zeros (no trust test, no offset) for those not given."""
    n, h, w = shape
    if (anchor is None) != (tolerance is None):
        raise ValueError("anchor and tolerance go together")
    if anchor is None:
        anc = np.zeros((h, w), np.float32)
        tol = np.zeros((h, w), np.float32)
    else:
        anc = np.ascontiguousarray(anchor, np.float32).reshape(h, w)
        anc = np.where(np.isfinite(anc), anc, np.float32(0.0))
        tol = np.ascontiguousarray(tolerance, np.float32).reshape(h, w)
    if offsets is None:
        offs = np.zeros((n, h, w), np.float32)
    else:
        offs = np.ascontiguousarray(offsets, np.float32).reshape(n, h, w)
    return anc, tol, offs


def surface_support(reference: npt.ArrayLike, edge_mm: float) -> np.ndarray:
    """Pixels of the reference with depth and at least one 8-neighbour within ``edge_mm``:
    part of a surface the camera saw (a thin part one pixel wide included), not a lone
    pixel. Their output is kept by the speckle filter (the fusion never erases what the
    reference measured on a surface)."""
    z = np.asarray(reference, np.float32)
    z = np.where(np.isnan(z), np.float32(0.0), z)
    h, w = z.shape
    pad = np.zeros((h + 2, w + 2), np.float32)
    pad[1:-1, 1:-1] = z
    found = np.zeros((h, w), np.bool_)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                u = pad[1 + di : 1 + di + h, 1 + dj : 1 + dj + w]
                found |= (u > 0) & (np.abs(u - z) <= edge_mm)
    return found & (z > 0)
