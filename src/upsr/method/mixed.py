"""Mixed ("flying") input pixels: a depth between two surfaces that belongs to neither.

Beyond the paper. A time-of-flight pixel integrates its footprint: where the footprint
straddles a depth edge it returns a mix of the two depths, which nearest or bicubic
upsampling spread over the pixel's whole high-res block (18–28 % flying pixels on the
realistic ToF scenes of :mod:`upsr.research.synth.realistic`). Whether a video's sensor mixes
at all is decided once per video (:mod:`upsr.method.footprint`). This module

* finds the mixed pixels of each frame (:func:`remove_mixed_pixels`: between its nearest and
  farthest neighbour, on no surface of its own, and not on a slope, nor on a slope two pixels
  wide along a straight edge, where a footprint would mix one; the parts narrower
  than a pixel, mixed along their whole length, :mod:`upsr.method.thin`; the clusters of like
  mixes of parts one to two pixels wide, :mod:`upsr.method.clusters`), which then abstain
  in the fusion so that the other frames fill them;
* splits those of the reference that no frame filled between the surfaces around them
  (:func:`split_mixed_pixels`): never a depth between two surfaces, never a hole where the
  camera measured something.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.method.clusters import mixed_clusters
from upsr.method.footprint import FLAT_END_SHARE
from upsr.method.slopes import STEEP_RUN_RATIO, _on_slope, _steps_agree
from upsr.method.thin import ThinParts, _gap_bottom, _thin_parts, split_thin_parts
from upsr.method.validation import nan_as_zero

__all__ = [
    "ABSTAIN",
    "BETWEEN_SHARE",
    "RAMP_ALONG_PX",
    "RAMP_END_SHARE",
    "SPLIT_MEAN_TOLERANCE",
    "mixed_pixels",
    "remove_mixed_pixels",
    "removed_depths",
    "split_mixed_pixels",
]

#: A pixel of a monotone pair between two flat surfaces across a row (column) is on a slope two
#: pixels wide, not mixed, when the same pair lies along the edge this many pixels on either
#: side (:func:`remove_mixed_pixels`): a footprint across a straight edge mixes one pixel per
#: row. The realistic approaching camera's box sides seen at a grazing angle, seeds 0–2
#: (``benchmarks/realistic_eval.py --quick --no-oracle --seed S``): moving-surface rmse
#: 9.96 / 9.66 / 4.99 → 9.10 / 8.33 / 4.94 mm (the bilateral filter's 9.84 / 8.98 / 6.17).
#: With 1 row on either side (and the end steps of the pixel's own row, not averaged), flying
#: pixels rose to 0.6–1.0 % on the animal, the room and that scene (curved and slanted edges
#: whose mixes change slowly along them).
RAMP_ALONG_PX = 3
#: ... when, averaged along those rows, each pixel of the pair lies beyond this share of the
#: edge threshold from the flat surface on its side and the step between them is the
#: largest of the three (the slope straddles the pixels' boundary): a mixed line whose next
#: pixel is the far surface, a little nearer with noise, is not such a pair.
RAMP_END_SHARE = 1.0 / 8.0

#: A removed (mixed) input pixel that abstains in the fusion: it votes neither on the depth nor
#: on whether there is depth (every kernel reads depth as ``> 0``).
ABSTAIN = -1.0

#: A reference block that the fusion filled (wholly or in part) must keep the mean its mixed
#: pixel measured, within this share of the step between the surfaces around it (the block's
#: share on each surface within 0.15), else the fused samples there were misregistered and the
#: block is split afresh (:func:`split_mixed_pixels` ``keep_mean``; on the realistic ToF
#: scenes, seeds 0–2: the deforming body's rmse 110–117 → 83–85 mm, the galloping animal's
#: 107 → 84–87, nearest 100–108; 0.08 within 1 mm of it, 0 (always split) 1–3 mm worse).
SPLIT_MEAN_TOLERANCE = 0.15
#: ... and none of its pixels may lie farther than this share of that step from both surfaces:
#: a fill made of other frames' mixes that their test missed keeps the mean but is mixed (on
#: the realistic ToF room, seeds 0–2: flying pixels 0.46 / 1.33 / 0.70 → 0.35 / 0.39 / 0.68 %;
#: 0.35 let most of them back, 1.40 % on seed 1; it costs the approaching camera's corner of
#: two walls, a slope pixel taken for mixed whose fill was right: surface rmse 11.0 → 12.6 mm).
#: Never farther than the edge threshold (``edge_mm`` of :func:`split_mixed_pixels`), which
#: separates two surfaces: across the 1.1 m from a galloping animal's leg to the wall the
#: share allowed a fill 275 mm behind the leg (realistic ToF scenes, seeds 0–2: the animal's
#: flying pixels 2.00 / 2.29 / 1.46 → 1.84 / 2.09 / 1.25 %, the room's edge accuracy +0.3 to
#: +0.7 points, its rmse −0.2 to +1.5 %).
BETWEEN_SHARE = 0.25
#: How far along the image's border (low-res px) a line of mixes at the border is followed to
#: the surface beyond the edge it straddles (:func:`remove_mixed_pixels`): a pixel of the
#: border that steps from the surface inward of it, with no such surface within reach along the
#: border, is a surface whose edge fell on the pixels' boundary (the approaching camera's box
#: top at the image's top: removing them, the wall's depth was taken from misregistered
#: samples of other frames, rmse +7.6 % on seed 0).
BORDER_REACH_PX = 16


@nb.njit(cache=True, nogil=True, inline="always")
def _between(z, i, j, edge, strength, own):  # pragma: no cover - numba
    """How far the pixel (i, j) lies from both its nearest and its farthest valid
    8-neighbour, min(v − lo, hi − v), where at most 2 of them lie within ``edge`` of it
    (on no surface of its own); −1 otherwise. Neighbours whose ``strength`` exceeds ``own``
    (more clearly mixed pixels) are left out."""
    h, w = z.shape
    v = z[i, j]
    lo = np.inf
    hi = -np.inf
    same = 0
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            u = z[a, b]
            if (a == i and b == j) or not u > 0 or strength[a, b] > own:
                continue
            lo = min(lo, u)
            hi = max(hi, u)
            same += 1 if abs(u - v) <= edge else 0
    d = min(v - lo, hi - v)
    return d if d > edge and same <= 2 else -1.0


@nb.njit(cache=True, nogil=True)
def _mixed_kernel(z, edge, marker, out):  # pragma: no cover - numba
    h, w = z.shape
    # first: how clearly each pixel lies between two surfaces (−1: not at all), then again
    # for those on a surface only through neighbours between two surfaces themselves (the
    # mixes of two legs side by side fall within the edge threshold of each other)
    strength = np.full((h, w), -1.0)
    for own in (np.inf, 0.0):
        again = strength.copy()
        for i in range(h):
            for j in range(w):
                if z[i, j] > 0 and strength[i, j] <= 0:
                    again[i, j] = _between(z, i, j, edge, strength, own)
        strength = again
    # then each such pixel again without its more clearly mixed neighbours: the first pixel
    # of a steep slope (a box top seen at a grazing angle) beside the line of mixed pixels
    # that separates it from the wall behind lies between that line and its own slope, but
    # not between two surfaces; the second pixel of a ramp of two mixed pixels between two
    # flat surfaces begins no slope
    for i in range(h):
        for j in range(w):
            v = z[i, j]
            out[i, j] = v
            s = strength[i, j]
            if v > 0 and _gap_bottom(z, i, j, edge):
                out[i, j] = marker  # (between no two surfaces beside it, a mix all the same)
                continue
            if not (v > 0 and s > 0):
                continue
            if _on_slope(z, i, j, edge) or _ramp_along_the_edge(z, i, j, edge):
                continue
            if _between(z, i, j, edge, strength, s) > 0 or not _starts_slope(
                z, i, j, edge, strength, s
            ):
                out[i, j] = marker
    # a pixel of the image's border whose footprint straddles an edge seen on one side only
    for i in range(h):
        step = 1 if i == 0 or i == h - 1 else max(w - 1, 1)  # (rows between: both ends)
        for j in range(0, w, step):
            if out[i, j] > 0 and _one_sided(z, i, j, edge):
                out[i, j] = marker


@nb.njit(cache=True, nogil=True, inline="always")
def _ramp_along_the_edge(z, i, j, edge):  # pragma: no cover - numba
    """(i, j) and its neighbour along a row (column) are a slope two pixels wide along a
    straight edge: in the 2·RAMP_ALONG_PX + 1 rows (columns) around it the pair lies within
    half the edge threshold of its own depths, and the means of the six pixels across the
    edge (q0, o1, pixel, neighbour, o2, q3) step monotonically from one flat surface
    (|q0 − o1|, |q3 − o2| within that half and FLAT_END_SHARE of the step) to another more
    than ``edge`` away, the middle step the largest and the outer two beyond
    RAMP_END_SHARE·``edge``."""
    h, w = z.shape
    v = z[i, j]
    n = 2 * RAMP_ALONG_PX + 1
    for di, dj in ((0, 1), (1, 0)):
        for s in (-1, 1):
            p = z[i + s * di, j + s * dj] if 0 <= i + s * di < h and 0 <= j + s * dj < w else 0.0
            if not p > 0:
                continue
            # the rows (columns) along the edge: each the same four pixels across it, the two
            # inner ones within a tolerance of the pixel's and its neighbour's depths
            total = np.zeros(6)
            ok = True
            for t in range(-RAMP_ALONG_PX, RAMP_ALONG_PX + 1):
                a, b = i + t * dj, j + t * di
                for k in range(6):  # q0, o1, v, p, o2, q3
                    c, d = a + (k - 2) * s * di, b + (k - 2) * s * dj
                    u = z[c, d] if 0 <= c < h and 0 <= d < w else 0.0
                    if not u > 0:
                        ok = False
                    total[k] += u
                if not ok:
                    break
                if t != 0 and (
                    abs(z[a, b] - v) > 0.5 * edge or abs(z[a + s * di, b + s * dj] - p) > 0.5 * edge
                ):
                    ok = False
                    break
            if not ok:
                continue
            q0, o1, mv, mp, o2, q3 = total / n
            step = abs(o2 - o1)
            if not step > edge or not ((o1 > mv > mp > o2) or (o1 < mv < mp < o2)):
                continue
            inner, out1, out2 = abs(mp - mv), abs(mv - o1), abs(o2 - mp)
            flat = min(FLAT_END_SHARE * step, 0.5 * edge)
            if (
                inner > out1
                and inner > out2
                and min(out1, out2) > RAMP_END_SHARE * edge
                and abs(q0 - o1) <= flat
                and abs(q3 - o2) <= flat
            ):
                return True
    return False


@nb.njit(cache=True, nogil=True, inline="always")
def _one_sided(z, i, j, edge):  # pragma: no cover - numba
    """The border pixel (i, j) steps by more than ``edge`` to the surface inward of it (its
    next two pixels inward within ``edge`` of each other) and none of its three inward
    neighbours lies on its own surface: a footprint that straddles an edge whose other side
    lies beyond the image (where nothing shows the depth behind it)."""
    h, w = z.shape
    v = z[i, j]
    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        a, b = i - di, j - dj  # outside the image?
        if 0 <= a < h and 0 <= b < w:
            continue
        i2, j2 = i + 2 * di, j + 2 * dj
        if not (0 <= i2 < h and 0 <= j2 < w):
            continue
        u, u2 = z[i + di, j + dj], z[i2, j2]
        if not (u > 0 and u2 > 0) or abs(u - v) <= edge or abs(u2 - u) > edge:
            continue
        if _steps_agree(v - u, u - u2):
            continue  # a slope that tapers into a flat surface
        own = False
        for k in range(-1, 2):
            a, b = i + di + k * dj, j + dj + k * di  # the inward row along the border
            if 0 <= a < h and 0 <= b < w and z[a, b] > 0 and abs(z[a, b] - v) <= edge:
                own = True
        if not own and (
            _behind_the_line(z, i, j, dj, di, v - u, edge)
            or _behind_the_line(z, i, j, -dj, -di, v - u, edge)
        ):
            return True
    return False


@nb.njit(cache=True, nogil=True, inline="always")
def _behind_the_line(z, i, j, di, dj, side, edge):  # pragma: no cover - numba
    """Along the border from (i, j) in direction (di, dj), through the pixels within ``edge``
    of the last (the line of mixes along the edge), at most :data:`BORDER_REACH_PX` steps: the
    first step beyond ``edge`` goes further to ``side`` (the sign of the step from the surface
    inward to (i, j)): the surface beyond the border, seen where the edge leaves it."""
    h, w = z.shape
    last = z[i, j]
    a, b = i, j
    for _ in range(BORDER_REACH_PX):
        a += di
        b += dj
        if not (0 <= a < h and 0 <= b < w) or not z[a, b] > 0:
            return False
        step = z[a, b] - last
        if abs(step) > edge:
            return (step > 0) == (side > 0)
        last = z[a, b]
    return False


def mixed_pixels(frame: npt.ArrayLike, edge_mm: float) -> np.ndarray:
    """The pixels of one frame that lie between two surfaces: :func:`remove_mixed_pixels`'
    test without the thin parts.

    Parameters
    ----------
    frame : array_like (h, w)
        Depth (mm), 0 or NaN = no measurement.
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    ndarray of bool (h, w)
    """
    z = np.ascontiguousarray(nan_as_zero(frame))
    if z.ndim != 2:
        raise ValueError(f"frame must be (h, w), got shape {z.shape}")
    out = np.empty_like(z)
    _mixed_kernel(z, float(edge_mm), 0.0, out)
    return (z > 0) & ~(out > 0)


@nb.njit(cache=True, nogil=True, inline="always")
def _starts_slope(z, i, j, edge, strength, own):  # pragma: no cover - numba
    """A steep slope begins at (i, j): in some direction its next two steps each exceed the
    edge threshold and agree within :data:`STEEP_RUN_RATIO`, through a neighbour whose
    ``strength`` does not exceed ``own`` (not through a more clearly mixed pixel)."""
    h, w = z.shape
    v = z[i, j]
    for di in range(-1, 2):
        for dj in range(-1, 2):
            a, b = i + di, j + dj
            c, d = i + 2 * di, j + 2 * dj
            if (di == 0 and dj == 0) or not (0 <= c < h and 0 <= d < w):
                continue
            u, x = z[a, b], z[c, d]
            if not (u > 0 and x > 0) or strength[a, b] > own:
                continue
            s, t = u - v, x - u
            if abs(s) > edge and abs(t) > edge and _steps_agree(s, t, STEEP_RUN_RATIO):
                return True
    return False


def remove_mixed_pixels(
    frames: npt.ArrayLike,
    edge_mm: float,
    marker: float = 0.0,
    *,
    thin_parts: bool = True,
    return_thin_parts: bool = False,
) -> np.ndarray | tuple[np.ndarray, ThinParts | None]:
    """Set the mixed ("flying") pixels of each frame to ``marker`` (0 = no measurement).

    A pixel is mixed when its depth lies more than ``edge_mm`` behind its nearest valid
    8-neighbour and more than ``edge_mm`` in front of its farthest one, and at most 2 of its
    8-neighbours lie within ``edge_mm`` of it (a mixed pixel belongs to no surface; a line of
    them along an edge still counts; a genuine surface between two others does not), or
    without the neighbours between two surfaces themselves (two legs' mixes side by side), also
    without those of its neighbours that lie more clearly between two surfaces (a larger
    min(v − lo, hi − v)): the first pixel of a steep slope (a box top at a grazing angle)
    lies between the line of mixed pixels in front of the wall and its own slope, not between
    two surfaces, when a steep slope begins at it (its next two steps beyond the edge
    threshold, agreeing); the second pixel of a ramp of two mixed pixels between flat
    surfaces begins none and stays mixed. A pixel on a steep slope is never mixed, nor one of
    a pair that steps from one flat surface to another along :data:`RAMP_ALONG_PX` rows
    (columns) on either side of it, the step between the two the largest (a box side two
    pixels wide seen at a grazing angle: a footprint across a straight edge mixes one pixel
    per row, and two mixes side by side shift from one row to the next). A ToF
    pixel whose footprint straddles a depth edge returns a depth between the two surfaces,
    which belongs to neither. So do the pixels of a part narrower than a pixel, mixed along
    its whole length (:func:`upsr.method.thin.thin_parts`: nothing nearer beside them but
    the surface the part grows out of), and the bottom of a gap narrower than a pixel
    between two nearer parts (:func:`upsr.method.thin._gap_bottom`), and with ``thin_parts``
    the small clusters of like mixes of a part one to two pixels wide
    (:func:`upsr.method.clusters.mixed_clusters`). The other frames of
    the window fill them (their samples there are not mixed), or :func:`split_mixed_pixels`
    splits them between the surfaces around them. At the image's border a footprint may
    straddle an edge whose other side lies beyond the image: a pixel of the border that steps
    by more than ``edge_mm`` from the surface inward of it (a flat one, not a slope tapering
    into it), with none of its inward neighbours on its own surface, is mixed when the line
    it belongs to, followed along the border (:data:`BORDER_REACH_PX`), steps on to a surface
    beyond it (seen where the edge leaves the border).

    Parameters
    ----------
    frames : array_like (..., h, w)
        Depth (mm), 0 or NaN = no measurement.
    edge_mm : float
        Depth step that separates two surfaces.
    marker : float
        What a mixed pixel becomes: 0 (no measurement: it votes "no depth") or
        :data:`ABSTAIN` (the fusion ignores it, like a sample outside the frame).
    thin_parts : bool
        Also the pixels of parts narrower than a pixel (:func:`upsr.method.thin.thin_parts`)
        and the clusters of like mixes of parts one to two pixels wide
        (:func:`upsr.method.clusters.mixed_clusters`).
    return_thin_parts : bool
        Also return the thin parts found, for :func:`split_mixed_pixels` (``thin``).

    Returns
    -------
    ndarray float32, same shape: the frames with mixed pixels set to ``marker`` (NaN become 0).
    thin : upsr.method.thin.ThinParts of arrays of the same shape, or None
        With ``return_thin_parts``: the frames' thin parts (None without ``thin_parts``).
    """
    z = np.asarray(frames, np.float32)
    z = np.where(np.isnan(z), np.float32(0.0), z)
    flat = z.reshape(-1, *z.shape[-2:])
    out = np.empty_like(flat)
    found = []
    for k in range(flat.shape[0]):
        zk = np.ascontiguousarray(flat[k])
        _mixed_kernel(zk, float(edge_mm), float(marker), out[k])
        if thin_parts:
            # (mixed along their whole length; the pixels just removed end no run), then the
            # clusters of like mixes of parts one to two pixels wide
            found.append(_thin_parts(zk, float(edge_mm), mixed=out[k] != zk))
            out[k][found[-1].near > 0] = marker
            out[k][mixed_clusters(zk, out[k] == zk, edge_mm)] = marker
    out = out.reshape(z.shape)
    if not return_thin_parts:
        return out
    if not found:
        return out, None
    return out, ThinParts(*(np.stack(a).reshape(z.shape) for a in zip(*found, strict=True)))


def removed_depths(measured: np.ndarray, cleaned: np.ndarray) -> np.ndarray:
    """The measurement at the pixels :func:`remove_mixed_pixels` marked :data:`ABSTAIN` in
    ``cleaned`` (its result for ``measured``), 0 elsewhere: the ``mixes_mm`` of
    :func:`upsr.method.fusion.register_and_fuse`."""
    return np.where(cleaned == ABSTAIN, measured, np.float32(0.0)).astype(np.float32)


@nb.njit(cache=True, nogil=True, inline="always")
def _side(removed, source, i, j, m, nearer):  # pragma: no cover - numba
    """The kept 8-neighbour of (i, j) nearest by centre (a tie: the depth nearest m) whose
    depth lies in front of m (``nearer``) or behind it: (depth, row, column), depth 0 where
    there is none. (Looking 2 px away as well gave blocks on box tops seen at grazing angles
    depths up to 300 mm off the surface next to them: on the ToF room the flying pixels rose
    from 0.67 to 2.04 %.)"""
    h, w = removed.shape
    best = np.inf
    pick = 0.0
    pa = -1
    pb = -1
    for a in range(max(i - 1, 0), min(i + 2, h)):
        for b in range(max(j - 1, 0), min(j + 2, w)):
            u = source[a, b]
            if removed[a, b] or not u > 0 or (u < m) != nearer or u == m:
                continue
            d = ((a - i) ** 2 + (b - j) ** 2) * 1e6 + min(abs(u - m), 1e6 - 1.0)
            if d < best:
                best = d
                pick = u
                pa = a
                pb = b
    return pick, pa, pb


@nb.njit(cache=True, nogil=True, inline="always")
def _slope_step(removed, source, i, j, a, b, m, limit, edge):  # pragma: no cover - numba
    """The depth step from the pixel beyond the neighbour (a, b) of (i, j) (on the far side
    from (i, j)) to (a, b): the slope of (a, b)'s surface towards (i, j) per step; 0 where
    that pixel is missing, removed, or steps by more than ``limit`` (another surface), or
    where a step beyond ``edge`` leads away from the mix m (the nearer side nearer still, the
    farther side farther) and the step beyond it does not go on alike
    (:func:`upsr.method.slopes._steps_agree`, :data:`STEEP_RUN_RATIO`): a floor seen at a
    grazing angle steps evenly, a like mix kept beside a thin part does not."""
    h, w = removed.shape
    a2 = 2 * a - i
    b2 = 2 * b - j
    if not (0 <= a2 < h and 0 <= b2 < w) or removed[a2, b2] or not source[a2, b2] > 0:
        return 0.0
    s = source[a, b] - source[a2, b2]
    if abs(s) > limit:
        return 0.0
    if abs(s) <= edge or (s > 0) == (source[a, b] < m):
        return s
    a3 = 3 * a - 2 * i
    b3 = 3 * b - 2 * j
    if not (0 <= a3 < h and 0 <= b3 < w) or removed[a3, b3] or not source[a3, b3] > 0:
        return 0.0
    return s if _steps_agree(s, source[a2, b2] - source[a3, b3], STEEP_RUN_RATIO) else 0.0


@nb.njit(cache=True, nogil=True, inline="always")
def _on_side(u, step, i, j, a, b, y, x, r):  # pragma: no cover - numba
    """The depth of the neighbour (a, b)'s surface (depth u at its centre, ``step`` per step
    from (a, b) towards (i, j)) at the high-res pixel (y, x) of the block of (i, j)."""
    da = i - a  # the step direction (i − a, j − b), unit low-res px
    db = j - b
    t = ((y - ((a + 0.5) * r - 0.5)) * da + (x - ((b + 0.5) * r - 0.5)) * db) / (
        r * (da * da + db * db)
    )
    return u + step * t


@nb.njit(cache=True, nogil=True, parallel=True)
def _split_kernel(
    fused, removed, measured, source, scale, keep_mean, edge, out
):  # pragma: no cover - numba
    h, w = removed.shape
    r = scale
    for i in nb.prange(h):
        score = np.empty(r * r, np.float64)
        split = np.empty(r * r, np.float32)
        for j in range(w):
            if not removed[i, j]:
                continue
            m = measured[i, j]
            near, na, nb_ = _side(removed, source, i, j, m, True)
            far, fa, fb = _side(removed, source, i, j, m, False)
            if near > 0 and far > 0:
                # the footprint's mean is m: a share alpha of it on the nearer surface, on the
                # pixels closest to that surface's pixel (rather than to the farther one's)
                alpha = (far - m) / (far - near)
                n_near = int(alpha * r * r + 0.5)
                # each side follows its surface's slope into the block (a floor seen at a
                # grazing angle steps by more than the edge threshold per pixel)
                limit = 0.5 * (far - near)
                s_near = _slope_step(removed, source, i, j, na, nb_, m, limit, edge)
                s_far = _slope_step(removed, source, i, j, fa, fb, m, limit, edge)
                for q in range(r * r):
                    y = i * r + q // r
                    x = j * r + q % r
                    dny = y - ((na + 0.5) * r - 0.5)
                    dnx = x - ((nb_ + 0.5) * r - 0.5)
                    dfy = y - ((fa + 0.5) * r - 0.5)
                    dfx = x - ((fb + 0.5) * r - 0.5)
                    score[q] = (dny * dny + dnx * dnx) - (dfy * dfy + dfx * dfx) + q * 1e-9
                order = np.argsort(score)
                for rank in range(r * r):
                    q = order[rank]
                    y = i * r + q // r
                    x = j * r + q % r
                    if rank < n_near:
                        split[rank] = _on_side(near, s_near, i, j, na, nb_, y, x, r)
                    else:
                        split[rank] = _on_side(far, s_far, i, j, fa, fb, y, x, r)
                total = 0.0
                between = False
                band = min(BETWEEN_SHARE * (far - near), edge)
                for rank in range(r * r):
                    q = order[rank]
                    y = i * r + q // r
                    x = j * r + q % r
                    if not fused[y, x] > 0:
                        out[y, x] = split[rank]
                    u = out[y, x]
                    total += u
                    between |= u - near > band and far - u > band
                tol = SPLIT_MEAN_TOLERANCE * (far - near)
                if keep_mean and (between or abs(total / (r * r) - m) > tol):
                    for rank in range(r * r):
                        q = order[rank]
                        out[i * r + q // r, j * r + q % r] = split[rank]
                continue
            for y in range(i * r, (i + 1) * r):
                for x in range(j * r, (j + 1) * r):
                    if fused[y, x] > 0:
                        continue
                    best = np.inf
                    pick = np.float32(0.0)
                    for a in range(max(i - 1, 0), min(i + 2, h)):
                        for b in range(max(j - 1, 0), min(j + 2, w)):
                            u = source[a, b]
                            if removed[a, b] or not u > 0:
                                continue
                            dy = y - ((a + 0.5) * r - 0.5)
                            dx = x - ((b + 0.5) * r - 0.5)
                            # nearest neighbour centre first; a tie: the depth nearest m
                            d = (dy * dy + dx * dx) * 1e6 + min(abs(u - m), 1e6 - 1.0)
                            if d < best:
                                best = d
                                pick = u
                    out[y, x] = pick


def split_mixed_pixels(
    fused: npt.ArrayLike,
    measured: npt.ArrayLike,
    cleaned: npt.ArrayLike,
    source: npt.ArrayLike,
    *,
    keep_mean: bool = False,
    edge_mm: float = math.inf,
    thin_parts: bool = True,
    thin: ThinParts | None = None,
) -> np.ndarray:
    """Give the reference's mixed pixels that no frame filled the depth of their neighbours.

    A pixel that :func:`remove_mixed_pixels` dropped from the reference did measure something:
    a mix of the surfaces its footprint straddles. Where the fusion left its block without
    depth, the block is split between the surfaces around it, never given a depth between
    them, and never left a hole:

    * with a kept 8-neighbour in front of the measured mix m (depth F) and one behind it
      (depth B), the footprint's mean is kept: a share α = (B − m)/(B − F) of the block's
      pixels, those closer to F's pixel than to B's, take F, the others B (on the realistic
      ToF room, seed 2, the mean error of these blocks fell from +102 to +25 mm; nearest-centre
      splitting gave half a block to each side whatever the mix). Each side follows its
      surface's slope into the block (the step from the pixel beyond F's, or B's, to it,
      where that step is under (B − F)/2): a floor at a grazing angle steps by more than the
      edge threshold per pixel (realistic ToF room, seeds 0–2: edge accuracy 81–82 → 82–87 %).
      With ``keep_mean``, a block the fusion filled, wholly or in part, whose mean (its fused
      pixels and the split's for the rest) misses m by more than
      :data:`SPLIT_MEAN_TOLERANCE` · (B − F), or one of whose pixels lies more than
      min(:data:`BETWEEN_SHARE` · (B − F), ``edge_mm``) from both F and B, is split afresh:
      samples that followed a moving edge keep the footprint's mean, misregistered ones do
      not, and other frames' mixes that their own test missed are mixes still;
    * with ``keep_mean`` and ``thin_parts``, the blocks of the reference's thin parts
      (:func:`upsr.method.thin.split_thin_parts`: their share of the part along its line,
      the rest the depth behind it), whatever the fusion gave them;
    * otherwise (a lone outlier, or one side only) each high-res pixel takes the depth of
      the nearest (by block centre) kept low-res 8-neighbour (a tie: the one nearest m).

    Parameters
    ----------
    fused : array_like (r·h, r·w)
        Fused depth (mm, 0 = none).
    measured, cleaned : array_like (h, w)
        The reference frame as measured and after :func:`remove_mixed_pixels` (mm).
    source : array_like (h, w)
        The depth the neighbours give (mm, 0 = none): the reference's anchor.
    keep_mean : bool
        The sensor integrates each pixel's footprint (its removed pixels are mixes, the mean
        of their block): fused blocks must keep it. False for point-sampling sensors, whose
        removed pixels are outliers that say nothing of their block.
    edge_mm : float
        Depth step that separates two surfaces: with ``keep_mean``, a fused pixel farther
        than this from both sides lies between them, however far apart they are.
    thin_parts : bool
        With ``keep_mean``, also split the blocks of the reference's thin parts.
    thin : upsr.method.thin.ThinParts of (h, w) arrays, optional
        The reference's thin parts where :func:`remove_mixed_pixels` found them
        (``return_thin_parts``); default: found here.

    Returns
    -------
    ndarray float32 (r·h, r·w): ``fused`` with those blocks filled (``fused`` itself when
    nothing was removed or split).
    """
    z = nan_as_zero(measured)
    c = nan_as_zero(cleaned)
    removed = (z > 0) & ~(c > 0)
    f = np.ascontiguousarray(fused, np.float32)
    src = np.ascontiguousarray(source, np.float32)
    out = f
    if removed.any():
        out = f.copy()
        r = int(f.shape[0] // z.shape[0])
        _split_kernel(f, removed, z, src, r, bool(keep_mean), float(edge_mm), out)
    if keep_mean and thin_parts:
        out = split_thin_parts(out, z, edge_mm, parts=thin)  # mixed along their whole length
    return out
