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

import cv2
import numba as nb
import numpy as np
import numpy.typing as npt

__all__ = [
    "OPEN_MM",
    "alternatives_on_grid",
    "mix_depths",
    "mix_tolerance",
    "side_of_centre",
    "surface_alternatives",
    "thin_fronts",
]


@nb.njit(cache=True, nogil=True, inline="always")
def _run(anchor, i, j, di, dj, a0, edge, reach, border=True):  # pragma: no cover - numba
    """How many pixels beyond (i, j) in direction (di, dj), up to ``reach``, lie on a0's
    surface (with ``border``, the image border counts as the surface going on)."""
    h, w = anchor.shape
    for s in range(1, reach + 1):
        a = i + s * di
        b = j + s * dj
        if a < 0 or a >= h or b < 0 or b >= w:
            return reach if border else s - 1
        u = anchor[a, b]
        if not (u > 0 and abs(u - a0) <= edge):
            return s - 1
    return reach


@nb.njit(cache=True, nogil=True, inline="always")
def _inside(anchor, i, j):  # pragma: no cover - numba
    h, w = anchor.shape
    return 0 <= i < h and 0 <= j < w


@nb.njit(cache=True, nogil=True, inline="always")
def _deep(anchor, i, j, di, dj, edge):  # pragma: no cover - numba
    """Whether (i, j) and (i + di, j + dj) lie inside the image, on one surface."""
    if not (_inside(anchor, i, j) and _inside(anchor, i + di, j + dj)):
        return False
    u = anchor[i, j]
    v = anchor[i + di, j + dj]
    return u > 0 and v > 0 and abs(u - v) <= edge


@nb.njit(cache=True, nogil=True, inline="always")
def _thin(anchor, i, j, a0, edge, strips):  # pragma: no cover - numba
    """Whether a0's surface at (i, j) is at most 2 px wide across x, y or a diagonal (a
    neck seen at 45°). The image border counts as the surface going on, except with
    ``strips`` across x or y where the surface on the other side is 2 px deep: then the
    strip in front of it at the border (the top of a box entering the view) is thin, not a
    grazing floor's last row."""
    thin = False
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        lo = _run(anchor, i, j, -di, -dj, a0, edge, 2, False)
        hi = _run(anchor, i, j, di, dj, a0, edge, 2, False)
        lo_out = lo < 2 and not _inside(anchor, i - (lo + 1) * di, j - (lo + 1) * dj)
        hi_out = hi < 2 and not _inside(anchor, i + (hi + 1) * di, j + (hi + 1) * dj)
        # a run that ends at the border goes on there, unless the surface beyond its other
        # end is 2 px deep (looked at only where the run ends at the border)
        axis = strips and (di == 0 or dj == 0)
        lo_end, hi_end = lo, hi
        if lo_out and not (
            axis and _deep(anchor, i + (hi + 1) * di, j + (hi + 1) * dj, di, dj, edge)
        ):
            lo_end = 2
        if hi_out and not (
            axis and _deep(anchor, i - (lo + 1) * di, j - (lo + 1) * dj, -di, -dj, edge)
        ):
            hi_end = 2
        thin = thin or lo_end + 1 + hi_end < 3
    return thin


@nb.njit(cache=True, nogil=True, inline="always")
def _apart(anchor, tol, i, j, a, b, edge):  # pragma: no cover - numba
    """Whether (a, b) lies on another surface than (i, j), beyond the tolerances of both."""
    d = abs(anchor[a, b] - anchor[i, j])
    return anchor[a, b] > 0 and d > edge and d > tol[i, j] + tol[a, b]


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


#: Half-width (mm) of the "any depth beyond the mix" interval of :func:`surface_alternatives`.
OPEN_MM = 5e5


