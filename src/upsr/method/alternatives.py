"""The other surfaces a registered sample may show at a depth edge of the reference (beyond the
paper).

At a depth edge the reference pixel's own surface is not the only one whose samples belong in
its block: the true edge lies somewhere between its centre and the centre of a neighbour on
the other surface. :func:`surface_alternatives` gives, per reference pixel and side of its
centre, the nearest and farthest other surface (with their tolerances) whose samples the
fusion trusts there too (:func:`upsr.method.fusion.register_and_fuse`), so that the surfaces
compete and the edge lands at a sub-pixel position; :func:`alternatives_on_grid` reads them
per high-res pixel.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import numpy.typing as npt

__all__ = ["alternatives_on_grid", "side_of_centre", "surface_alternatives"]


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


@nb.njit(cache=True, nogil=True, inline="always")
def _two_sided(anchor, i, j, a0, edge):  # pragma: no cover - numba
    """Whether (i, j) has 8-neighbours off its surface (beyond ``edge`` of ``a0``) both
    nearer and farther than it."""
    h, w = anchor.shape
    near = False
    far = False
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            u = anchor[a, b]
            if u > 0 and abs(u - a0) > edge:
                near |= u < a0
                far |= u > a0
    return near and far


@nb.njit(cache=True, nogil=True)
def _alternatives_kernel(anchor, tol, edge, lo, tlo, hi, thi):  # pragma: no cover - numba
    h, w = anchor.shape
    lo[:] = 0.0
    tlo[:] = 0.0
    hi[:] = 0.0
    thi[:] = 0.0
    for i in range(h):
        for j in range(w):
            a0 = anchor[i, j]
            if not a0 > 0:
                continue
            # a thin part (its surface at most 2 px wide across x, y or a diagonal: a neck
            # seen at 45°) keeps its own samples against a surface beyond the tolerances of
            # both; within them, and every neighbour off its surface on one side of it (a
            # ridge, a speck: noise outliers side by side, not a floor at a grazing angle),
            # the samples of that surface compete
            thin = False
            for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
                wd = _run(anchor, i, j, -di, -dj, a0, edge, 2)
                wd += 1 + _run(anchor, i, j, di, dj, a0, edge, 2)
                thin = thin or wd < 3
            if thin and _two_sided(anchor, i, j, a0, edge):
                continue
            # per side (sy, sx) of the pixel's centre: the neighbours on that side only
            for qy in range(3):
                for qx in range(3):
                    best_lo = np.inf
                    best_hi = -np.inf
                    for a in (i, i + qy - 1):
                        for b in (j, j + qx - 1):
                            if (a == i and b == j) or not (0 <= a < h and 0 <= b < w):
                                continue
                            u = anchor[a, b]
                            if not (u > 0 and abs(u - a0) > edge):
                                continue
                            if thin and abs(u - a0) > tol[i, j] + tol[a, b]:
                                continue
                            if u < best_lo:
                                best_lo = u
                                lo[qy, qx, i, j] = u
                                tlo[qy, qx, i, j] = tol[a, b]
                            if u > best_hi:
                                best_hi = u
                                hi[qy, qx, i, j] = u
                                thi[qy, qx, i, j] = tol[a, b]


def surface_alternatives(
    anchor: npt.ArrayLike, tolerance: npt.ArrayLike, edge_mm: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The other surfaces next to each reference pixel at a depth edge, whose samples compete.

    At a depth edge of the reference the true edge lies somewhere between the pixel's centre
    (where the reference measured its own surface) and the centre of a neighbour on the
    other surface: for the high-res pixels on that neighbour's side of the centre, the
    samples of the neighbour's surface are trusted too (within its own tolerance) and the
    surfaces compete in the fusion (vote weights, forward-splat guide), so the edge lands at
    a sub-pixel position. Never on the far side of the centre (a surface that only reaches
    one side of the pixel cannot cover the other), and not for thin parts: a pixel whose
    surface is at most 2 low-res px wide across x, y or a diagonal keeps only its own
    samples (a thin fast leg the flow did not follow is not voted away by the wall behind it),
    except against a neighbour whose anchor lies within the two tolerances added up, when
    every neighbour off the part's surface lies on one side of it (a ridge or a speck, not a
    floor at a grazing angle, steeper per pixel than the edge threshold): noise outliers side
    by side (Samba, Laplacian σ = 50 mm: two pixels 3.5σ nearer than the surface, each the
    other's surface) kept their blocks against every other frame; now that surface's
    samples compete. A small part far in front of the wall still keeps its own.

    Parameters
    ----------
    anchor, tolerance : array_like (h, w)
        From :func:`reference_anchor`.
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    near, near_tol, far, far_tol : ndarray float32 (3, 3, h, w)
        Index ``[sy + 1, sx + 1, i, j]``, sy, sx ∈ {−1, 0, 1} the side of the pixel's centre
        (the sign of a high-res pixel's offset from it, :func:`side_of_centre`): the nearest
        and the farthest anchor that lies more than ``edge_mm`` from the pixel's own among the
        neighbours (i + a, j + b), a ∈ {0, sy}, b ∈ {0, sx}, and their tolerances; 0 where
        there is none (no edge on that side, a thin part, no depth in the reference; always
        at the centre itself).
    """
    anc = np.ascontiguousarray(anchor, np.float32)
    tol = np.ascontiguousarray(tolerance, np.float32)
    outs = [np.empty((3, 3, *anc.shape), np.float32) for _ in range(4)]
    _alternatives_kernel(anc, tol, float(edge_mm), *outs)
    return outs[0], outs[1], outs[2], outs[3]


def side_of_centre(n_px: int, scale: int) -> np.ndarray:
    """For each of ``n_px`` high-res indices along an axis, the side (−1, 0 or 1) of the
    centre of its low-res pixel ((x // r + 0.5)·r − 0.5) it lies on: 0 only at the centre
    itself (odd r). Index 1 + side into :func:`surface_alternatives`."""
    x = np.arange(int(n_px))
    return np.sign(x - ((x // scale + 0.5) * scale - 0.5)).astype(np.int64)


def alternatives_on_grid(alternatives: tuple[np.ndarray, ...], scale: int) -> list[np.ndarray]:
    """:func:`surface_alternatives` per high-res pixel: each (3, 3, h, w) array read at the
    pixel's low-res pixel and side, as (r·h, r·w) arrays."""
    _, _, h, w = alternatives[0].shape
    sy = side_of_centre(h * scale, scale)[:, None] + 1
    sx = side_of_centre(w * scale, scale)[None, :] + 1
    iy = (np.arange(h * scale) // scale)[:, None]
    ix = (np.arange(w * scale) // scale)[None, :]
    return [a[sy, sx, iy, ix] for a in alternatives]
