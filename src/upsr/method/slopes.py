"""Slanted surfaces: each output block follows the slope of its surface, never across an edge.

Beyond the paper. UP-SR's upsampling ``U`` (nearest neighbour, eq. 13) puts each low-res
sample on its whole r×r block; sub-pixel detail comes only from the other frames of the
window. Where they cannot give it (a camera moving through a room: walls, floor and ceiling
seen at grazing angles, whose samples the trust rules reject as misregistered or whose motion
the flow cannot follow), the output keeps the reference's r×r staircase: on the realistic room
of :mod:`upsr.research.synth.realistic` (ToF size, r = 4) its surface RMSE equals nearest
upsampling's (31 mm, bicubic: 11 mm), at every σ.

This step replaces the linear trend of each output block with the slope of its surface, as
measured on the reference's anchor (:func:`upsr.method.trust.reference_anchor`) between the
block and its 4-neighbours on the same surface (a first-order, plane-wise reconstruction):

* the slope across a block along x (y likewise) is the central difference of the anchor over
  the block's left and right neighbours, or the one-sided difference where only one of them
  lies on the block's surface; a link between two neighbours is on one surface when its step
  is at most ``edge_mm``, or when it belongs to a run of three agreeing steep steps (same
  sign, within a factor :data:`STEEP_RATIO`: a floor seen at a grazing angle, not the
  staircase of two depth edges), or when both links beside it step the same way within a
  factor :data:`FACE_RATIO` (the middle of a box's side seen obliquely, two or three pixels
  wide, whose end steps into the flat surfaces around it are partial; an occlusion edge has
  a flat side);
* the depths those differences are taken on are the anchor's, except inside a surface
  (all 8 neighbours measured, no depth edge beside the pixel), where the median is taken over
  a centrally symmetric neighbourhood (:func:`plane_anchor`): a surface that bends steeply on
  one side of a pixel (a box's top seen at a grazing angle meeting its front) would pull a
  one-sided median towards the other side;
* the slope is used only where it is significant (beyond :data:`SIGNIFICANCE` σ); elsewhere
  the block keeps its own trend (the sub-pixel detail the fusion found);
* only blocks whose every pixel lies on the block's surface are changed (within 3σ + 2 mm of
  the anchor, plus half the slope): never a block with a depth edge, a hole or another
  surface in it; the block's mean is kept.

So the output never takes a depth between two surfaces (a link across an edge gives no
slope), no depth is invented (0 stays 0) and on a surface the fusion resolved, whose blocks
already follow the slope, nothing changes. For a linear surface the block then follows the
truth exactly; the slope's noise (the anchor is a 3×3 median) adds about 0.1 σ at the block's
corners.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.method.noise import noise_at_depth
from upsr.method.sorting import _small_median
from upsr.method.validation import nan_as_zero

__all__ = [
    "FACE_RATIO",
    "MEASURED_SLOPE_SHARE",
    "SIGNIFICANCE",
    "STEEP_RATIO",
    "edge_ends",
    "follow_slopes",
    "plane_anchor",
    "plane_slopes",
    "sloped_pixels",
    "surface_slopes",
]

#: A slope is used where it exceeds this many σ (mm per low-res px).
SIGNIFICANCE = 2.0
#: Consecutive steep steps (beyond the edge threshold) of one slope agree within this factor.
STEEP_RATIO = 1.5
#: A steep step between two steps of the same sign, each within this factor of it, is the
#: middle of a face seen obliquely (two or more pixels on it: its end steps into the flat
#: surfaces around it are partial, so the run is not even); an occlusion edge has a flat side.
FACE_RATIO = 3.0
#: Where the anchor gives a pixel no slope, the slope of the frame as measured is used when it
#: exceeds this share of the edge threshold per low-res px (and 4σ): a face seen at a grazing
#: angle, two or three pixels wide, whose ramp the anchor's 3×3 median pulls towards the flat
#: surfaces beside it (measured 2409 / 2333 / 2170 / 2069 mm across a box side, anchor 2392 /
#: 2362 / 2170 / 2040: the face rule no longer joins its links). Realistic scenes, seeds
#: 0 / 1 / 2, surface rmse geomean −1.0 / −0.2 / −0.2 % windowed, −1.3 / −0.6 / −0.6 %
#: recursive (room and approaching camera up to −6 %); with 1/4 the recursive Kinect body
#: +3.5 … +3.9 %; the measured slope everywhere: flat moving bodies +15 … +80 % (its noise).
MEASURED_SLOPE_SHARE = 0.5
#: Consecutive steps of a steep run (:func:`_steep_run`) agree within this factor: a floor
#: seen at a grazing angle steps evenly (pairs of consecutive steps beyond 100 mm on the clean
#: realistic room at 64×56: ratio 1.1 at the median, 1.45 at the 90th percentile), a line of
#: mixed pixels beside a steep surface does not (on the ToF room the step from such a line
#: into a box's top is 2.4 times the next one).
STEEP_RUN_RATIO = 2.0
#: The pixel's own step into a steep run agrees with the next one within this factor: a line
#: of mixes between a floor seen at a grazing angle (steps of 170–180 mm per pixel at 64×56)
#: and a nearer surface steps 1.8 times the floor's step from it, mostly floor, and passed for
#: the floor's run. Realistic ToF room, seeds 0–4 (``benchmarks/realistic_eval.py --quick
#: --no-oracle [--tof-sigma 20 --tof-dropout 0.01 | --tof-sigma 30] --seed S``): see the
#: README's depth rules; 1.5 removed more such lines but cost up to +1 % rmse and +3 %
#: moving-surface rmse.
STEEP_FIRST_RATIO = 1.7


@nb.njit(cache=True, nogil=True, inline="always")
def _steps_agree(s, t, ratio=3.0):  # pragma: no cover - numba
    """Two consecutive depth steps of one slope: same sign, within a factor ``ratio``."""
    if s == 0.0 or t == 0.0 or (s > 0) != (t > 0):
        return False
    a, b = abs(s), abs(t)
    return max(a, b) <= ratio * min(a, b)


@nb.njit(cache=True, nogil=True, inline="always")
def _steep_run(z, i, j, di, dj, step, edge):  # pragma: no cover - numba
    """The two steps beyond the neighbour (i + di, j + dj) continue ``step`` (its step from
    (i, j)) in direction (di, dj), each beyond the edge threshold and agreeing with the last
    (the first within :data:`STEEP_FIRST_RATIO`)."""
    h, w = z.shape
    last = z[i + di, j + dj]
    for s in (2, 3):
        a = i + s * di
        b = j + s * dj
        if not (0 <= a < h and 0 <= b < w and z[a, b] > 0):
            return False
        t = z[a, b] - last
        ratio = STEEP_FIRST_RATIO if s == 2 else STEEP_RUN_RATIO
        if abs(t) <= edge or not _steps_agree(step, t, ratio):
            return False
        step = t
        last = z[a, b]
    return True


@nb.njit(cache=True, nogil=True, inline="always")
def _across_on_surface(z, i, j, pi, pj, di, dj, edge):  # pragma: no cover - numba
    """Some neighbour of (i, j) across the direction (di, dj) (its two neighbours at
    ±(pi, pj)) lies within ``edge`` of it and continues the slope there (one of its own steps
    along (di, dj) agrees with the step of (i, j) that way), or neither has depth: a slope's
    rows run on across it. A leg crossing the pixel grid at a slant makes a ramp of mixed
    pixels along a column, and across it the wall and the next ramp, which does not step
    the same way (on the realistic galloping animal, ToF, seeds 0–2, windowed: flying pixels
    4.0 / 3.8 / 3.0 → 2.0 / 2.3 / 1.5 %, edge accuracy 89.9 / 89.3 / 90.6 → 91.7 / 90.6 /
    91.9 %)."""
    h, w = z.shape
    v = z[i, j]
    step = z[i + di, j + dj] - v
    back = v - z[i - di, j - dj]
    seen = False
    for s in (-1, 1):
        a = i + s * pi
        b = j + s * pj
        if not (0 <= a < h and 0 <= b < w and z[a, b] > 0):
            continue
        seen = True
        u = z[a, b]
        if abs(u - v) > edge:
            continue
        for t in (-1, 1):
            c = a + t * di
            d = b + t * dj
            if 0 <= c < h and 0 <= d < w and z[c, d] > 0:
                if _steps_agree(t * (z[c, d] - u), step if t > 0 else back):
                    return True
    return not seen


@nb.njit(cache=True, nogil=True)
def _on_slope(z, i, j, edge):  # pragma: no cover - numba
    """True when, along a row, column or diagonal, the pixel (i, j) continues a slanted surface
    whose steps between neighbours can exceed the edge threshold (a floor seen at a grazing
    angle): its two neighbours step through depth evenly with it, and so do the steps beyond
    both of them, or, on one side, the next two steps, all beyond the edge threshold (a steep
    slope that begins at another surface), or, along a row or column, the step beyond one of
    them agrees with the pixel's step to it and stays within the edge threshold (a slope
    that tapers into a flat surface: a box side seen at a grazing angle, two pixels wide; a
    footprint straddles a depth edge in one pixel per row or column); and across that
    direction the pixel has a neighbour on its own surface (the slope's row). A mixed pixel
    sits between two flat runs, ends a ramp of at most two mixed pixels across a ToF edge,
    or belongs to a line of them along the edge (even along the line, between two surfaces
    across it). A run of five pixels counts only where the pixel's smaller step is at most
    :data:`STEEP_RUN_RATIO` times the step beyond it on that side, or that step stays within
    the edge threshold: a strip one pixel high between a wall and a slope straddles two
    pixels, and the second (mostly slope, partly strip) steps into the slope further than the
    slope steps on."""
    h, w = z.shape
    v = z[i, j]
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        ia, ja, ib, jb = i - di, j - dj, i + di, j + dj
        if min(ia, ib) < 0 or max(ia, ib) >= h or min(ja, jb) < 0 or max(ja, jb) >= w:
            continue
        a, b = z[ia, ja], z[ib, jb]
        if not (a > 0 and b > 0) or not _steps_agree(v - a, b - v):
            continue
        if not _across_on_surface(z, i, j, dj, -di, di, dj, edge):
            continue  # a line of mixed pixels along an edge: even along it, torn across it
        if _steep_run(z, i, j, di, dj, b - v, edge) or _steep_run(z, i, j, -di, -dj, a - v, edge):
            return True
        # or the steps beyond both neighbours agree (a slope of five pixels or more)
        ic, jc, ie, je = i - 2 * di, j - 2 * dj, i + 2 * di, j + 2 * dj
        if not (0 <= ic < h and 0 <= jc < w and 0 <= ie < h and 0 <= je < w):
            continue
        c, e = z[ic, jc], z[ie, je]
        if not (c > 0 and e > 0):
            continue
        if _steps_agree(a - c, v - a) and _steps_agree(b - v, e - b):
            # (on the side of the pixel's smaller step the slope runs on, or tapers)
            small, beyond = (b - v, e - b) if abs(v - a) >= abs(b - v) else (v - a, a - c)
            if abs(beyond) <= edge or abs(small) <= STEEP_RUN_RATIO * abs(beyond):
                return True
        # or, along a row or column, the slope tapers into a flat surface on one side: the
        # step beyond one neighbour agrees with the pixel's step to it and stays within the
        # edge threshold (a face seen at a grazing angle, two pixels wide between a wall and
        # a box front); a footprint straddles a depth edge in one pixel per row or column
        if (di == 0 or dj == 0) and (
            (abs(a - c) <= edge and _steps_agree(a - c, v - a))
            or (abs(e - b) <= edge and _steps_agree(e - b, b - v))
        ):
            return True
    return False


@nb.njit(cache=True, nogil=True, inline="always")
def _step(row, k):  # pragma: no cover - numba
    """Step of link k (pixels k and k + 1) of a row; NaN where either has no depth or the link
    leaves the row."""
    if k < 0 or k + 1 >= row.shape[0]:
        return np.nan
    a = row[k]
    b = row[k + 1]
    return b - a if (a > 0 and b > 0) else np.nan


@nb.njit(cache=True, nogil=True, inline="always")
def _agree(s, t):  # pragma: no cover - numba
    """Two consecutive steps of one slope (:func:`upsr.method.mixed._steps_agree` within
    :data:`STEEP_RATIO`); False for a missing step."""
    return s == s and t == t and _steps_agree(s, t, STEEP_RATIO)


@nb.njit(cache=True, nogil=True, inline="always")
def _link(row, k, edge, kept):  # pragma: no cover - numba
    """The step of link k where it joins one surface (at most ``edge``, a steep link in a
    run of three agreeing links, or the middle of a face, where ``kept`` holds both its
    pixels), else NaN."""
    s = _step(row, k)
    if s != s or abs(s) <= edge:
        return s
    b2, b1, a1, a2 = _step(row, k - 2), _step(row, k - 1), _step(row, k + 1), _step(row, k + 2)
    before = _agree(b1, s)
    after = _agree(s, a1)
    if (before and after) or (before and _agree(b2, b1)) or (after and _agree(a1, a2)):
        return s
    if (
        kept[k]
        and kept[k + 1]
        and b1 == b1
        and a1 == a1
        and _steps_agree(b1, s, FACE_RATIO)
        and _steps_agree(s, a1, FACE_RATIO)
    ):
        return s  # the middle of a face
    return np.nan


@nb.njit(cache=True, nogil=True, parallel=True)
def _slopes_kernel(z, edge, kept, out):  # pragma: no cover - numba
    h, w = z.shape
    for i in nb.prange(h):
        row = z[i]
        krow = kept[i]
        # links[k + 1]: link k of the row (k = −1 … w − 1; NaN beyond it), each computed
        # once for the two pixels it joins
        links = np.empty(w + 1, np.float64)
        for k in range(-1, w):
            links[k + 1] = _link(row, k, edge, krow)
        for j in range(w):
            if not row[j] > 0:
                out[i, j] = 0.0
                continue
            left = links[j]
            right = links[j + 1]
            if left != left:
                out[i, j] = 0.0 if right != right else right
            elif right != right:
                out[i, j] = left
            else:
                out[i, j] = 0.5 * (left + right)


def _slope_along_rows(z: np.ndarray, edge_mm: float, kept: np.ndarray) -> np.ndarray:
    """Slope (mm per px) of ``z`` along its rows, on one surface (see the module)."""
    out = np.empty(z.shape, np.float32)
    _slopes_kernel(
        np.ascontiguousarray(z, np.float32), float(edge_mm), np.ascontiguousarray(kept), out
    )
    return out


def surface_slopes(
    anchor: npt.ArrayLike, edge_mm: float, kept: npt.ArrayLike | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Slopes of the reference's surfaces on the low-res grid, never across a depth edge.

    Parameters
    ----------
    anchor : array_like (h, w)
        Depth (mm, 0 = none), usually :func:`upsr.method.trust.reference_anchor`.
    edge_mm : float
        Depth step that separates two surfaces.
    kept : array_like of bool (h, w), optional
        The pixels a link may join as the middle of a face (:data:`FACE_RATIO`); default
        all. A link with a pixel outside joins one surface only within ``edge_mm`` or in a
        steep run.

    Returns
    -------
    (slope_y, slope_x) : ndarray float32 (h, w)
        mm per low-res px along rows (y) and columns (x): central differences over the two
        neighbours on the pixel's surface, one-sided where one neighbour is on another
        surface or has no depth, 0 where neither is (see the module for "one surface").

    Examples
    --------
    >>> a = np.array([[1000.0, 1010.0, 1020.0, 3000.0]])
    >>> sy, sx = surface_slopes(a, 100.0)
    >>> sx.tolist()
    [[10.0, 10.0, 10.0, 0.0]]
    """
    z = nan_as_zero(anchor)
    k = np.ones(z.shape, np.bool_) if kept is None else np.asarray(kept, np.bool_)
    if k.shape != z.shape:
        raise ValueError(f"kept {k.shape} and anchor {z.shape} differ in shape")
    return _slope_along_rows(z.T, edge_mm, k.T).T, _slope_along_rows(z, edge_mm, k)


@nb.njit(cache=True, nogil=True, parallel=True)
def _follow_kernel(depth, anchor, sy, sx, scale, sigma, out):  # pragma: no cover - numba
    h, w = anchor.shape
    r = scale
    d = np.empty(r, np.float64)  # offset of each pixel from its block's centre (low-res px)
    for a in range(r):
        d[a] = (a - 0.5 * (r - 1)) / r
    dd = 0.0
    for a in range(r):
        dd += d[a] * d[a]
    dd *= r  # sum over the block of d_x² (and of d_y²)
    thr = SIGNIFICANCE * sigma  # (noise-free data: every non-zero slope)
    for i in nb.prange(h):
        for j in range(w):
            a0 = anchor[i, j]
            if not a0 > 0:
                continue
            gx = sx[i, j]
            gy = sy[i, j]
            use_x = abs(gx) > thr
            use_y = abs(gy) > thr
            if not (use_x or use_y):
                continue
            lim = 3.0 * sigma + 2.0 + 0.5 * (abs(gx) + abs(gy))
            total = 0.0
            ok = True
            for y in range(i * r, i * r + r):
                for x in range(j * r, j * r + r):
                    v = depth[y, x]
                    if not (v > 0 and abs(v - a0) <= lim):
                        ok = False
                    total += v
            if not ok:
                continue
            mean = total / (r * r)
            tx = 0.0
            ty = 0.0
            for b in range(r):
                for c in range(r):
                    e = depth[i * r + b, j * r + c] - mean
                    tx += e * d[c]
                    ty += e * d[b]
            cx = gx - tx / dd if use_x else 0.0
            cy = gy - ty / dd if use_y else 0.0
            # never through the camera: a block a few mm away on a steep slope (a sensor's
            # stray near values) keeps its depths rather than reach 0 or below
            low = np.inf
            for b in range(r):
                for c in range(r):
                    low = min(low, depth[i * r + b, j * r + c] + cx * d[c] + cy * d[b])
            if not low > 0:
                continue
            for b in range(r):
                for c in range(r):
                    y = i * r + b
                    x = j * r + c
                    out[y, x] = depth[y, x] + cx * d[c] + cy * d[b]


def follow_slopes(
    depth_mm: npt.ArrayLike,
    anchor: npt.ArrayLike,
    *,
    sigma_mm: float,
    edge_mm: float,
    frame: npt.ArrayLike | None = None,
    measured: npt.ArrayLike | None = None,
    slopes: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """The output frame with each block's linear trend set to its surface's slope.

    Parameters
    ----------
    depth_mm : array_like (r·h, r·w)
        Super-resolved frame (mm, 0 = none).
    anchor : array_like (h, w)
        The reference's anchor (:func:`upsr.method.trust.reference_anchor`, mm, 0 = none).
    sigma_mm : float
        Noise std of the video (mm): slopes below :data:`SIGNIFICANCE` σ are not used.
    edge_mm : float
        Depth step that separates two surfaces.
    frame : array_like (h, w), optional
        The reference frame itself (mm, ≤ 0 = none): the slopes are taken on
        :func:`plane_anchor` (the pixels inside their surface over a symmetric neighbourhood),
        and where that gives a pixel no slope, the frame's slope when steeper than
        :data:`MEASURED_SLOPE_SHARE` · ``edge_mm`` and 4σ per low-res px (a face seen at a
        grazing angle).
    measured : array_like (h, w), optional
        With ``frame``: the reference as measured, before its mixed pixels and lone
        outliers were removed (mm, ≤ 0 = none). The frame's slope is read on it where it
        gives one, with the links into a removed pixel joining one surface only within
        ``edge_mm`` or in a steep run, never as the middle of a face (a staircase of mixes
        across a ToF edge steps like one): a surface seen at a grazing angle whose first
        pixel, beside the wall behind it, the mixed-pixel test removed still follows its
        slope (:func:`upsr.method.mixed.remove_mixed_pixels` cannot tell that pixel from a
        mix).
    slopes : (ndarray, ndarray), optional
        With ``frame``: :func:`plane_slopes` of ``frame`` and ``anchor``, when already
        computed.

    Returns
    -------
    ndarray float32 (r·h, r·w): a new frame; pixels without depth stay 0.

    Examples
    --------
    A ramp seen as a staircase of 2×2 blocks becomes the ramp:

    >>> low = np.array([[1000.0, 1040.0, 1080.0, 1120.0]] * 3)
    >>> up = np.repeat(np.repeat(low, 2, axis=0), 2, axis=1)
    >>> follow_slopes(up, low, sigma_mm=0.0, edge_mm=100.0)[2, 2:6].tolist()
    [1030.0, 1050.0, 1070.0, 1090.0]
    """
    z = np.array(depth_mm, np.float32)  # the output, changed block by block in place
    if not np.isfinite(z).all():
        np.nan_to_num(z, copy=False, nan=0.0)
    a = nan_as_zero(anchor)
    h, w = a.shape
    if z.shape[0] % h or z.shape[1] % w or z.shape[0] // h != z.shape[1] // w:
        raise ValueError(f"depth {z.shape} is not a whole multiple of the anchor {a.shape}")
    if z.shape[0] == h:
        return z  # r = 1: a block is one pixel, without a trend
    if frame is None:
        sy, sx = surface_slopes(a, edge_mm)
    else:
        m = nan_as_zero(frame)
        sy, sx = plane_slopes(m, a, edge_mm, sigma_mm) if slopes is None else slopes
        my, mx = surface_slopes(np.where(m > 0, m, np.float32(0.0)), edge_mm)
        if measured is not None:
            full = nan_as_zero(measured)
            if full.shape != m.shape:
                raise ValueError(f"measured {full.shape} and frame {m.shape} differ in shape")
            extra = (full > 0) & ~(m > 0)  # the removed pixels
            if extra.any():
                full = np.where(full > 0, full, np.float32(0.0))
                fy, fx = surface_slopes(full, edge_mm, kept=~extra)
                my = np.where(fy != 0, fy, my).astype(np.float32)
                mx = np.where(fx != 0, fx, mx).astype(np.float32)
        steep = max(MEASURED_SLOPE_SHARE * float(edge_mm), 4.0 * max(float(sigma_mm), 0.0))
        sy = np.where((sy == 0) & (np.abs(my) > steep), my, sy).astype(np.float32)
        sx = np.where((sx == 0) & (np.abs(mx) > steep), mx, sx).astype(np.float32)
    # (each block is read whole before it is written: in place is safe)
    _follow_kernel(z, a, sy, sx, z.shape[0] // h, max(float(sigma_mm), 0.0), z)
    return z


@nb.njit(cache=True, nogil=True, inline="always")
def _border_anchor(z, i, j, c, edge, gate, buf):  # pragma: no cover - numba
    """The anchor ``c`` of a pixel on the image's border (not a corner): the median of itself
    and its two neighbours along the border where all its neighbours are measured, those two
    lie within ``edge`` of ``c`` and that median lies more than ``gate`` from ``c``; else
    ``c`` (:func:`plane_anchor`)."""
    h, w = z.shape
    for di in range(-1, 2):
        for dj in range(-1, 2):
            a, b = i + di, j + dj
            if 0 <= a < h and 0 <= b < w and not (z[a, b] > 0):
                return c
    along_rows = i == 0 or i == h - 1
    if along_rows == (j == 0 or j == w - 1):  # a corner: no symmetric pair
        return c
    di, dj = (0, 1) if along_rows else (1, 0)
    u = z[i - di, j - dj]
    v = z[i + di, j + dj]
    if abs(u - c) > edge or abs(v - c) > edge or abs(z[i, j] - c) > edge:
        return c
    buf[0] = u
    buf[1] = z[i, j]
    buf[2] = v
    b = _small_median(buf, 3)
    return b if abs(b - c) > gate else c


@nb.njit(cache=True, nogil=True, parallel=True)
def _plane_kernel(z, anchor, ends, edge, gate, out):  # pragma: no cover - numba
    h, w = z.shape
    for i in nb.prange(h):
        buf = np.empty(9, np.float32)
        for j in range(w):
            c = anchor[i, j]
            out[i, j] = c
            if not (c > 0) or ends[i, j]:
                continue
            if i == 0 or j == 0 or i == h - 1 or j == w - 1:
                out[i, j] = _border_anchor(z, i, j, c, edge, gate, buf)
                continue
            inside = True  # all 8 neighbours measured
            bent = False  # one beyond the edge threshold: the anchor is one-sided
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    v = z[i + di, j + dj]
                    inside &= v > 0
                    bent |= abs(v - c) > edge
            if not (inside and bent):
                continue
            m = 0
            if abs(z[i, j] - c) <= edge:
                buf[0] = z[i, j]
                m = 1
            for di, dj in ((0, 1), (1, -1), (1, 0), (1, 1)):
                a = z[i + di, j + dj]
                b = z[i - di, j - dj]
                if abs(a - c) <= edge and abs(b - c) <= edge:
                    buf[m] = a
                    buf[m + 1] = b
                    m += 2
            if m > 0:
                out[i, j] = _small_median(buf, m)


def plane_anchor(
    frame: npt.ArrayLike, anchor: npt.ArrayLike, edge_mm: float, sigma_mm: float = 0.0
) -> np.ndarray:
    """The anchor, with each pixel inside its surface taken over a symmetric neighbourhood.

    The anchor (:func:`upsr.method.trust.reference_anchor`) is the median of the 3×3
    neighbours on the pixel's surface. Where the surface bends steeply on one side, the
    neighbours there lie beyond ``edge_mm`` and drop out: the median is then taken over one
    side and leans towards it (a box's top seen at a grazing angle, 122 mm per pixel, meeting
    its front face: 2267 → 2234 mm at σ = 0), and the slopes beside that pixel are wrong.
    Here a pixel inside its surface with a neighbour (or itself) beyond ``edge_mm`` of its
    anchor takes the median of itself and of the pairs of opposite 8-neighbours that both lie
    within ``edge_mm`` of the anchor: a centrally symmetric neighbourhood, in which a plane
    keeps its depth. The rims of a surface keep their anchor
    (beside a depth edge or a pixel without depth, the symmetric neighbourhood of a curved
    body's silhouette makes its slopes steeper than its blocks: Samba, r = 4, σ = 50,
    rmse +0.9 %).

    Parameters
    ----------
    frame : array_like (h, w)
        The reference frame (mm; ≤ 0 or NaN: none).
    anchor : array_like (h, w)
        Its anchor (mm, 0 = none).
    edge_mm : float
        Depth step that separates two surfaces.
    sigma_mm : float
        Noise std (mm). On the image's border (its surfaces go on beyond it) the 3×3 anchor
        is one-sided too: on a slope across the border it leans half a pixel's step inwards.
        There the anchor is the median of the pixel and its two neighbours along the border
        where all its neighbours are measured and that median lies more than ``sigma_mm``
        from the anchor (on a flat surface the median of 6 is the less noisy; the corners
        keep theirs).

    Returns
    -------
    ndarray float32 (h, w): the anchor, re-centred on the pixels inside their surface (all
    8 neighbours measured, no end of a depth edge, :func:`edge_ends`) and where the border
    leans; 0 where it is 0.

    Examples
    --------
    >>> col = np.array([1000.0, 1150.0, 1300.0, 1450.0, 1500.0, 1550.0, 1600.0])
    >>> z = np.repeat(col[:, None], 3, axis=1)  # steps of 150 mm, then of 50 mm
    >>> from upsr.method.trust import reference_anchor
    >>> a = reference_anchor(z, 1.0, 3.0, 100.0)[0]
    >>> float(a[3, 1]), float(plane_anchor(z, a, 100.0)[3, 1])
    (1475.0, 1450.0)
    """
    z = nan_as_zero(frame)
    a = nan_as_zero(anchor)
    if z.shape != a.shape:
        raise ValueError(f"frame {z.shape} and anchor {a.shape} differ in shape")
    ends = edge_ends(z, edge_mm)
    out = np.empty(z.shape, np.float32)
    gate, edge = max(float(sigma_mm), 0.0), float(edge_mm)
    _plane_kernel(np.ascontiguousarray(z), np.ascontiguousarray(a), ends, edge, gate, out)
    return out


@nb.njit(cache=True, nogil=True)
def _edge_ends_kernel(z, edge, out):  # pragma: no cover - numba
    h, w = z.shape
    every = np.ones(w, np.bool_)
    for i in range(h):
        row = z[i]
        for k in range(w - 1):
            if abs(row[k + 1] - row[k]) > edge and row[k] > 0 and row[k + 1] > 0:
                s = _link(row, k, edge, every)
                if s != s:  # NaN: no surface joins them
                    out[i, k] = True
                    out[i, k + 1] = True


def edge_ends(depth_mm: npt.ArrayLike, edge_mm: float) -> np.ndarray:
    """The pixels at either end of a depth edge: a 4-neighbour step beyond ``edge_mm`` that
    no surface joins (not a steep slope nor a face seen obliquely, see the module).

    Parameters
    ----------
    depth_mm : array_like (h, w)
        Depth (mm; ≤ 0 or NaN: none).
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    ndarray bool (h, w)

    Examples
    --------
    >>> edge_ends(np.array([[1000.0, 1000.0, 3000.0, 3000.0]]), 100.0).astype(int).tolist()
    [[0, 1, 1, 0]]
    >>> floor = np.array([[1000.0, 1150.0, 1300.0, 1450.0]])  # even steps: one surface
    >>> edge_ends(floor, 100.0).any()
    np.False_
    """
    z = nan_as_zero(depth_mm)
    out = np.zeros(z.shape, np.bool_)
    _edge_ends_kernel(np.ascontiguousarray(z), float(edge_mm), out)
    rows = np.zeros(z.shape[::-1], np.bool_)
    _edge_ends_kernel(np.ascontiguousarray(z.T), float(edge_mm), rows)
    return out | rows.T


def plane_slopes(
    frame: npt.ArrayLike, anchor: npt.ArrayLike, edge_mm: float, sigma_mm: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """(slope_y, slope_x) of :func:`surface_slopes` on the :func:`plane_anchor` of ``frame``
    and its ``anchor`` (h, w, mm, 0 = none): the slopes :func:`follow_slopes` gives the blocks
    (before the frame's own steep slopes); ``sigma_mm``: :func:`plane_anchor`'s."""
    plane = plane_anchor(nan_as_zero(frame), nan_as_zero(anchor), edge_mm, sigma_mm)
    return surface_slopes(plane, edge_mm)


def sloped_pixels(
    anchor: npt.ArrayLike,
    slopes: tuple[np.ndarray, np.ndarray],
    sigma_mm: float,
    *,
    noise_profile: tuple[float, float] | None = None,
    significance: float = SIGNIFICANCE,
) -> np.ndarray:
    """The pixels on a significant slope: the slope (``slopes``, mm per low-res px, usually
    :func:`plane_slopes`; the root sum of squares of its two components) beyond
    ``significance`` σ, the σ at the anchor's depth with a ``noise_profile`` (σ₁, p):
    σ₁·(z / 1 m)^p.

    Parameters
    ----------
    anchor : array_like (h, w)
        The frame's anchor (:func:`upsr.method.trust.reference_anchor`), mm, 0 = none.
    slopes : (ndarray, ndarray) float (h, w)
        (slope_y, slope_x), mm per low-res px.
    sigma_mm : float
        Noise std (mm) without a profile.
    noise_profile : (float, float), optional
        (σ₁, p) of σ(z) = σ₁·(z / 1 m)^p, used where p > 0.
    significance : float
        Slopes beyond this many σ count (default :data:`SIGNIFICANCE`, the finishing's).

    Returns
    -------
    ndarray of bool (h, w)

    Examples
    --------
    >>> ramp = np.tile(1000.0 + 50.0 * np.arange(6), (5, 1))
    >>> slopes = plane_slopes(ramp, ramp, 100.0)
    >>> sloped_pixels(ramp, slopes, 10.0)[2].tolist()
    [True, True, True, True, True, True]
    >>> bool(sloped_pixels(ramp, slopes, 30.0).any())
    False
    >>> bool(sloped_pixels(ramp, slopes, 30.0, significance=1.0).all())
    True
    """
    a = nan_as_zero(anchor)
    sigma = np.float32(max(float(sigma_mm), 0.0))
    if noise_profile is not None and noise_profile[1] > 0:
        sigma = noise_at_depth(a, *noise_profile)
    return (a > 0) & (np.hypot(*slopes) > significance * sigma)