@nb.njit(cache=True, nogil=True, inline="always")
def _mix_surfaces(anchor, tol, edge, m0, i, j, lo, tlo, hi, thi):  # pragma: no cover - numba
    """The surfaces around the removed mixed pixel (i, j) of depth m0 (see
    :func:`surface_alternatives`), on every side of its centre."""
    h, w = anchor.shape
    best_lo = np.inf
    best_hi = -np.inf
    c_lo = t_lo = c_hi = t_hi = 0.0
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            u = anchor[a, b]
            if not u > 0:
                continue
            # the neighbour's surface continued one pixel towards (i, j): its slope from the
            # pixel beyond it, when that one lies on its surface
            e = u
            a2 = 2 * a - i
            b2 = 2 * b - j
            if 0 <= a2 < h and 0 <= b2 < w:
                u2 = anchor[a2, b2]
                if u2 > 0 and abs(u2 - u) <= edge:
                    e = 2 * u - u2
            if u < best_lo:
                best_lo = u
                c_lo = 0.5 * (u + e)
                t_lo = 0.5 * abs(u - e) + tol[a, b]
            if u > best_hi:
                best_hi = u
                c_hi = 0.5 * (u + e)
                t_hi = 0.5 * abs(u - e) + tol[a, b]
    if best_hi < best_lo:
        return  # no anchored neighbour: no candidates
    if best_hi - best_lo <= edge:
        # one surface known: the other lies beyond the mix's depth, away from it
        if best_hi < m0:
            c_hi = m0 + OPEN_MM
            t_hi = OPEN_MM
        elif best_lo > m0:
            c_lo = m0 - OPEN_MM
            t_lo = OPEN_MM
    lo[:, :, i, j] = c_lo
    tlo[:, :, i, j] = t_lo
    hi[:, :, i, j] = c_hi
    thi[:, :, i, j] = t_hi


@nb.njit(cache=True, nogil=True)
def _alternatives_kernel(
    anchor, tol, edge, mixes, followed, strips, lo, tlo, hi, thi
):  # pragma: no cover - numba
    h, w = anchor.shape
    lo[:] = 0.0
    tlo[:] = 0.0
    hi[:] = 0.0
    thi[:] = 0.0
    for i in range(h):
        for j in range(w):
            a0 = anchor[i, j]
            if mixes[i, j] > 0 and not a0 > 0:
                _mix_surfaces(anchor, tol, edge, mixes[i, j], i, j, lo, tlo, hi, thi)
                continue
            if not a0 > 0:
                continue
            # a thin part (its surface at most 2 px wide across x, y or a diagonal: a neck
            # seen at 45°) keeps its own samples against a surface beyond the tolerances of
            # both; within them, and every neighbour off its surface on one side of it (a
            # ridge, a speck: noise outliers side by side, not a floor at a grazing angle),
            # the samples of that surface compete; and so do all, where the motion followed
            # the part (``followed``: the frames that did not follow it abstain there)
            thin = _thin(anchor, i, j, a0, edge, strips)
            if thin and _two_sided(anchor, i, j, a0, edge):
                continue
            thin = thin and not followed[i, j]
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
                            if thin and _apart(anchor, tol, i, j, a, b, edge):
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
    anchor: npt.ArrayLike,
    tolerance: npt.ArrayLike,
    edge_mm: float,
    mixes_mm: npt.ArrayLike | None = None,
    followed: npt.ArrayLike | None = None,
    *,
    border_strips: bool = False,
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
    samples compete. A small part far in front of the wall still keeps its own, unless the
    motion followed it (``followed``: :func:`thin_fronts`,
    :func:`upsr.method.consistency.thin_parts_followed`): then the frames that did not follow
    it abstain there and the surface behind competes in the others, which puts the part's
    edges at sub-pixel positions instead of filling its r×r blocks.

    A mixed pixel of the reference that was removed (``mixes_mm``: its anchor is 0, so its
    samples are not checked against its own surface) lies between surfaces around it: there
    the nearest and the farthest anchored 8-neighbour, each continued one pixel towards it
    (its slope from the pixel beyond it, when that one lies within ``edge_mm``: the interval
    between the two plus its tolerance), on every side of the centre; with one surface
    known, the other is any depth beyond the mix's own, away from it (an interval
    :data:`OPEN_MM` wide). The fusion then takes no sample there that lies on neither side
    nor near the mix's own depth (:func:`mix_tolerance`): a sample of a third surface the
    flow misregistered (the ToF room: a box 800 mm from the wall and the box top whose mixes
    it was, at their corner) gave flying pixels.

    Parameters
    ----------
    anchor, tolerance : array_like (h, w)
        From :func:`reference_anchor`.
    edge_mm : float
        Depth step that separates two surfaces.
    mixes_mm : array_like (h, w), optional
        The reference's measurement at its removed mixed pixels (mm), 0 elsewhere.
    followed : array_like bool (h, w), optional
        The thin parts in front that the motion followed (see above); None: none.
    border_strips : bool
        A surface that runs into the image border is thin where it is at most 2 px wide
        inside the image across x or y, in front of a surface 2 px deep (the top of a box
        entering the view); else the border counts as the surface going on. On for
        point-sampling sensors (a sensor that mixes has its mixes there, which
        :mod:`upsr.method.mixed` splits).

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
    mixes = mix_depths(mixes_mm, anc.shape)
    fol = np.zeros(anc.shape, np.bool_)
    if followed is not None:
        fol = np.ascontiguousarray(followed, np.bool_).reshape(anc.shape)
    _alternatives_kernel(anc, tol, float(edge_mm), mixes, fol, bool(border_strips), *outs)
    return outs[0], outs[1], outs[2], outs[3]


