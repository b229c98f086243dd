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

import numba as nb
import numpy as np
import numpy.typing as npt
from scipy import ndimage

from upsr.method.sorting import _heaviest_run

__all__ = ["SURFACE_GAP", "edge_band", "vote_surface"]

#: :func:`vote_surface` moves a pixel to the winning surface only if the fusion's value lies
#: more than this many ``edge_mm`` from it: a floor at a grazing angle steps by about the edge
#: threshold per pixel, and its bilinear neighbours are no two surfaces (realistic room,
#: Laplace σ = 0, seed 0: surface rmse 9.97 → 10.30 mm with 1, unchanged with 2; the
#: occlusion edges of the scenes step by 300 mm and more).
SURFACE_GAP = 2.0


def edge_band(reference: npt.ArrayLike, edge_mm: float) -> np.ndarray:
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

    Returns
    -------
    ndarray bool (h, w)
    """
    z = np.nan_to_num(np.asarray(reference, np.float32), nan=0.0)
    valid = z > 0
    z = np.where(valid, z, np.float32(0.0))
    far = np.float32(np.finfo(np.float32).max)
    hi = ndimage.maximum_filter(z, size=3, mode="nearest")
    lo = ndimage.minimum_filter(np.where(valid, z, far), size=3, mode="nearest")
    return (hi > 0) & (hi - lo > edge_mm)


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
    surface wins."""
    if not (fused > 0):
        return fused  # never depth where the fusion left none
    n, h, w = lowres.shape
    inv_r = 1.0 / scale
    inf = np.float32(np.inf)
    gap = SURFACE_GAP * edge_mm
    m = 0
    far = False  # some depth sample more than the gap from the fusion's value
    for k in range(n):
        if raw[k] != raw[k]:
            continue
        u = (py[k] + 0.5) * inv_r - 0.5
        v = (px[k] + 0.5) * inv_r - 0.5
        i0 = int(np.floor(u))
        j0 = int(np.floor(v))
        fy = u - i0
        fx = v - j0
        for di in range(2):
            ii = min(max(i0 + di, 0), h - 1)
            wy = fy if di == 1 else 1.0 - fy
            for dj in range(2):
                jj = min(max(j0 + dj, 0), w - 1)
                wt = wy * (fx if dj == 1 else 1.0 - fx)
                z = lowres[k, ii, jj]
                if wt <= 0.0 or z < 0:
                    continue
                val = z - offsets[k] if z > 0 else inf
                if val < floor:
                    continue
                far |= (z > 0) & (abs(val - fused) > gap)
                vals[m] = val
                wts[m] = wt
                m += 1
    if not far:
        # every depth sample within the gap of the fusion's value: so is the winning
        # surface, or "no depth" wins; either way the fusion's value stays (most pixels of
        # the band, which only the few beside an edge leave)
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
