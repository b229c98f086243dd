"""Per-frame and per-pixel quantities that decide which registered samples the fusion trusts.

Beyond the paper. The temporal median of eq. 28 lets every registered sample vote, also the
ones the motion did not carry along (a thin fast leg: the other frames' samples there show the
wall behind it and vote it away), the ones that see another depth because the surface moved
along the viewing ray, and the mixed ("flying") pixels of ToF sensors
(:mod:`upsr.method.mixed`). This module computes, on the low-res grid:

* :func:`reference_anchor` (of :mod:`upsr.method.anchor`, here too): per reference pixel, an
  edge-aware robust estimate of its own depth (the median of its 3×3 neighbours on its
  surface) and the tolerance τ = k·σ + the local relief of that surface, against which each
  registered sample is trusted or not;
* :func:`radial_offsets`: per frame of the window, the depth offset of the frame registered to
  the reference (motion along the viewing ray), a masked median over a neighbourhood of one
  surface, subtracted from that frame's samples before trust and fusion;
* :func:`fill_holes`: optional filling of pixels without depth from the background side;
* :func:`fusion_inputs`: all of these as the compiled fusion reads them.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.method.alternatives import mix_depths, mix_tolerance, surface_alternatives
from upsr.method.anchor import (
    OWN_SURFACE_SIGMAS,
    TOLERANCE_FLOOR_MM,
    _sigma_and_power,
    reference_anchor,
)
from upsr.method.consistency import hole_backgrounds, maps_at_centres, registered_samples
from upsr.method.mixed import ABSTAIN
from upsr.method.noise import _sigma_at
from upsr.method.sorting import _small_median, _twice_beyond, median_beyond
from upsr.method.validation import nan_as_zero

__all__ = [
    "OFFSET_SIGNIFICANCE",
    "OFFSET_SIGNIFICANCE_MOVED",
    "OWN_SURFACE_SIGMAS",
    "TOLERANCE_FLOOR_MM",
    "abstain_lone_outliers",
    "far_offsets",
    "fill_holes",
    "fusion_inputs",
    "radial_offsets",
    "reference_anchor",
    "significance",
    "state_significance",
    "surface_support",
    "trust_arrays",
]

#: Standard errors of its median beyond which a radial offset is kept (:func:`radial_offsets`)
#: where the frame did not move there (zero motion: noise alone never shifts a static frame).
OFFSET_SIGNIFICANCE = 4.0
#: The same where the frame moved there: a surface seen from a moving camera changes depth,
#: and offsets below 4 standard errors, left unmeasured, biased the fused frames of a camera
#: moving along slanted walls (see :func:`radial_offsets`).
OFFSET_SIGNIFICANCE_MOVED = 2.0


def abstain_lone_outliers(lowres: np.ndarray, ref: int, anchor: npt.ArrayLike) -> np.ndarray:
    """The window with the reference's lone outliers abstaining in the fusion.

    A reference pixel with depth but no anchor (:func:`reference_anchor`: no 8-neighbour on
    its surface) is a noise outlier; as a sample it would still win its own block (it lies
    exactly at the block's centre, where the vote weight and the forward-splat guide favour
    it), and the speckle filter would then blank the block. It abstains instead
    (:data:`upsr.method.mixed.ABSTAIN`): the other frames decide, and where none does,
    :func:`upsr.method.mixed.split_mixed_pixels` gives the block its neighbours' depth.

    Parameters
    ----------
    lowres : ndarray float32 (N, h, w)
        The window (mm, 0 = no depth).
    ref : int
        Index of the reference frame.
    anchor : array_like (h, w)
        :func:`reference_anchor` of ``lowres[ref]``.

    Returns
    -------
    ndarray float32 (N, h, w): ``lowres`` itself when there is none, else a copy.
    """
    lone = (lowres[ref] > 0) & ~(np.asarray(anchor) > 0)
    if not lone.any():
        return lowres
    out = np.array(lowres, np.float32, copy=True)
    out[ref][lone] = ABSTAIN
    return out


@nb.njit(cache=True, nogil=True)
def _select_median(buf, m):  # pragma: no cover - numba
    """Median of buf[:m] by quickselect (in place, O(m)); the mean of the two middle values
    for an even m."""
    if m <= 25:
        return _small_median(buf, m)
    hi_k = m // 2
    lo, hi = 0, m - 1
    while lo < hi:  # Hoare partition around the middle element until buf[hi_k] is in place
        pivot = buf[(lo + hi) // 2]
        a, b = lo, hi
        while a <= b:
            while buf[a] < pivot:
                a += 1
            while buf[b] > pivot:
                b -= 1
            if a <= b:
                buf[a], buf[b] = buf[b], buf[a]
                a += 1
                b -= 1
        if hi_k <= b:
            hi = b
        elif hi_k >= a:
            lo = a
        else:
            break
    upper = buf[hi_k]
    if m % 2 == 1:
        return upper
    lower = buf[0]
    for q in range(1, hi_k):  # the largest of the lower half
        lower = max(lower, buf[q])
    return 0.5 * (lower + upper)


@nb.njit(cache=True, nogil=True, inline="always")
def _surface_neighbours(ref, anc, i, j, edge, radius, stride, rows, cols, us):
    # pragma: no cover - numba
    """The reference's samples around (i, j) (every ``stride``-th pixel of the window of
    ``radius``) on the pixel's surface (within ``edge`` of its anchor ``anc``, any where it
    has none) into (rows, cols, us)[:n]; returns n. The same for every frame of the window."""
    h, w = ref.shape
    c = anc[i, j]
    n = 0
    for a in range(max(i - radius, i % stride), min(i + radius + 1, h), stride):
        for b in range(max(j - radius, j % stride), min(j + radius + 1, w), stride):
            u = ref[a, b]
            if not (u > 0):
                continue
            if c > 0 and abs(u - c) > edge:
                continue  # another surface than the pixel's
            rows[n] = a
            cols[n] = b
            us[n] = u
            n += 1
    return n


@nb.njit(cache=True, nogil=True, inline="always")
def _offset_from(reg_k, rows, cols, us, n, edge, sigma, power, buf, signif, low):
    # pragma: no cover - numba
    """The significant median of frame k's registered differences ``reg_k`` − us at the
    samples (rows, cols)[:n] of :func:`_surface_neighbours`, or 0; the noise std ``sigma``,
    or σ₁ = ``sigma`` of the profile σ₁·(z / 1 m)^power at the mean depth z of the
    reference's samples used. Returns (that from ``signif`` standard errors, the same from
    min(signif, ``low``))."""
    m = 0
    zsum = 0.0
    for q in range(n):
        v = reg_k[rows[q], cols[q]]
        if not (v > 0):
            continue
        u = us[q]
        d = v - u
        if abs(d) <= edge:
            buf[m] = d
            m += 1
            zsum += u
    if m < 5:
        return 0.0, 0.0
    sig = _sigma_at(sigma, power, zsum / m)
    # significant only: beyond ``signif`` standard errors of the median of m differences of
    # two noisy samples
    se = 1.2533 * math.sqrt(2.0) * sig / math.sqrt(m)
    thr = signif * se
    weak = min(signif, low) * se
    # the median exceeds weak only if at least half the differences do (the common case, no
    # offset, is decided by counting, without the selection; the result is the same)
    above, below = _twice_beyond(buf, m, weak)
    if above < m and below < m:
        return 0.0, 0.0
    med = _select_median(buf, m)
    return (med if abs(med) > thr else 0.0), (med if abs(med) > weak else 0.0)


@nb.njit(cache=True, nogil=True)
def _offset_at(
    reg, ref, anc, k, i, j, edge, sigma, power, radius, stride, buf, rows, cols, us, signif, low
):  # pragma: no cover - numba
    """:func:`_offset_from` of frame k at one pixel (i, j) (its own neighbours; ``buf``,
    ``rows``, ``cols``, ``us``: scratch of (2·radius + 1)² values each, allocated once by
    the caller)."""
    n = _surface_neighbours(ref, anc, i, j, edge, radius, stride, rows, cols, us)
    return _offset_from(reg[k], rows, cols, us, n, edge, sigma, power, buf, signif[k, i, j], low)


@nb.njit(cache=True, nogil=True, parallel=True)
def _offset_kernel(
    reg, ref, anc, ref_index, edge, sigma, power, signif, radius, out, step, stride, own,
    low, weak,
):  # fmt: skip
    # pragma: no cover - numba
    """``out``: the offsets of :func:`_offset_from` of every frame but ``ref_index`` (0 for
    it); where ``weak`` is not empty (0, 0, 0), also those from min(signif, ``low``)
    standard errors (``low`` = ∞: none). Each pixel's neighbours on its surface are gathered
    once for the N frames (a 320×240 window's 17 % faster on two threads, the same output)."""
    n, h, w = reg.shape
    both = weak.shape[0] > 0
    n_grid = (h + step - 1) // step
    size = (2 * radius + 1) ** 2
    # on every step-th pixel of each axis (the offsets are smooth), in parallel over the rows
    for gi in nb.prange(n_grid):
        i = gi * step
        buf = np.empty(size, np.float32)
        rows = np.empty(size, np.int64)
        cols = np.empty(size, np.int64)
        us = np.empty(size, np.float32)
        for j in range(0, w, step):
            m = _surface_neighbours(ref, anc, i, j, edge, radius, stride, rows, cols, us)
            for k in range(n):
                if k == ref_index:
                    continue
                a, b = _offset_from(
                    reg[k], rows, cols, us, m, edge, sigma, power, buf, signif[k, i, j], low
                )
                out[k, i, j] = a
                if both:
                    weak[k, i, j] = b
    # a pixel takes the value of its grid pixel when that one lies on its surface, else its
    # own (``own``) or none
    for i in nb.prange(h):
        buf = np.empty(size, np.float32)
        rows = np.empty(size, np.int64)
        cols = np.empty(size, np.int64)
        us = np.empty(size, np.float32)
        gi = i - i % step
        for j in range(w):
            gj = j - j % step
            if gi == i and gj == j:
                continue
            c = anc[i, j]
            g = anc[gi, gj]
            if c > 0 and g > 0 and abs(c - g) <= edge:
                for k in range(n):
                    out[k, i, j] = out[k, gi, gj]
                    if both:
                        weak[k, i, j] = weak[k, gi, gj]
                continue
            m = 0
            if own:
                m = _surface_neighbours(ref, anc, i, j, edge, radius, stride, rows, cols, us)
            for k in range(n):
                a = b = 0.0
                if own and k != ref_index:
                    a, b = _offset_from(
                        reg[k], rows, cols, us, m, edge, sigma, power, buf, signif[k, i, j], low
                    )
                out[k, i, j] = a
                if both:
                    weak[k, i, j] = b
    if 0 <= ref_index < n:
        out[ref_index] = 0.0
        if both:
            weak[ref_index] = 0.0


#: ``_offset_kernel``'s (step, stride, own) of the offsets on the neighbourhood of
#: :func:`radial_offsets`: every 2nd pixel's own, the others' from it on its surface. (Passed
#: explicitly: a call that leaves arguments to their defaults takes numba's slow dispatch,
#: 0.7 ms per call under cProfile at 320×240.)
OFFSET_GRID = (2, 1, True)

#: ``_offset_kernel``'s (low, weak) where only the offsets from ``signif`` are wanted.
NO_WEAK_OFFSETS = (np.inf, np.zeros((0, 0, 0), np.float32))

#: The wider neighbourhood of :func:`radial_offsets` where the first is not significant
#: (radius × this factor, every second pixel of it: (f·R + 1)² differences).
COARSE_RADIUS_FACTOR = 8


def radial_offsets(
    lowres: npt.ArrayLike,
    maps: npt.ArrayLike,
    scale: int,
    ref: int,
    *,
    sigma_mm: float,
    edge_mm: float,
    radius_px: int = 2,
    registered: npt.ArrayLike | None = None,
    anchor: npt.ArrayLike | None = None,
    noise_profile: tuple[float, float] | None = None,
    centres: np.ndarray | None = None,
) -> np.ndarray:
    """Depth offset of each frame registered to the reference (motion along the viewing ray).

    Frame k's sample at each reference pixel's centre (moved by its map) minus the reference
    there, where both have depth and differ by at most ``edge_mm``; the median of those
    differences over the (2·radius+1)² low-res neighbours on the pixel's surface. Kept only
    where it exceeds :data:`OFFSET_SIGNIFICANCE` (4) standard errors of that median, from at
    least 5 differences, where the frame did not move at the pixel (noise alone never shifts a
    static frame), :data:`OFFSET_SIGNIFICANCE_MOVED` (2) where it moved (on the realistic
    scenes, ``benchmarks/realistic_eval.py --quick``, 4 everywhere left the offsets of a
    camera moving along slanted walls unmeasured: moving-surface rmse of the Kinect room 22.2
    against 15.9 mm with 2, bias +5.1 against +1.1 mm; Laplace σ = 10 room 17.4 against 15.6;
    camera approaching a wall at σ = 30: 13.4 against 11.8); elsewhere the same over a
    neighbourhood :data:`COARSE_RADIUS_FACTOR` times as wide, every second pixel of it (its
    standard error ≈ 3.4 times smaller at R = 2: a slow radial motion under strong noise),
    where it exceeds :data:`OFFSET_SIGNIFICANCE`.

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
    registered : array_like (N, h, w), optional
        :func:`upsr.method.consistency.registered_samples` of ``lowres`` and ``maps``, when
        already computed.
    anchor : array_like (h, w), optional
        :func:`reference_anchor` of the reference (any k), when already computed.
    noise_profile : (float, float), optional
        (σ₁, p) of :func:`upsr.method.noise.noise_profile`: with p > 0 the significance test
        takes σ₁·(z / 1 m)^p at the neighbourhood's depth z instead of ``sigma_mm``.
    centres : ndarray (N, h, w, 2), optional
        :func:`upsr.method.consistency.maps_at_centres` of ``maps``, when already computed.

    Returns
    -------
    ndarray float32 (N, h, w): the offset (mm) to subtract from frame k's samples that land on
    reference pixel (i, j); 0 for the reference.
    """
    lr = nan_as_zero(np.ascontiguousarray(lowres, np.float32))
    n, h, w = lr.shape
    if registered is None:
        registered = registered_samples(lr, maps, scale)
    reg = np.ascontiguousarray(registered, np.float32)
    if anchor is None:
        anchor = reference_anchor(lr[ref], sigma_mm, 1.0, edge_mm)[0]
    anc = np.ascontiguousarray(anchor, np.float32)
    signif = significance(maps, (h, w), centres=centres)
    sigma, power = _sigma_and_power(sigma_mm, noise_profile)
    args = (reg, lr[ref], anc, int(ref), float(edge_mm), sigma, power, signif)
    out = np.empty((n, h, w), np.float32)
    _offset_kernel(*args, int(radius_px), out, *OFFSET_GRID, *NO_WEAK_OFFSETS)
    return _with_wide_offsets(out, args[:-1], int(radius_px))


def _with_wide_offsets(offsets: np.ndarray, args: tuple, radius_px: int) -> np.ndarray:
    """``offsets`` (N, h, w) of ``_offset_kernel(*args, signif, radius_px, offsets)``, and
    where they are 0 (not significant: a camera moving 10 mm per frame under 30 mm of noise)
    the same on a neighbourhood :data:`COARSE_RADIUS_FACTOR` times as wide: on every 2nd
    pixel of it, on a grid of 2f px, none off the grid's surface (the cost of the first), from
    :data:`OFFSET_SIGNIFICANCE` standard errors everywhere (its error is so small that the
    differences of a camera's motion across it would be taken for an offset)."""
    wide = np.empty_like(offsets)
    f = COARSE_RADIUS_FACTOR
    strict = np.full(offsets.shape, OFFSET_SIGNIFICANCE, np.float32)
    _offset_kernel(*args, strict, f * int(radius_px), wide, 2 * f, 2, False, *NO_WEAK_OFFSETS)
    return np.where(offsets != 0, offsets, wide)


def significance(
    maps: npt.ArrayLike, lowres_shape: tuple[int, int], *, centres: np.ndarray | None = None
) -> np.ndarray:
    """Per frame and low-res pixel, the standard errors beyond which a radial offset is kept:
    :data:`OFFSET_SIGNIFICANCE_MOVED` where the motion
    (:func:`upsr.method.consistency.maps_at_centres`) is not zero,
    :data:`OFFSET_SIGNIFICANCE` where it is.

    Parameters
    ----------
    maps : array_like (N, s·h, s·w, 2)
        Motion of each frame on the flow grid (flow px).
    lowres_shape : (int, int)
        (h, w).
    centres : ndarray (N, h, w, 2), optional
        :func:`~upsr.method.consistency.maps_at_centres` of ``maps``, when already computed.

    Returns
    -------
    ndarray float32 (N, h, w)
    """
    at = maps_at_centres(maps, lowres_shape) if centres is None else centres
    moved = (np.abs(at[..., 0]) > 1e-3) | (np.abs(at[..., 1]) > 1e-3)
    return np.where(moved, np.float32(OFFSET_SIGNIFICANCE_MOVED), np.float32(OFFSET_SIGNIFICANCE))


def state_significance(
    flow: np.ndarray,
    registered: np.ndarray,
    measurement: np.ndarray,
    *,
    sigma_mm: float,
    edge_mm: float,
    radius_px: int,
    noise_factor: float,
    along_significance: float,
    centres: np.ndarray | None = None,
) -> tuple[np.ndarray, bool]:
    """:func:`significance` of a recursive state's radial offsets against the current frame,
    at most ``along_significance`` where the state as a whole lies nearer or farther than
    the frame (the camera moves along its axis), and whether it does.

    The state moved along the viewing ray when the median of its differences to the frame
    within ``edge_mm`` (at least 25 of them) lies beyond the standard error of one offset's
    window of (2·``radius_px`` + 1)² differences of std ``noise_factor``·``sigma_mm``.

    Parameters
    ----------
    flow : ndarray float32 (s·h, s·w, 2)
        Motion from the current frame to the previous one on the flow grid (flow px).
    registered : ndarray float32 (1, h, w)
        The state registered to the frame's low-res pixel centres (mm, 0 = none).
    measurement : ndarray float32 (h, w)
        The current frame (mm, 0 = none).
    sigma_mm, edge_mm : float
        Noise std and the depth step that separates two surfaces (mm).
    radius_px : int
        Half-size of the offsets' neighbourhood (low-res px).
    noise_factor : float
        Std of (sample − state) in units of σ (the state is less noisy than a frame).
    along_significance : float
        The standard errors kept where the state moved along the ray.
    centres : ndarray (1, h, w, 2), optional
        :func:`~upsr.method.consistency.maps_at_centres` of ``flow[None]``, when already
        computed.

    Returns
    -------
    (ndarray float32 (1, h, w), bool)
    """
    sig = significance(flow[None], measurement.shape, centres=centres)
    valid = (registered[0] > 0) & (measurement > 0)
    diff = (registered[0] - measurement)[valid]
    diff = diff[np.abs(diff) <= edge_mm]
    se = 1.2533 * math.sqrt(2.0) * noise_factor * sigma_mm / (2 * radius_px + 1)
    along = diff.size >= 25 and median_beyond(diff, se)
    if along:
        sig = np.minimum(sig, np.float32(along_significance))
    return sig, along


def far_offsets(offsets: npt.ArrayLike, edge_mm: float) -> np.ndarray:
    """Where a radial offset is too large to be trusted: beyond half the edge threshold.

    :func:`radial_offsets` measures the differences within ``edge_mm`` only, so an offset
    near it (a frame far from an off-centre reference at the end of a clip while the camera
    approaches a wall) is truncated towards 0; the samples of that frame there abstain
    instead of biasing the output (bool, same shape as ``offsets``)."""
    return np.abs(np.asarray(offsets, np.float32)) > 0.5 * float(edge_mm)


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


def fusion_inputs(
    anchor: npt.ArrayLike | None,
    tolerance: npt.ArrayLike | None,
    offsets: npt.ArrayLike | None,
    untrusted: npt.ArrayLike | None,
    lr: np.ndarray,
    edge_mm: float,
    holes_of: int | None,
    mixes_mm: npt.ArrayLike | None,
    followed: npt.ArrayLike | None = None,
    border_strips: bool = False,
) -> tuple:
    """The trust arrays of :func:`upsr.method.fusion.register_and_fuse` as its kernel reads
    them: anchor, tolerance, offsets, the four surface alternatives (from the anchor, the
    removed mixed pixels ``mixes_mm``, the thin parts the motion ``followed`` and
    ``border_strips``), the misregistered samples, the nearest depth a sample may have at
    each reference pixel (``holes_of``: the reference's index, or None for no limit), and the
    removed mixed pixels' depths and tolerances (:func:`mix_tolerance`)."""
    n, h, w = lr.shape
    nearest = np.full((h, w), -np.inf, np.float32)
    if holes_of is not None:
        bg = hole_backgrounds(lr[holes_of])
        nearest = np.where(bg > 0, bg - np.float32(edge_mm), nearest).astype(np.float32)
    anc, tol, offs = trust_arrays(anchor, tolerance, offsets, (n, h, w))
    mixes = mix_depths(mixes_mm, (h, w))
    alternatives = surface_alternatives(
        anc, tol, edge_mm, mixes, followed, border_strips=border_strips
    )
    alts = [np.ascontiguousarray(a, np.float32).reshape(3, 3, h, w) for a in alternatives]
    if untrusted is None:
        bad = np.zeros((n, h, w), np.bool_)
    else:
        bad = np.ascontiguousarray(untrusted, np.bool_).reshape(n, h, w)
    return anc, tol, offs, alts, bad, nearest, mixes, mix_tolerance(anc, tol, mixes)


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
