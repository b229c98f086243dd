"""Whether the motion carried each frame of a window along: the local registration residual.

Beyond the paper. The registration of eq. 18–21 chains dense flows; where the flow did not
follow the scene (a head moving 25 px per frame, an occlusion seen by a moving camera) the
frame's samples land on the wrong surface and, voting in the fusion, blur or erase what the
reference measured. A frame registered to the reference is checked against the reference
itself, on the low-res grid: frame k's sample at each reference pixel centre (moved by its
map) should lie on the same surface as the reference there. Disagreement at a single pixel
proves nothing (noise, a dropout, a sub-pixel shift across an edge), but disagreement at
several *interior* pixels of the reference (pixels whose 8 neighbours all lie on their
surface, where a sub-pixel shift cannot reach another surface) around a pixel, each seeing a
depth of another surface in frame k, does: frame k is misregistered there and none of its
samples near that pixel is trusted (:func:`misregistered`, read by
:func:`upsr.method.fusion.register_and_fuse`).

Where the reference measured nothing next to a depth edge (the projector shadow of
structured light lies beside every foreground edge, on its far side; a dropout there), a
sample showing a surface nearer than everything the reference measured around the hole
(:func:`hole_backgrounds`) is misregistered too and abstains
(:func:`upsr.method.fusion.register_and_fuse` with ``hole_floors``; the recursive update
forgets such a state): the shadow of a moving body is filled from the background side or
stays empty, never with the body that other frames show there. Conversely, on the half of a
hole's block towards a neighbour that measured a nearer surface, a fill behind that surface
is dropped (:func:`clear_stale_fills`): a body that moved into the hole may reach there,
while the other frames still show the wall.
"""

from __future__ import annotations

import math

import cv2
import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.method.alternatives import _run
from upsr.method.validation import check_ref, nan_as_zero

__all__ = [
    "ENCLOSED_RADIUS_PX",
    "ENCLOSED_SHARE",
    "FOLLOWED_MAX_SPREAD_PX",
    "FOLLOWED_SHARE",
    "HOLE_REACH_PX",
    "MISMATCH_FRACTION",
    "MISMATCH_MIN_COUNT",
    "clear_stale_fills",
    "enclosed_holes",
    "hole_backgrounds",
    "map_spread",
    "maps_at_centres",
    "misregistered",
    "registered_samples",
    "thin_parts_followed",
]

#: How far (low-res px, through the hole) :func:`hole_backgrounds` looks for the depth around a
#: hole: a projector shadow is several pixels wide (f·b·(1/z_near − 1/z_far): 7 px at 640×480
#: for a body at 2 m before a wall at 3 m), and its middle has no measured neighbour.
HOLE_REACH_PX = 8
#: Half-side (low-res px) of the window in which :func:`enclosed_holes` weighs how much of a
#: hole's surroundings the frame measured ...
ENCLOSED_RADIUS_PX = 4
#: ... and the least share of the window's pixels (those inside the image) it must have
#: measured. The recursive mode's state in a hole of the frame outside such surroundings (an
#: open region where nothing returns) stays only where its surface is measured beside the
#: hole: on the galloping animal with no wall behind it (``realistic_eval.py --quick
#: --no-oracle --scenes gallop_none``) that alone took its flying pixels from 0.9–2.0 % to
#: 0.5 % or less, but applied in every hole it cost the Kinect bodies at 320×240
#: (``--full-kinect``) 1.6 points of edge accuracy: their projector shadows, several pixels
#: wide, keep the wall the state saw.
ENCLOSED_SHARE = 0.5

#: Fewest mismatching interior pixels in a neighbourhood that make a frame untrusted there.
MISMATCH_MIN_COUNT = 2
#: ... and the least share of the neighbourhood's checked interior pixels they must be.
MISMATCH_FRACTION = 0.2
#: Least share of a window's other frames that followed a thin part in front for the surface
#: behind it to compete there (:func:`thin_parts_followed`).
FOLLOWED_SHARE = 0.5
#: Largest spread (low-res px) of a frame's motion over a thin part's block
#: (:func:`map_spread`) for that frame to follow the part there: a flow that stretches across
#: the part (a rotating blade whose centre it follows) moves the block's sides elsewhere
#: (the outside propeller at r = 2, σ = 10: rmse 101.3 → 98.5 mm against nearest's 99.2).
FOLLOWED_MAX_SPREAD_PX = 0.5


