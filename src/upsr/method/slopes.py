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

from upsr.method.mixed import _steps_agree

__all__ = [
    "FACE_RATIO",
    "SIGNIFICANCE",
    "STEEP_RATIO",
    "edge_ends",
    "follow_slopes",
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
def _link(row, k, edge):  # pragma: no cover - numba
    """The step of link k where it joins one surface (at most ``edge``, a steep link in a
    run of three agreeing links, or the middle of a face), else NaN."""
    s = _step(row, k)
    if s != s or abs(s) <= edge:
        return s
    b2, b1, a1, a2 = _step(row, k - 2), _step(row, k - 1), _step(row, k + 1), _step(row, k + 2)
    before = _agree(b1, s)
    after = _agree(s, a1)
    if (before and after) or (before and _agree(b2, b1)) or (after and _agree(a1, a2)):
        return s
    if (
        b1 == b1
        and a1 == a1
        and _steps_agree(b1, s, FACE_RATIO)
        and _steps_agree(s, a1, FACE_RATIO)
    ):
        return s  # the middle of a face
    return np.nan


@nb.njit(cache=True, nogil=True, parallel=True)
def _slopes_kernel(z, edge, out):  # pragma: no cover - numba
    h, w = z.shape
    for i in nb.prange(h):
        row = z[i]
        for j in range(w):
            if not row[j] > 0:
                out[i, j] = 0.0
                continue
            left = _link(row, j - 1, edge)
            right = _link(row, j, edge)
            if left != left:
                out[i, j] = 0.0 if right != right else right
            elif right != right:
                out[i, j] = left
            else:
                out[i, j] = 0.5 * (left + right)


def _slope_along_rows(z: np.ndarray, edge_mm: float) -> np.ndarray:
    """Slope (mm per px) of ``z`` along its rows, on one surface (see the module)."""
    out = np.empty(z.shape, np.float32)
    _slopes_kernel(np.ascontiguousarray(z, np.float32), float(edge_mm), out)
    return out


def surface_slopes(anchor: npt.ArrayLike, edge_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Slopes of the reference's surfaces on the low-res grid, never across a depth edge.

    Parameters
    ----------
    anchor : array_like (h, w)
        Depth (mm, 0 = none), usually :func:`upsr.method.trust.reference_anchor`.
    edge_mm : float
        Depth step that separates two surfaces.

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
    z = np.nan_to_num(np.asarray(anchor, np.float32), nan=0.0)
    return _slope_along_rows(z.T, edge_mm).T, _slope_along_rows(z, edge_mm)


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
    a = np.nan_to_num(np.asarray(anchor, np.float32), nan=0.0)
    h, w = a.shape
    if z.shape[0] % h or z.shape[1] % w or z.shape[0] // h != z.shape[1] // w:
        raise ValueError(f"depth {z.shape} is not a whole multiple of the anchor {a.shape}")
    if z.shape[0] == h:
        return z  # r = 1: a block is one pixel, without a trend
    sy, sx = surface_slopes(a, edge_mm)
    # (each block is read whole before it is written: in place is safe)
    _follow_kernel(z, a, sy, sx, z.shape[0] // h, max(float(sigma_mm), 0.0), z)
    return z


@nb.njit(cache=True, nogil=True)
def _edge_ends_kernel(z, edge, out):  # pragma: no cover - numba
    h, w = z.shape
    for i in range(h):
        row = z[i]
        for k in range(w - 1):
            if abs(row[k + 1] - row[k]) > edge and row[k] > 0 and row[k + 1] > 0:
                s = _link(row, k, edge)
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
    z = np.nan_to_num(np.asarray(depth_mm, np.float32), nan=0.0)
    out = np.zeros(z.shape, np.bool_)
    _edge_ends_kernel(np.ascontiguousarray(z), float(edge_mm), out)
    rows = np.zeros(z.shape[::-1], np.bool_)
    _edge_ends_kernel(np.ascontiguousarray(z.T), float(edge_mm), rows)
    return out | rows.T