@nb.njit(cache=True, nogil=True)
def _fronts_kernel(anchor, tol, edge, strips, out):  # pragma: no cover - numba
    h, w = anchor.shape
    for i in range(h):
        for j in range(w):
            a0 = anchor[i, j]
            out[i, j] = False
            thin = a0 > 0 and _thin(anchor, i, j, a0, edge, strips)
            if not thin or _two_sided(anchor, i, j, a0, edge):
                continue
            for a in range(max(i - 1, 0), min(i + 2, h)):
                for b in range(max(j - 1, 0), min(j + 2, w)):
                    out[i, j] = out[i, j] or _apart(anchor, tol, i, j, a, b, edge)


def thin_fronts(
    anchor: npt.ArrayLike,
    tolerance: npt.ArrayLike,
    edge_mm: float,
    *,
    border_strips: bool = False,
) -> np.ndarray:
    """The reference pixels of thin parts that stand apart from a surface beside them (a leg,
    an arm, a bar in front of a wall): those that :func:`surface_alternatives` lets keep their
    own samples against that surface unless the motion followed them.

    The part's surface is at most 2 px wide across x, y or a diagonal; it does not lie between
    a nearer and a farther surface (a floor at a grazing angle); an 8-neighbour off it lies
    beyond the tolerances of both (not noise outliers side by side).

    Parameters
    ----------
    anchor, tolerance : array_like (h, w)
        From :func:`upsr.method.trust.reference_anchor` (anchor 0: no depth).
    edge_mm : float
        Depth step that separates two surfaces.
    border_strips : bool
        As in :func:`surface_alternatives`.

    Returns
    -------
    ndarray bool (h, w)
    """
    anc = np.ascontiguousarray(anchor, np.float32)
    anc = np.where(np.isfinite(anc), anc, np.float32(0.0))
    tol = np.ascontiguousarray(tolerance, np.float32).reshape(anc.shape)
    out = np.empty(anc.shape, np.bool_)
    _fronts_kernel(anc, tol, float(edge_mm), bool(border_strips), out)
    return out


def mix_depths(mixes_mm: npt.ArrayLike | None, shape: tuple[int, ...]) -> np.ndarray:
    """``mixes_mm`` of :func:`surface_alternatives` as its kernels read it: float32 of
    ``shape``, 0 (no removed mix) where it is None, NaN or infinite."""
    if mixes_mm is None:
        return np.zeros(shape, np.float32)
    m = np.ascontiguousarray(mixes_mm, np.float32).reshape(shape)
    return np.where(np.isfinite(m), m, np.float32(0.0))


def mix_tolerance(
    anchor: npt.ArrayLike, tolerance: npt.ArrayLike, mixes_mm: npt.ArrayLike | None
) -> np.ndarray:
    """How far from a removed mixed pixel's own measurement (``mixes_mm``, see
    :func:`surface_alternatives`) a sample may lie and still be taken there (a surface the
    mixed-pixel test took for a mix: a strip seen at a grazing angle): the largest tolerance
    of its anchored 8-neighbours; 0 elsewhere and where none is anchored (no rule there).

    Returns
    -------
    ndarray float32 (h, w)
    """
    anc = np.ascontiguousarray(anchor, np.float32)
    mixes = mix_depths(mixes_mm, anc.shape)
    if not (mixes > 0).any():
        return np.zeros(anc.shape, np.float32)  # (every window of a sensor that does not mix)
    anchored = np.where(anc > 0, np.asarray(tolerance, np.float32), np.float32(0.0))
    largest = cv2.dilate(anchored, np.ones((3, 3), np.uint8))  # (outside: no neighbour)
    return np.where((mixes > 0) & ~(anc > 0), largest, np.float32(0.0)).astype(np.float32)


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