@nb.njit(cache=True, nogil=True)
def _registered_kernel(lowres, maps, scale, ratio, out):  # pragma: no cover - numba
    n, h, w = lowres.shape
    gh = maps.shape[1]
    gw = maps.shape[2]
    s_y = gh / h
    s_x = gw / w
    hh = h * scale
    ww = w * scale
    nan = np.float32(np.nan)
    for k in range(n):
        for i in range(h):
            yg = min(max(int((i + 0.5) * s_y), 0), gh - 1)
            cy = (i + 0.5) * scale - 0.5
            for j in range(w):
                xg = min(max(int((j + 0.5) * s_x), 0), gw - 1)
                cx = (j + 0.5) * scale - 0.5
                qx = cx + maps[k, yg, xg, 0] * ratio
                qy = cy + maps[k, yg, xg, 1] * ratio
                out[k, i, j] = nan
                if -0.5 <= qx < ww - 0.5 and -0.5 <= qy < hh - 0.5:
                    xl = int((qx + 0.5) / scale)
                    yl = int((qy + 0.5) / scale)
                    out[k, i, j] = lowres[k, yl, xl]


def maps_at_centres(maps: npt.ArrayLike, lowres_shape: tuple[int, int]) -> np.ndarray:
    """Each frame's motion at every low-res pixel centre: the map at the flow-grid node
    nearest to it, as :func:`registered_samples` reads it.

    Parameters
    ----------
    maps : array_like (N, s·h, s·w, 2)
        Motion of each frame on the flow grid (flow px).
    lowres_shape : (int, int)
        (h, w).

    Returns
    -------
    ndarray float64 (N, h, w, 2)
    """
    m = np.asarray(maps)
    h, w = lowres_shape
    gh, gw = m.shape[1:3]
    yg = np.clip(((np.arange(h) + 0.5) * (gh / h)).astype(np.int64), 0, gh - 1)
    xg = np.clip(((np.arange(w) + 0.5) * (gw / w)).astype(np.int64), 0, gw - 1)
    # (the nodes first, then float64: the whole map is never converted)
    return np.take(np.take(m, yg, axis=1), xg, axis=2).astype(np.float64)


@nb.njit(cache=True, nogil=True, inline="always")
def _spread_at(maps, k, i, j, h, w):  # pragma: no cover - numba
    """:func:`map_spread` of frame k at low-res pixel (i, j) of an (h, w) frame."""
    gh, gw = maps.shape[1], maps.shape[2]
    s_y = gh / h
    s_x = gw / w
    yg = min(max(int((i + 0.5) * s_y), 0), gh - 1)
    xg = min(max(int((j + 0.5) * s_x), 0), gw - 1)
    cx = maps[k, yg, xg, 0]
    cy = maps[k, yg, xg, 1]
    worst = 0.0
    for a in range(int(i * s_y), max(min(int((i + 1) * s_y), gh), int(i * s_y) + 1)):
        for b in range(int(j * s_x), max(min(int((j + 1) * s_x), gw), int(j * s_x) + 1)):
            dx = (maps[k, a, b, 0] - cx) / s_x
            dy = (maps[k, a, b, 1] - cy) / s_y
            worst = max(worst, dx * dx + dy * dy)
    return math.sqrt(worst)


