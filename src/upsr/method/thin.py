"""Thin parts of a time-of-flight frame: narrower than a pixel, mixed along their length.

Beyond the paper. A time-of-flight pixel integrates its footprint. A part narrower than the
footprint (a leg, an antler, a chair leg, a cable) covers only a share α of each pixel along
it, so the camera measures α·F + (1 − α)·B all along it: a line of depths between the part
(F) and what lies behind it (B) that belongs to neither.
:func:`upsr.method.mixed.remove_mixed_pixels` finds a mixed pixel between a nearer and a
farther neighbour; along a thin part every neighbour but the background is itself mixed,
so only the pixel next to the surface the part grows out of has a nearer neighbour, and the
rest of the line reached the output as flying pixels (realistic ToF galloping animal,
windowed, seeds 0–2: 1.8 / 2.0 / 1.3 % of the pixels near edges).

This module

* finds those pixels (:func:`thin_parts`): runs of one or two pixels (a part narrower than a
  pixel covers at most two) along a row, a column or a diagonal, in front of both pixels
  that end the run by more than the edge threshold, each of which lies on a surface of its
  own (at least :data:`SURFACE_NEIGHBOURS` of its 8-neighbours within the edge threshold of
  it, or one when both ends lie within the edge threshold of each other: the wall seen on
  both sides of the part, once through the last pixel of a gap between two legs) and is
  not a mix itself (:func:`upsr.method.mixed.mixed_pixels`: a line of mixed pixels along a
  box's edge is its own neighbour), none of them on a steep slope
  (:func:`upsr.method.slopes._on_slope`: a box side seen at a grazing angle is a surface);
  the part's own depth F is that of the surface it grows out of, where it touches it
  (directly, or through one pixel that the part fills but for a sliver: as near as the
  thin pixel or nearer by less than the edge threshold, with nothing on its surface but the part),
  carried along the part (breadth first, at most :data:`REACH_PX` steps): a thin part is
  about as far as what it sticks out of; for the pixels still without F, a second round
  also takes it from the tip of a line one pixel wide that grows out of a surface (a leg
  that fills its pixels across before it runs on between two columns: the realistic ToF
  animal's flying pixels 0.30 / 0.37 / 0.43 / 0.52 / 0.33 → 0.27 / 0.09 / 0.18 / 0.24 /
  0.25 % on seeds 0–4);
* has them abstain in the fusion with the other mixed pixels
  (:func:`upsr.method.mixed.remove_mixed_pixels`): a mix of one frame never votes, nor is
  it taken for a surface that other frames' samples may join;
* splits their blocks of the output (:func:`split_thin_parts`): the footprint's mean is
  kept, α = (B − m)/(B − F) of the block's r² pixels take F, the others B, those being the
  pixels where the bilinear interpolation of the shares of F around the block (α of each
  thin pixel, 1 on F's surface, 0 elsewhere) is largest: the part runs through the block
  along its line, towards the surface it grows out of.

A gap narrower than a pixel (between two legs, between an arm and the body) is the same
seen the other way: a line of mixes of the wall behind and the parts beside it, farther
than both. Its pixels are the thin parts of the mirror image (depth top − z), across rows
and columns (:data:`GAP_AXES`): F the depth of the surface seen through the gap where the gap
opens onto it, carried along the gap; B the nearer side's. On the realistic ToF scenes, seeds
0–4 (``benchmarks/realistic_eval.py --quick --no-oracle --seed S``): the deforming body's
rmse −1.0 … −2.7 %, its flying pixels 0.08 / 0.13 → 0.08 / 0.04 % on seeds 3 / 4.

Never a depth between two surfaces, never a hole where the camera measured something. A
part without a nearer surface within reach (a cable hanging in front of a wall) is left as
measured: nothing says how deep it is.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.method.slopes import _on_slope
from upsr.method.validation import nan_as_zero

__all__ = [
    "GAP_AXES",
    "GAP_BOTTOM_STEPS",
    "REACH_PX",
    "SURFACE_NEIGHBOURS",
    "ThinParts",
    "split_thin_parts",
    "thin_parts",
]

#: A pixel lies on a surface of its own when at least this many of its 8-neighbours lie
#: within the edge threshold of it (the background seen through a gap one pixel wide between
#: two legs has 2: the gap's pixels above and below); the mixed pixels, which a line of them
#: along an edge also gives 2, are excluded by their own test. Realistic ToF galloping
#: animal, windowed, seeds 0–2 (``benchmarks/realistic_eval.py --quick --no-oracle --seed
#: S``): flying pixels 1.19 / 1.14 / 1.29 % with 4 (a background pixel in the corner between
#: a leg and the body fails it), 1.12 / 0.65 / 1.07 % with 3, 0.82 / 0.37 / 0.49 % with 2
#: and the mixed pixels excluded (rmse −3.6 … −4.8 %), 1.20 / 0.46 / 0.60 % with 2 alone
#: (the lines of mixed pixels along the room's box edges taken for runs' ends: its edge
#: accuracy −0.8 points), 0.72 / 0.37 / 0.43 % when one neighbour suffices for two ends
#: within the edge threshold of each other (rmse −0.5 … −1.1 % more; no other scene changed).
SURFACE_NEIGHBOURS = 2
#: The farthest (low-res px, 8-connected steps along the part) a thin part's depth is carried
#: from the surface it grows out of (8 gave the same realistic results: their legs and
#: antlers are shorter; a 320×240 sensor sees longer ones).
REACH_PX = 16

#: The directions across a thin part: along a row, a column and the two diagonals.
AXES = ((0, 1), (1, 0), (1, 1), (1, -1))
#: A gap narrower than a pixel is looked for across the first GAP_AXES of :data:`AXES` (rows
#: and columns): across the diagonals the mirror image also took a room's corner pixels,
#: mixes of three surfaces (floor, wall, a box), for gaps (realistic ToF room, seeds 0–4:
#: flying pixels up to +0.17 points, 0.52 % on seed 0; the deforming body gained about as
#: much).
GAP_AXES = 2
#: The bottom of a gap that the mirror image misses (:func:`_gap_bottom`) lies behind both
#: sides of the gap by more than this many edge thresholds: a slope that steps by about the
#: edge threshold per pixel (a floor or wall at a grazing angle) has no gap. Realistic ToF
#: scenes, seeds 0–3 at 64×56, σ = 10, 36 frames each: with 1, 22 of the room's pixels whose
#: footprint saw one surface were taken for gap bottoms (and 4 mixes); with 2, 6 (and none),
#: while 15 of the galloping animal's mixes still are (26 with 1), none of its pure pixels.
GAP_BOTTOM_STEPS = 2.0


@nb.njit(cache=True, nogil=True, inline="always")
def _gap_bottom(z, i, j, edge):  # pragma: no cover - numba
    """The pixel (i, j) lies more than :data:`GAP_BOTTOM_STEPS` · ``edge`` behind both of its
    neighbours along a row, column or diagonal, none of its 8-neighbours lies more than half
    of ``edge`` behind it, and a pixel two steps away lies more than ``edge`` behind it: the
    bottom of a gap narrower than a pixel between two nearer parts (two legs crossing), a mix
    of them and of the surface seen through the gap, whose depth only pixels beyond the
    parts show. :func:`upsr.method.mixed.remove_mixed_pixels` removes it where the thin
    parts' mirror image misses it (the gap opens onto nothing within reach, or its sides are
    mixes themselves): realistic ToF galloping animal, seeds 0–7, σ = 10 and σ = 20 with 1 %
    dropouts, flying pixels 0.30 → 0.15 % on average, rmse +0.4 % (windowed), +1.3 %
    (recursive); at 128×112, seeds 0–2: 2.0–2.5 → 1.4–2.0 %, rmse +3 to +4 % (a block split
    between the sides takes their depth where the truth also shows the wall)."""
    h, w = z.shape
    v = z[i, j]
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            if z[a, b] > v + 0.5 * edge:
                return False
    depth = GAP_BOTTOM_STEPS * edge
    sides = False
    for di, dj in AXES:
        ia, ja, ib, jb = i - di, j - dj, i + di, j + dj
        if min(ia, ib) < 0 or max(ia, ib) >= h or min(ja, jb) < 0 or max(ja, jb) >= w:
            continue
        p, q = z[ia, ja], z[ib, jb]
        sides = sides or (0 < p < v - depth and 0 < q < v - depth)
    if not sides:
        return False
    for a in range(max(i - 2, 0), min(i + 3, h)):
        for b in range(max(j - 2, 0), min(j + 3, w)):
            if max(abs(a - i), abs(b - j)) == 2 and z[a, b] > v + edge:
                return True
    return False


class ThinParts(NamedTuple):
    """A frame's thin parts, found once (:func:`upsr.method.mixed.remove_mixed_pixels` with
    ``return_thin_parts``) for :func:`split_thin_parts`.

    Attributes
    ----------
    near, far : ndarray float32 (..., h, w)
        F and B of each thin pixel (F < measured < B; a gap's F > measured > B), 0
        elsewhere (mm).
    axis : ndarray int64 (..., h, w)
        The index in :data:`AXES` of the run across the part.
    """

    near: np.ndarray
    far: np.ndarray
    axis: np.ndarray


@nb.njit(cache=True, nogil=True, inline="always")
def _on_surface(z, i, j, edge, support):  # pragma: no cover - numba
    """Whether (i, j) lies on a surface of its own (:data:`SURFACE_NEIGHBOURS`), counted
    once into ``support`` (−1: not yet)."""
    if support[i, j] < 0:
        h, w = z.shape
        v = z[i, j]
        n_on = 0
        for a in range(max(i - 1, 0), min(i + 2, h)):
            for b in range(max(j - 1, 0), min(j + 2, w)):
                n_on += 1 if (z[a, b] > 0 and abs(z[a, b] - v) <= edge) else 0
        support[i, j] = n_on - 1 if v > 0 else 0  # (not the pixel itself)
    return support[i, j] >= SURFACE_NEIGHBOURS


@nb.njit(cache=True, nogil=True, inline="always")
def _tip(z, near, far, i, j, edge, reach, support):  # pragma: no cover - numba
    """Whether (i, j) ends a line one pixel wide that grows out of a surface (a leg that
    fills one pixel across): exactly one of its 8-neighbours lies within the edge threshold
    of it, and so on along the line (each pixel's one other such neighbour) until, within
    ``reach`` steps, a pixel with more than two such neighbours (a surface, not a line) or
    one beside a thin pixel whose F lies within the edge threshold of it (the same leg,
    between two columns there). A cable's line of mixes in front of a wall grows out of
    neither."""
    if _on_surface(z, i, j, edge, support) or support[i, j] != 1:
        return False
    h, w = z.shape
    pi, pj = -1, -1
    for _ in range(reach):
        ni, nj = -1, -1
        v = z[i, j]
        for a in range(max(i - 1, 0), min(i + 2, h)):
            for b in range(max(j - 1, 0), min(j + 2, w)):
                if far[a, b] > 0 and near[a, b] < np.inf and abs(near[a, b] - v) <= edge:
                    return True
                if (a != i or b != j) and (a != pi or b != pj):
                    if z[a, b] > 0 and abs(z[a, b] - v) <= edge:
                        ni, nj = a, b
        if ni < 0:
            return False
        _on_surface(z, ni, nj, edge, support)
        if support[ni, nj] > 2:
            return True
        if support[ni, nj] < 2:
            return False
        pi, pj = i, j
        i, j = ni, nj
    return False


@nb.njit(cache=True, nogil=True, inline="always")
def _through_the_part(z, far, i, j, edge, support):  # pragma: no cover - numba
    """The depth of the surface the thin pixel (i, j) reaches through one neighbour that is
    mostly the part (as near as it or nearer, within the edge threshold, not thin itself: the part
    fills it but for a sliver) and has no other neighbour on its surface but thin pixels (a
    box's corner or a staircase's step one pixel tall has one): that neighbour's on-surface
    neighbour farthest away that lies more than the edge threshold in front of (i, j) and
    no farther than it; −inf when there is none."""
    h, w = z.shape
    v = z[i, j]
    f = -np.inf
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            q = z[a, b]
            if far[a, b] > 0 or not (q > 0 and q <= v and v - q <= edge):
                continue
            alone = True
            for c in range(max(a - 1, 0), min(a + 2, h)):
                for d in range(max(b - 1, 0), min(b + 2, w)):
                    u = z[c, d]
                    if (c != a or d != b) and far[c, d] == 0 and u > 0 and abs(u - q) <= edge:
                        alone = False
            if not alone:
                continue
            for c in range(max(a - 1, 0), min(a + 2, h)):
                for d in range(max(b - 1, 0), min(b + 2, w)):
                    u = z[c, d]
                    if far[c, d] > 0 or not (0 < u <= q and u < v - edge and u > f):
                        continue
                    if _on_surface(z, c, d, edge, support):
                        f = u
    return f


@nb.njit(cache=True, nogil=True)
def _thin_kernel(z, edge, reach, mixed, near, far, axis, n_axes, tips):  # pragma: no cover - numba
    # (n_axes: across the first n_axes of AXES; tips: the second round of F below)
    h, w = z.shape
    # the deepest 8-neighbour of each pixel (a separable 3×3 maximum): the start of a run
    # has both its ends over edge behind it
    across = np.empty((h, w), np.float32)
    for i in range(h):
        for j in range(w):
            across[i, j] = max(z[i, max(j - 1, 0)], z[i, j], z[i, min(j + 1, w - 1)])
    deepest = np.empty((h, w), np.float32)
    for i in range(h):
        up = across[max(i - 1, 0)]
        mid = across[i]
        down = across[min(i + 1, h - 1)]
        for j in range(w):
            deepest[i, j] = max(up[j], mid[j], down[j])
    support = np.full((h, w), -1, np.int64)  # (counted where needed: _on_surface)
    # the thin pixels: runs of one or two pixels (a part narrower than a pixel covers at most
    # two) in front of the two neighbours that end them, along a row, a column or a
    # diagonal, each end on a surface of its own and not mixed; B the nearer end (the run
    # whose nearer end is farthest)
    span = np.full((h, w), np.inf)
    for i in range(h):
        for j in range(w):
            near[i, j] = 0.0
            far[i, j] = 0.0
    for i in range(h):
        for j in range(w):
            if not (z[i, j] > 0 and deepest[i, j] - z[i, j] > edge):
                continue
            for k in range(n_axes):
                di, dj = AXES[k]
                for width in (1, 2):
                    ia, ja = i - di, j - dj
                    ib, jb = i + width * di, j + width * dj
                    if min(ia, ib) < 0 or max(ia, ib) >= h or min(ja, jb) < 0 or max(ja, jb) >= w:
                        continue
                    lo = z[ia, ja]
                    hi = z[ib, jb]
                    if not (lo - z[i, j] > edge and hi - z[i, j] > edge):
                        continue
                    if mixed[ia, ja] or mixed[ib, jb]:
                        continue
                    on_a = _on_surface(z, ia, ja, edge, support)
                    on_b = _on_surface(z, ib, jb, edge, support)
                    # (both ends on one surface behind the part: one neighbour each suffices)
                    if not (on_a and on_b) and not (
                        abs(lo - hi) <= edge and min(support[ia, ja], support[ib, jb]) >= 1
                    ):
                        continue
                    run = True
                    for s in range(width):
                        u = z[i + s * di, j + s * dj]
                        run &= u > 0 and lo - u > edge and hi - u > edge
                    for s in range(width):
                        run = run and not _on_slope(z, i + s * di, j + s * dj, edge)
                    if not run:
                        continue
                    # the shortest run across the part (a band two pixels wide along a
                    # column is also a run along a diagonal), then the farthest nearer end
                    length = width * (1.0 if di == 0 or dj == 0 else np.sqrt(2.0))
                    for s in range(width):
                        a, b = i + s * di, j + s * dj
                        if length < span[a, b] or (
                            length == span[a, b] and min(lo, hi) > far[a, b]
                        ):
                            far[a, b] = min(lo, hi)
                            span[a, b] = length
                            axis[a, b] = k
    rows = np.empty(h * w, np.int64)
    cols = np.empty(h * w, np.int64)
    n = 0
    for i in range(h):
        for j in range(w):
            if far[i, j] > 0:
                near[i, j] = np.inf
                rows[n] = i
                cols[n] = j
                n += 1
    # F: the depth of the surface the part grows out of, carried along the part from where
    # it touches it, directly or through a pixel that is mostly the part (a breadth-first
    # walk: each sweep one step, reading the last sweep's depths, so that reach counts
    # steps; a pixel keeps the first depth that reaches it, the farthest of those that
    # reach it in the same step)
    since = np.full((h, w), 2 * reach, np.int64)  # the sweep that set the pixel's depth
    steps = np.zeros((h, w), np.int64)  # and how far it was carried
    # With ``tips``, a second round for the pixels still without F: also from the tip of a
    # line one pixel wide (thin itself or not, unless mixed), the end of a leg that fills
    # its pixels across before it runs on between two columns (rows) of pixels; within the
    # same reach
    sweep = 0
    late = False
    while sweep < (2 * reach if late else reach):
        changed = False
        for k in range(n):
            i = rows[k]
            j = cols[k]
            if near[i, j] < np.inf:
                continue
            v = z[i, j]
            f = -np.inf
            fs = 0
            for a in range(max(i - 1, 0), min(i + 2, h)):
                for b in range(max(j - 1, 0), min(j + 2, w)):
                    s = 0
                    if far[a, b] > 0 and near[a, b] < np.inf:  # another part's pixel, set
                        s = steps[a, b] + 1
                        c = near[a, b] if since[a, b] < sweep and s < reach else np.inf
                    elif not z[a, b] > 0:
                        continue
                    elif far[a, b] == 0 and _on_surface(z, a, b, edge, support):
                        c = z[a, b]
                    elif late and not mixed[a, b]:
                        if not _tip(z, near, far, a, b, edge, reach, support):
                            continue
                        c = z[a, b]
                    else:
                        continue
                    if c < v - edge and c > f:
                        f = c
                        fs = s
            if f == -np.inf:
                f = _through_the_part(z, far, i, j, edge, support)
            if f > -np.inf:
                near[i, j] = f
                since[i, j] = sweep
                steps[i, j] = fs
                changed = True
        sweep += 1
        if not changed or sweep == reach:
            if late or not tips:
                break
            late = True
            sweep = reach
    for k in range(n):
        i = rows[k]
        j = cols[k]
        if near[i, j] == np.inf or not near[i, j] < far[i, j]:
            near[i, j] = 0.0
            far[i, j] = 0.0


def thin_parts(
    measured: npt.ArrayLike,
    edge_mm: float,
    *,
    reach_px: int = REACH_PX,
    mixed: npt.ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The pixels of a frame that measured a mix of a thin part and what lies behind it.

    Parameters
    ----------
    measured : array_like (h, w)
        One frame as measured (mm, 0 or NaN = no measurement).
    edge_mm : float
        Depth step that separates two surfaces.
    reach_px : int
        The farthest (8-connected steps along the part) F is carried.
    mixed : array_like of bool (h, w), optional
        The frame's mixed pixels (:func:`upsr.method.mixed.mixed_pixels`, which never end a
        run); default: found here.

    Returns
    -------
    near, far : ndarray float32 (h, w)
        F and B of each such pixel (F < measured < B), 0 elsewhere; and of the pixels of
        gaps narrower than a pixel (F > measured > B: the depth seen through the gap, and
        the nearer side's).
    """
    z = np.ascontiguousarray(nan_as_zero(measured))
    if z.ndim != 2:
        raise ValueError(f"measured must be (h, w), got shape {z.shape}")
    near, far, _ = _thin_parts(z, float(edge_mm), int(reach_px), mixed)
    return near, far


def _thin_parts(z, edge_mm, reach_px=REACH_PX, mixed=None):
    if mixed is None:
        # (upsr.method.mixed imports this module: its test is imported where it is used)
        from upsr.method.mixed import mixed_pixels

        mixed = mixed_pixels(z, edge_mm)
    mixed = np.ascontiguousarray(mixed, np.bool_)
    if mixed.shape != z.shape:
        raise ValueError(f"mixed {mixed.shape} differs from the frame's shape {z.shape}")

    def found(depth: np.ndarray, n_axes: int, tips: bool) -> ThinParts:
        out = ThinParts(np.empty_like(z), np.empty_like(z), np.zeros(z.shape, np.int64))
        _thin_kernel(depth, edge_mm, reach_px, mixed, *out, n_axes, tips)
        return out

    parts = found(z, len(AXES), True)
    # the gaps narrower than a pixel (between two legs): the thin parts of the mirror image
    # (depth top − z: behind becomes in front), along rows and columns
    top = np.float32(2.0 * float(z.max(initial=0.0)) + 2.0 * edge_mm + 1.0)
    gaps = found(np.where(z > 0, top - z, np.float32(0.0)).astype(np.float32), GAP_AXES, False)
    g = (gaps.near > 0) & ~(parts.near > 0)
    parts.near[g] = top - gaps.near[g]
    parts.far[g] = top - gaps.far[g]
    parts.axis[g] = gaps.axis[g]
    return parts


@nb.njit(cache=True, nogil=True, inline="always")
def _share(z, near, alpha, i, j, f, edge, gap):  # pragma: no cover - numba
    """The share of F (depth f) at the low-res pixel (i, j): α at a thin pixel, 1 on F's
    surface (in front of it for a part, behind it for a ``gap``), else 0."""
    if near[i, j] > 0:
        return alpha[i, j]
    if not z[i, j] > 0:
        return 0.0
    return 1.0 if (z[i, j] >= f - edge if gap else z[i, j] <= f + edge) else 0.0


@nb.njit(cache=True, nogil=True, inline="always")
def _share_at(z, near, alpha, i, j, f, edge, gap):  # pragma: no cover - numba
    """:func:`_share` at (i, j) clamped to the frame."""
    h, w = z.shape
    return _share(z, near, alpha, min(max(i, 0), h - 1), min(max(j, 0), w - 1), f, edge, gap)


@nb.njit(cache=True, nogil=True)
def _split_thin_kernel(z, near, far, axis, edge, r, out):  # pragma: no cover - numba
    h, w = z.shape
    alpha = np.zeros((h, w), np.float64)
    for i in range(h):
        for j in range(w):
            if near[i, j] > 0:
                a = (far[i, j] - z[i, j]) / (far[i, j] - near[i, j])
                alpha[i, j] = min(max(a, 0.0), 1.0)
    score = np.empty(r * r, np.float64)
    for i in range(h):
        for j in range(w):
            f = near[i, j]
            if not f > 0:
                continue
            gap = f > far[i, j]  # (a gap narrower than a pixel: F behind the measured mix)
            # the part's centre line runs along the part through the centroid of the shares
            # of F across it (the pixel and its two neighbours across, in steps (di, dj))
            di, dj = AXES[axis[i, j]]
            total = alpha[i, j]
            moment = 0.0
            for s in (-1, 1):
                share = _share_at(z, near, alpha, i + s * di, j + s * dj, f, edge, gap)
                total += share
                moment += s * share
            c = moment / total if total > 0 else 0.0
            for q in range(r * r):
                # the block pixel's centre in low-res coordinates: bilinear in the shares
                ly = (i * r + q // r + 0.5) / r - 0.5
                lx = (j * r + q % r + 0.5) / r - 0.5
                y0 = int(np.floor(ly))
                x0 = int(np.floor(lx))
                gy = ly - y0
                gx = lx - x0
                s00 = _share_at(z, near, alpha, y0, x0, f, edge, gap)
                s01 = _share_at(z, near, alpha, y0, x0 + 1, f, edge, gap)
                s10 = _share_at(z, near, alpha, y0 + 1, x0, f, edge, gap)
                s11 = _share_at(z, near, alpha, y0 + 1, x0 + 1, f, edge, gap)
                bilinear = (1 - gy) * ((1 - gx) * s00 + gx * s01) + gy * ((1 - gx) * s10 + gx * s11)
                # ties (two thin pixels of equal shares side by side, a part along a pixel's
                # centre line): nearest the centre line across, then the side before it, then
                # in order (a line of whole rows or columns rather than a clump)
                across = ((ly - i) * di + (lx - j) * dj) / (di * di + dj * dj) - c
                score[q] = (
                    -np.round(bilinear, 6)
                    + 1e-8 * abs(across)
                    + (1e-10 if across > 0 else 0.0)
                    + q * 1e-13
                )
            order = np.argsort(score)
            n_near = int(alpha[i, j] * r * r + 0.5)
            for rank in range(r * r):
                q = order[rank]
                out[i * r + q // r, j * r + q % r] = f if rank < n_near else far[i, j]


def split_thin_parts(
    fused: npt.ArrayLike,
    measured: npt.ArrayLike,
    edge_mm: float,
    *,
    parts: ThinParts | None = None,
) -> np.ndarray:
    """Split the blocks of a frame's thin parts (:func:`thin_parts`) between the part and
    what lies behind it, keeping the mean the camera measured.

    Parameters
    ----------
    fused : array_like (r·h, r·w)
        The output (mm, 0 = none) at the frame's time.
    measured : array_like (h, w)
        The frame as measured (mm).
    edge_mm : float
        Depth step that separates two surfaces.
    parts : ThinParts of (h, w) arrays, optional
        The frame's thin parts where already found (by
        :func:`upsr.method.mixed.remove_mixed_pixels`); default: found here.

    Returns
    -------
    ndarray float32 (r·h, r·w): ``fused`` with each thin pixel's block split (``fused``
    itself when the frame has none).
    """
    f = np.ascontiguousarray(fused, np.float32)
    z = np.ascontiguousarray(nan_as_zero(measured))
    near, far, axis = _thin_parts(z, float(edge_mm)) if parts is None else parts
    if near.shape != z.shape:
        raise ValueError(f"thin parts {near.shape} differ from the frame's shape {z.shape}")
    if not (near > 0).any():
        return f
    r = f.shape[0] // z.shape[0]
    if f.shape != (z.shape[0] * r, z.shape[1] * r) or r < 1:
        raise ValueError(f"fused {f.shape} is not a multiple of measured {z.shape}")
    out = f.copy()
    _split_thin_kernel(z, near, far, axis, float(edge_mm), r, out)
    return out