@nb.njit(cache=True, nogil=True, parallel=True)
def _spread_kernel(maps, h, w, out):  # pragma: no cover - numba
    n = maps.shape[0]
    for ki in nb.prange(n * h):
        for j in range(w):
            out[ki // h, ki % h, j] = _spread_at(maps, ki // h, ki % h, j, h, w)


def map_spread(maps: npt.ArrayLike, lowres_shape: tuple[int, int]) -> np.ndarray:
    """How far each frame's motion over a low-res pixel's block strays from its motion at the
    pixel's centre (the flow-grid node :func:`registered_samples` reads): the largest
    distance, in low-res px, between the map at any flow-grid node of the block and at that
    node. A motion the block shares (a translation, a slow turn) spreads by a fraction of a
    pixel; a flow that stretches across a thin part the frame reaches only at its centre
    (a rotating blade) by more.

    Parameters
    ----------
    maps : array_like (N, s·h, s·w, 2)
        Motion from the reference to each frame on the flow grid (flow px).
    lowres_shape : (int, int)
        (h, w).

    Returns
    -------
    ndarray float32 (N, h, w): 0 where the flow grid is the low-res grid (s = 1).
    """
    mp = np.ascontiguousarray(maps, np.float32)
    h, w = lowres_shape
    out = np.empty((mp.shape[0], h, w), np.float32)
    _spread_kernel(mp, int(h), int(w), out)
    return out


def registered_samples(lowres: npt.ArrayLike, maps: npt.ArrayLike, scale: int) -> np.ndarray:
    """Each frame's low-res sample at every reference pixel's centre, moved by its map.

    Parameters
    ----------
    lowres : array_like (N, h, w)
        Low-res frames of the window (mm, 0 = no depth; NaN is read as 0).
    maps : array_like (N, s·h, s·w, 2)
        Motion from the reference to each frame on the flow grid (flow px), eq. 21.
    scale : int
        SR factor r (the maps are read at the flow-grid node nearest to each centre and
        scaled to output px by r·w / (s·w), as in the fusion).

    Returns
    -------
    ndarray float32 (N, h, w): frame k's sample (mm; 0: no depth) at reference pixel (i, j);
    NaN where the motion leaves frame k.
    """
    lr = nan_as_zero(np.ascontiguousarray(lowres, np.float32))
    mp = np.ascontiguousarray(maps, np.float32)
    n, h, w = lr.shape
    if mp.ndim != 4 or mp.shape[0] != n or mp.shape[3] != 2:
        raise ValueError(f"maps must be (N={n}, H, W, 2), got {mp.shape}")
    out = np.empty((n, h, w), np.float32)
    _registered_kernel(lr, mp, int(scale), float(scale * w / mp.shape[2]), out)
    return out


@nb.njit(cache=True, nogil=True, parallel=True)
def _mismatch_kernel(reg, ref, offsets, ref_index, edge, radius, min_count, fraction, out):
    # pragma: no cover - numba
    n, h, w = reg.shape
    interior = np.zeros((h, w), np.bool_)
    for i in range(h):
        for j in range(w):
            c = ref[i, j]
            ok = c > 0
            for a in range(max(i - 1, 0), min(i + 2, h)):
                for b in range(max(j - 1, 0), min(j + 2, w)):
                    u = ref[a, b]
                    if not (u > 0 and abs(u - c) <= edge):
                        ok = False
            interior[i, j] = ok
    for k in nb.prange(n):
        out[k] = False
        if k == ref_index:
            continue
        # summed-area tables of: the interior pixels where frame k's registered sample has
        # depth (checked), and those of them where it lies on another surface (bad)
        bad = np.zeros((h + 1, w + 1), np.int32)
        checked = np.zeros((h + 1, w + 1), np.int32)
        for i in range(h):
            for j in range(w):
                v = reg[k, i, j]
                c = 0
                e = 0
                # at an edge, outside frame k, without depth in either (a dropout of the
                # reference or of frame k, or a part moved off the background): no evidence
                if interior[i, j] and ref[i, j] > 0 and v > 0:
                    c = 1
                    e = 0 if abs(v - offsets[k, i, j] - ref[i, j]) <= edge else 1
                checked[i + 1, j + 1] = c + checked[i, j + 1] + checked[i + 1, j] - checked[i, j]
                bad[i + 1, j + 1] = e + bad[i, j + 1] + bad[i + 1, j] - bad[i, j]
        # both counted over the (2R+1)² neighbourhood of each pixel
        for i in range(h):
            i0 = max(i - radius, 0)
            i1 = min(i + radius + 1, h)
            for j in range(w):
                j0 = max(j - radius, 0)
                j1 = min(j + radius + 1, w)
                nb_bad = bad[i1, j1] - bad[i0, j1] - bad[i1, j0] + bad[i0, j0]
                nb_chk = checked[i1, j1] - checked[i0, j1] - checked[i1, j0] + checked[i0, j0]
                out[k, i, j] = nb_bad >= min_count and nb_bad >= fraction * nb_chk


def misregistered(
    registered: npt.ArrayLike,
    reference: npt.ArrayLike,
    ref: int,
    *,
    edge_mm: float,
    offsets: npt.ArrayLike | None = None,
    radius_px: int = 2,
    min_count: int = MISMATCH_MIN_COUNT,
    fraction: float = MISMATCH_FRACTION,
) -> np.ndarray:
    """Where each frame of a window is misregistered: its samples there are not trusted.

    Frame k is misregistered at reference pixel (i, j) when, among the interior pixels of
    the reference (with depth, and all 8 neighbours with depth within ``edge_mm`` of it) in
    the (2R+1)² neighbourhood of (i, j) where frame k's registered sample has depth
    (:func:`registered_samples`, minus the radial offset), at least ``min_count``, and at
    least ``fraction`` of them, see another surface: a depth more than ``edge_mm`` away.
    A missing depth on either side is no evidence (a dropout, a whole frame without depth,
    a part that moved off an empty background: the fusion's vote on "is there depth"
    decides those).

    Parameters
    ----------
    registered : array_like (N, h, w)
        :func:`registered_samples` of the window.
    reference : array_like (h, w)
        The reference low-res frame (mm, 0 = no depth), after mixed-pixel removal.
    ref : int
        Index of the reference frame (never misregistered).
    edge_mm : float
        Depth step that separates two surfaces.
    offsets : array_like (N, h, w), optional
        Radial offsets (mm, :func:`upsr.method.trust.radial_offsets`) subtracted first.
    radius_px : int
        R (low-res px).
    min_count : int
        Fewest mismatching interior pixels.
    fraction : float
        Least share of the checked interior pixels that mismatch.

    Returns
    -------
    ndarray bool (N, h, w): True where frame k's samples do not vote (neither on depth nor on
    whether there is depth); all False for ``ref``.
    """
    reg = np.ascontiguousarray(registered, np.float32)
    n, h, w = reg.shape
    z = np.ascontiguousarray(reference, np.float32).reshape(h, w)
    z = np.where(np.isnan(z), np.float32(0.0), z)
    if offsets is None:
        offs = np.zeros((n, h, w), np.float32)
    else:
        offs = np.ascontiguousarray(offsets, np.float32).reshape(n, h, w)
    ref = check_ref(ref, n)
    out = np.empty((n, h, w), np.bool_)
    _mismatch_kernel(
        reg,
        z,
        offs,
        int(ref),
        float(edge_mm),
        int(radius_px),
        int(min_count),
        float(fraction),
        out,
    )
    return out


def thin_parts_followed(
    registered: npt.ArrayLike,
    anchor: npt.ArrayLike,
    tolerance: npt.ArrayLike,
    fronts: npt.ArrayLike,
    ref: int,
    *,
    edge_mm: float,
    offsets: npt.ArrayLike | None = None,
    min_trusted: int = 1,
    share: float = FOLLOWED_SHARE,
    maps: npt.ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Which thin parts in front the motion followed, and the frames that did not follow them.

    A thin part in front of a surface (:func:`upsr.method.alternatives.thin_fronts`) keeps its
    own samples in the fusion, so that a fast leg the flow lost is not voted away by the wall
    behind it; but where the flow did follow it, that fills its r×r blocks with it and widens
    it by up to r/2 px on each side. At such a pixel, frame k followed the part when its
    registered sample there (:func:`registered_samples`, minus the radial offset) lies within
    the pixel's tolerance of its anchor, and so do its samples at the neighbours along the
    part: the 8-neighbours that are thin parts in front on its surface (within ``edge_mm``), in
    the directions where that surface is 3 px wide or more (not across the part, where a
    sub-pixel shift takes an edge column's nearest sample off it); a rotating blade whose
    centre a frame reaches but not its length was not followed. The part counts as followed
    where, among the other frames with a sample in frame, at least ``share`` did, and with the
    reference at least ``min_trusted``: there the frames that did not follow it abstain, and
    the surfaces around it compete in the others
    (:func:`upsr.method.alternatives.surface_alternatives`, ``followed``). Elsewhere nothing
    changes.

    Parameters
    ----------
    registered : array_like (N, h, w)
        :func:`registered_samples` of the window (NaN: outside the frame).
    anchor, tolerance : array_like (h, w)
        The reference's anchor and tolerance (:func:`upsr.method.trust.reference_anchor`).
    fronts : array_like bool (h, w)
        The thin parts in front (:func:`upsr.method.alternatives.thin_fronts`).
    ref : int
        Index of the reference frame.
    edge_mm : float
        Depth step that separates two surfaces.
    offsets : array_like (N, h, w), optional
        Radial offsets (mm, :func:`upsr.method.trust.radial_offsets`) subtracted first.
    min_trusted : int
        Fewest samples on the part's surface, the reference's included.
    share : float
        Least share of the other frames in frame that followed the part.
    maps : array_like (N, s·h, s·w, 2), optional
        The window's motion on the flow grid: a frame whose motion spreads over the block of
        the part's pixel (or of a neighbour along it) by more than
        :data:`FOLLOWED_MAX_SPREAD_PX` (:func:`map_spread`) did not follow it there.

    Returns
    -------
    followed : ndarray bool (h, w)
    lost : ndarray bool (N, h, w)
        True where frame k did not follow a followed part (never for ``ref``): its samples
        there abstain, like those of a misregistered frame (:func:`misregistered`).
    """
    reg = np.asarray(registered, np.float32)
    n = reg.shape[0]
    ref = check_ref(ref, n)
    anc = np.ascontiguousarray(anchor, np.float32)
    anc = np.where(np.isnan(anc), np.float32(0.0), anc)
    tol = np.ascontiguousarray(tolerance, np.float32).reshape(anc.shape)
    offs = np.zeros(reg.shape, np.float32)
    if offsets is not None:
        offs = np.ascontiguousarray(offsets, np.float32).reshape(reg.shape)
    fronts = np.ascontiguousarray(fronts, np.bool_).reshape(anc.shape)
    mp = np.zeros((reg.shape[0], 0, 0, 2), np.float32)  # (none: no spread)
    if maps is not None:
        mp = np.ascontiguousarray(maps, np.float32)
    followed = np.zeros(anc.shape, np.bool_)
    lost = np.zeros(reg.shape, np.bool_)
    _followed_kernel(
        np.ascontiguousarray(reg), offs, mp, anc, tol, fronts, int(ref), float(edge_mm),
        int(min_trusted), float(share), followed, lost,
    )  # fmt: skip
    return followed, lost


@nb.njit(cache=True, nogil=True, inline="always")
def _follows(reg, offs, maps, anc, tol, k, ref, i, j):  # pragma: no cover - numba
    """(in frame, on the part's surface) for frame k's registered sample at (i, j), its
    motion (``maps``, or none: (N, 0, 0, 2)) spreading over the pixel's block by at most
    :data:`FOLLOWED_MAX_SPREAD_PX`."""
    v = reg[k, i, j] - offs[k, i, j]
    inside = k != ref and not np.isnan(v)
    own = inside and v > 0 and abs(v - anc[i, j]) <= tol[i, j]
    if own and maps.shape[1] > 0:
        own = _spread_at(maps, k, i, j, reg.shape[1], reg.shape[2]) <= FOLLOWED_MAX_SPREAD_PX
    return inside, own


@nb.njit(cache=True, nogil=True)
def _followed_kernel(
    reg, offs, maps, anc, tol, fronts, ref, edge, min_trusted, share, followed, lost
):  # pragma: no cover - numba
    n, h, w = reg.shape
    along = np.empty((8, 2), np.int64)
    for i in range(h):
        for j in range(w):
            if not (fronts[i, j] and anc[i, j] > 0):
                continue
            # its neighbours along it: thin parts on its surface in the directions where that
            # surface is 3 px wide or more, not beyond the image border (not across it: a
            # sub-pixel shift takes the nearest sample of an edge column off a thin part)
            a0 = anc[i, j]
            m = 0
            for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
                wide = _run(anc, i, j, -di, -dj, a0, edge, 2, False)
                wide += 1 + _run(anc, i, j, di, dj, a0, edge, 2, False)
                if wide < 3:
                    continue
                for sign in (-1, 1):
                    a, b = i + sign * di, j + sign * dj
                    if 0 <= a < h and 0 <= b < w and fronts[a, b] and anc[a, b] > 0:
                        if abs(anc[a, b] - a0) <= edge:
                            along[m, 0] = a
                            along[m, 1] = b
                            m += 1
            n_in = 0
            n_own = 0
            for k in range(n):
                inside, own = _follows(reg, offs, maps, anc, tol, k, ref, i, j)
                for q in range(m):
                    a, b = along[q, 0], along[q, 1]
                    q_in, q_own = _follows(reg, offs, maps, anc, tol, k, ref, a, b)
                    own = own and (q_own or not q_in)
                n_in += inside
                n_own += own
                lost[k, i, j] = inside and not own
            ok = n_own + 1 >= min_trusted and n_own >= share * n_in
            followed[i, j] = ok
            if not ok:
                for k in range(n):
                    lost[k, i, j] = False


def hole_backgrounds(reference: npt.ArrayLike, reach_px: int = HOLE_REACH_PX) -> np.ndarray:
    """At each pixel the reference did not measure (0 or NaN, not a removed pixel's negative
    marker), the farthest depth measured within ``reach_px`` of it through the hole (its 8
    neighbours with ``reach_px`` = 1; across a projector shadow several pixels wide, the
    background on its far side); 0 elsewhere and where none is in reach.

    Taking the farthest depth in reach for every pixel of the hole, those beside the body
    included, was measured against the 8 neighbours' for the pixels that have some (on the
    realistic Kinect scenes, seeds 0–2: the animal's rmse 71.9 / 71.2 / 72.4 against 73.4 /
    73.1 / 73.6 mm, the deforming body's 63.8 / 65.5 / 64.3 against 67.1 / 68.1 / 67.2; a
    silhouette beside a background with no return loses a little: Samba and the synthetic
    scenes, edge accuracy 0.1–0.3 points lower, missing depth up to 0.09 points higher).

    Parameters
    ----------
    reference : array_like (h, w)
        Low-res frame (mm; 0/NaN: no measurement; negative: a measurement that abstains).
    reach_px : int
        Steps (8-connected, low-res px) through the hole: :data:`HOLE_REACH_PX`.

    Returns
    -------
    ndarray float32 (h, w)
    """
    z = nan_as_zero(reference)
    ys, xs = np.nonzero(z == 0)
    # the measured depths (a removed pixel's negative marker: none) and, at the hole's
    # pixels, the farthest found so far: grown step by step over the hole's pixels only
    depth = np.ascontiguousarray(np.maximum(z, np.float32(0.0)), np.float32)
    _hole_reach_kernel(depth, ys, xs, max(int(reach_px), 1))
    far = np.zeros_like(depth)
    far[ys, xs] = depth[ys, xs]
    return far


@nb.njit(cache=True, nogil=True)
def _hole_reach_kernel(depth, ys, xs, steps):  # pragma: no cover - numba
    """``steps`` times at once (Jacobi: each step reads the previous one's values), each hole
    pixel (ys, xs) takes the largest of ``depth`` over its 3×3 (a grey dilation masked to the
    hole), in place. Only the hole pixels beside one that changed in the step before can
    change (the values only grow): each step visits those (the work follows the front)."""
    h, w = depth.shape
    n = ys.size
    hole = np.zeros((h, w), np.bool_)
    for q in range(n):
        hole[ys[q], xs[q]] = True
    seen = np.full((h, w), -1, np.int32)  # the step a pixel was last put on the front
    front_y = ys.copy()  # step 1: every hole pixel
    front_x = xs.copy()
    m_front = n
    grown = np.empty(n, np.float32)
    next_y = np.empty(n, ys.dtype)
    next_x = np.empty(n, xs.dtype)
    for step in range(steps):
        m_changed = 0
        for q in range(m_front):
            y, x = front_y[q], front_x[q]
            m = np.float32(0.0)
            for yy in range(max(y - 1, 0), min(y + 2, h)):
                for xx in range(max(x - 1, 0), min(x + 2, w)):
                    m = max(m, depth[yy, xx])
            if m != depth[y, x]:
                grown[m_changed] = m
                next_y[m_changed] = y
                next_x[m_changed] = x
                m_changed += 1
        if m_changed == 0:
            return
        for q in range(m_changed):
            depth[next_y[q], next_x[q]] = grown[q]
        # the next front: the hole pixels around those that changed
        m_front = 0
        for q in range(m_changed):
            y, x = next_y[q], next_x[q]
            for yy in range(max(y - 1, 0), min(y + 2, h)):
                for xx in range(max(x - 1, 0), min(x + 2, w)):
                    if hole[yy, xx] and seen[yy, xx] != step:
                        seen[yy, xx] = step
                        front_y[m_front] = yy
                        front_x[m_front] = xx
                        m_front += 1


def enclosed_holes(
    frame: npt.ArrayLike,
    radius_px: int = ENCLOSED_RADIUS_PX,
    share: float = ENCLOSED_SHARE,
) -> np.ndarray:
    """Holes inside a measured area: the pixels ``frame`` did not measure (0 or NaN) whose
    (2·``radius_px`` + 1)² window, as far as it lies inside the image, the frame measured for
    at least ``share`` of its pixels (a dropout, a projector shadow beside a body), not an open
    region where nothing returns (no wall behind a body, the sky, beyond the range).

    Parameters
    ----------
    frame : array_like (h, w)
        Low-res depth (mm; 0 or NaN: no measurement).
    radius_px : int
        Half-side of the window (low-res px).
    share : float
        Least measured share of the window.

    Returns
    -------
    ndarray bool (h, w)
    """
    z = nan_as_zero(frame)
    measured = (z > 0).astype(np.float32)
    side = 2 * int(radius_px) + 1
    kw = {"normalize": False, "borderType": cv2.BORDER_CONSTANT}
    seen = cv2.boxFilter(measured, -1, (side, side), **kw)
    inside = cv2.boxFilter(np.ones_like(measured), -1, (side, side), **kw)
    return (measured == 0) & (seen >= np.float32(share) * inside)


@nb.njit(cache=True, nogil=True, inline="always")
def _nearer_beside(meas, i, j, di, dj, limit):  # pragma: no cover - numba
    """Some low-res neighbour of block (i, j) on the side (di, dj) of its centre (an output
    pixel's quadrant; 0: the centre row or column of an odd block) measured a depth nearer
    than ``limit``: a surface that may reach into that part of the block."""
    h, w = meas.shape
    for ni, nj in ((i + di, j), (i, j + dj), (i + di, j + dj)):
        if (ni == i and nj == j) or ni < 0 or ni >= h or nj < 0 or nj >= w:
            continue
        u = meas[ni, nj]
        if u > 0 and u < limit:
            return True
    return False


@nb.njit(cache=True, nogil=True, inline="always")
def _block_side(y, scale):  # pragma: no cover - numba
    """The low-res index of high-res index ``y`` and the side (−1, 0 or 1) of its block's
    centre it lies on (0: the centre row or column of an odd block)."""
    i = y // scale
    s = y - i * scale
    half = scale // 2
    return i, (0 if (scale % 2 == 1 and s == half) else (-1 if s < half else 1))


@nb.njit(cache=True, nogil=True)
def _block_sides(n, scale):  # pragma: no cover - numba
    """:func:`_block_side` of the indices 0 … n − 1: (low-res indices, sides), int64 (n,)."""
    low = np.empty(n, np.int64)
    side = np.empty(n, np.int64)
    for y in range(n):
        low[y], side[y] = _block_side(y, scale)
    return low, side


@nb.njit(cache=True, nogil=True, parallel=True)
def _stale_kernel(fused, ref, scale, edge, out):  # pragma: no cover - numba
    hh, ww = fused.shape
    js, djs = _block_sides(ww, scale)  # (not an integer division per pixel)
    for y in nb.prange(hh):
        i, di = _block_side(y, scale)
        for x in range(ww):
            v = fused[y, x]
            out[y, x] = v
            j = js[x]
            dj = djs[x]
            if ref[i, j] != 0.0 or not v > 0:
                continue
            if _nearer_beside(ref, i, j, di, dj, v - edge):
                out[y, x] = 0.0


def clear_stale_fills(
    fused: npt.ArrayLike, reference: npt.ArrayLike, scale: int, edge_mm: float
) -> np.ndarray:
    """Empty the fills of the reference's holes that lie more than ``edge_mm`` behind a
    surface it measured beside them, on that side of the block.

    Where the reference measured nothing (a Kinect projector shadow or dropout along the edge
    of a body), the other frames (or the recursive state) may show the wall that was there
    before the body moved in; the part of the hole's block towards a neighbour that measured
    a nearer surface may belong to that surface, so a fill there that lies more than
    ``edge_mm`` behind it is dropped (0: no depth) rather than given the wall. The far part
    of the block keeps it (the shadow's background). Realistic Kinect scenes, seeds 0–2:
    every wrongly filled pixel more than 100 mm off lay behind the truth (the wall where the
    body was, about 1.1 m); the figures of the rule are in the README.

    Parameters
    ----------
    fused : array_like (r·h, r·w)
        The fused depth (mm, 0 = none).
    reference : array_like (h, w)
        The reference frame (mm; 0/NaN: a hole; negative: a removed pixel, not a hole).
    scale : int
        SR factor r.
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    ndarray float32 (r·h, r·w)
    """
    f = np.ascontiguousarray(fused, np.float32)
    ref = nan_as_zero(reference)
    out = np.empty_like(f)
    _stale_kernel(f, np.ascontiguousarray(ref), int(scale), float(edge_mm), out)
    return out
