"""Motion estimation on upsampled depth frames (paper §4, §5.2).

The flow is computed between *consecutive upsampled* frames y_t↑ (eq. 16–17): upsampling first
gives the pyramid more levels and sub-pixel accuracy on the high-res grid (eq. 9–12). The depth
frames are bilateral-prefiltered (§5.2) and mapped to 8 bit with **one fixed mapping per video**
(never per frame: a per-frame mapping would change the brightness of a static surface whenever
something else enters the view and break the brightness constancy the flow relies on).

Flow convention: ``flow[i, j] = (dx, dy)`` maps the pixel (x=j, y=i) of the first image to
(x+dx, y+dy) in the second, i.e. ``first(p) ≈ second(p + flow(p))`` (OpenCV's convention).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Protocol

import cv2
import numba as nb
import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method.registration import remap_by_flow
from upsr.method.upsampling import upsample_nearest

__all__ = [
    "FlowBackend",
    "available_flow_backends",
    "bilateral_prefilter",
    "bilateral_prefilter_nearest",
    "depth_range",
    "depth_to_u8",
    "flow_backend_is_thread_safe",
    "make_flow_backend",
    "register_flow_backend",
    "suppress_spurious_motion",
]


class FlowBackend(Protocol):
    """A dense optical-flow estimator ``(first_u8, second_u8) -> flow (H, W, 2) float32``."""

    def __call__(self, first: np.ndarray, second: np.ndarray) -> np.ndarray: ...


def bilateral_prefilter(depth_mm: npt.ArrayLike, sigma_mm: float, sigma_px: float) -> np.ndarray:
    """Edge-preserving bilateral filter of an (upsampled) depth frame, for motion only (§5.2).

    Invalid pixels (0) keep the value 0 and, being far from any real depth in range, get a
    negligible weight in their valid neighbours.

    Parameters
    ----------
    depth_mm : array_like, (H, W)
        Depth in mm, 0 = invalid.
    sigma_mm : float
        Range standard deviation (mm).
    sigma_px : float
        Spatial standard deviation (px); the window diameter is 2·⌈2·sigma_px⌉ + 1.

    Returns
    -------
    ndarray float32 (H, W)
    """
    src = np.ascontiguousarray(depth_mm, dtype=np.float32)
    diameter = 2 * int(np.ceil(2.0 * sigma_px)) + 1
    out = cv2.bilateralFilter(src, diameter, float(sigma_mm), float(sigma_px))
    out[src <= 0] = 0.0
    return out


def bilateral_prefilter_nearest(
    depth_mm: npt.ArrayLike, factor: int, sigma_mm: float, sigma_px: float
) -> np.ndarray:
    """:func:`bilateral_prefilter` of the frame upsampled by ``factor`` with nearest neighbour
    (eq. 13–15), computed on the low-res grid (beyond the paper; a speed-up, same result).

    The upsampled frame is constant on ``factor``×``factor`` blocks, so the range weight of
    two output pixels depends only on their two low-res pixels, and the spatial weights of a
    window fall into a few blocks whose sums depend only on the pixel's place in its block.
    Each output pixel then costs one weighted sum over ~(2·radius/factor + 2)² blocks instead
    of a (2·radius + 1)² window. OpenCV's conventions are kept: a circular window of radius
    ⌈2·sigma_px⌉, reflected borders (BORDER_REFLECT_101) and its interpolated table of range
    weights, so the result equals ``bilateral_prefilter(upsample_nearest(depth, factor), ...)``
    up to float rounding (< 0.01 mm; tests/method/test_motion.py). Frames smaller than the window,
    and ``factor`` = 1, go to OpenCV.

    Parameters
    ----------
    depth_mm : array_like, (h, w)
        Low-res depth in mm; 0, NaN, ±inf and negative values are invalid (0 in the output).
    factor : int
        Upsampling factor s ≥ 1.
    sigma_mm, sigma_px : float
        As in :func:`bilateral_prefilter` (sigma_px in upsampled px).

    Returns
    -------
    ndarray float32 (s·h, s·w)
    """
    src = np.asarray(depth_mm, dtype=np.float32)
    src = np.where(np.isfinite(src) & (src > 0), src, np.float32(0.0))  # NaN, ±inf, ≤ 0: invalid
    factor = int(factor)
    radius = int(np.ceil(2.0 * sigma_px))
    h, w = src.shape
    if factor == 1 or min(h, w) * factor <= 2 * radius + 1:
        return bilateral_prefilter(upsample_nearest(src, factor), sigma_mm, sigma_px)
    out = np.empty((h * factor, w * factor), np.float32)
    vmin, vmax = float(src.min()), float(src.max())
    if abs(vmax - vmin) < np.finfo(np.float32).eps:  # a constant frame is its own result
        out[:] = upsample_nearest(src, factor)
    else:
        _block_bilateral_kernel(
            src, factor, radius, float(sigma_mm), float(sigma_px), vmin, vmax, out
        )
    return out


@nb.njit(cache=True, nogil=True, inline="always")
def _reflect101(p, n):  # pragma: no cover - numba
    """OpenCV's BORDER_REFLECT_101 index (n > 1)."""
    while p < 0 or p >= n:
        p = -p if p < 0 else 2 * n - 2 - p
    return p


@nb.njit(cache=True, nogil=True)
def _border_classes(n, s, radius):  # pragma: no cover - numba
    """Class of each of n rows (or columns) for the spatial block sums: the place y % s in
    its block where the window (±radius) lies inside, else a class of its own; and one
    representative row of each class."""
    cls = np.empty(n, np.int64)
    rep = np.full(s + n, -1, np.int64)  # -1: a place no row with an inner window has
    m = s
    for y in range(n):
        if y - radius >= 0 and y + radius < n:
            cls[y] = y % s
            if rep[y % s] < 0:
                rep[y % s] = y
        else:
            cls[y] = m
            rep[m] = y
            m += 1
    return cls, rep[:m]


@nb.njit(cache=True, nogil=True)
def _block_bilateral_kernel(
    low, s, radius, sigma_mm, sigma_px, vmin, vmax, out
):  # pragma: no cover - numba
    h, w = low.shape
    hh, ww = h * s, w * s
    color_coeff = -0.5 / (sigma_mm * sigma_mm)
    space_coeff = -0.5 / (sigma_px * sigma_px)
    side = 2 * radius + 1
    # the taps of the circular window and their spatial weights (as OpenCV)
    tap_dy = np.empty(side * side, np.int64)
    tap_dx = np.empty(side * side, np.int64)
    tap_w = np.empty(side * side, np.float32)
    nt = 0
    for i in range(-radius, radius + 1):
        for j in range(-radius, radius + 1):
            r = math.sqrt(i * i + j * j)
            if r > radius:
                continue
            tap_dy[nt] = i
            tap_dx[nt] = j
            tap_w[nt] = np.float32(math.exp(r * r * space_coeff))
            nt += 1
    # blocks lo..hi (relative to a pixel's own block) hold the window's taps
    lo = -((radius + s - 1) // s)
    hi = (s - 1 + radius) // s
    nb_ = hi - lo + 1
    # spatial weight sums per block, by the row class of a pixel's row and the column class
    # of its column: the place in its block (a window inside the image), or, within
    # ``radius`` px of the border, the row / column itself (a window with reflected taps)
    row_class, row_rep = _border_classes(hh, s, radius)
    col_class, col_rep = _border_classes(ww, s, radius)
    sums = np.zeros((row_rep.size, col_rep.size, nb_, nb_), np.float32)
    for cr in range(row_rep.size):
        y = row_rep[cr]
        for cc in range(col_rep.size):
            x = col_rep[cc]
            if y < 0 or x < 0:
                continue  # an unused class
            for t in range(nt):
                p = _reflect101(y + tap_dy[t], hh) // s - y // s - lo
                q = _reflect101(x + tap_dx[t], ww) // s - x // s - lo
                sums[cr, cc, p, q] += tap_w[t]
    # OpenCV's range weights: exp tabulated on 4096 bins of the image's span, interpolated
    scale_index = np.float32(4096.0) / np.float32(vmax - vmin)
    lut = np.empty(4098, np.float32)
    for i in range(4098):
        val = i / scale_index
        lut[i] = math.exp(val * val * color_coeff)
    wn = np.empty((nb_, nb_), np.float32)
    wd = np.empty((nb_, nb_), np.float32)
    for bi_ in range(h):
        for bj_ in range(w):
            c = low[bi_, bj_]
            if not c > 0:
                for a in range(s):
                    for b in range(s):
                        out[bi_ * s + a, bj_ * s + b] = 0.0
                continue
            # range weights of this block's pixel with its neighbour blocks, shared by its s² px
            for p in range(nb_):
                for q in range(nb_):
                    v = low[min(max(bi_ + lo + p, 0), h - 1), min(max(bj_ + lo + q, 0), w - 1)]
                    alpha = abs(v - c) * scale_index
                    k = int(alpha)
                    alpha -= k
                    wgt = lut[k] + np.float32(alpha) * (lut[k + 1] - lut[k])
                    wd[p, q] = wgt
                    wn[p, q] = wgt * v
            for a in range(s):
                y = bi_ * s + a
                for b in range(s):
                    x = bj_ * s + b
                    spatial = sums[row_class[y], col_class[x]]
                    num = np.float32(0.0)
                    den = np.float32(0.0)
                    for p in range(nb_):
                        for q in range(nb_):
                            sw = spatial[p, q]
                            num += sw * wn[p, q]
                            den += sw * wd[p, q]
                    out[y, x] = num / den


def depth_range(
    frames_mm: npt.ArrayLike, *, low_pct: float = 1.0, high_pct: float = 99.0, margin: float = 0.1
) -> tuple[float, float]:
    """A fixed (near, far) depth range (mm) for the 8-bit mapping of a whole video.

    Percentiles of the valid depths of ``frames_mm`` widened by ``margin`` of the span on both
    sides. With no valid depth, (0, 10000) mm.
    """
    arr = np.asarray(frames_mm, dtype=np.float32)
    valid = arr[arr > 0]
    if valid.size == 0:
        return 0.0, 10000.0
    near, far = np.percentile(valid, [low_pct, high_pct]).astype(float)
    span = max(far - near, 1.0)
    return max(0.0, near - margin * span), far + margin * span


@nb.njit(cache=True, nogil=True, parallel=True)
def _u8_kernel(d, near, far, scale, out):  # pragma: no cover - numba
    n = d.size
    chunk = 4096
    for c in nb.prange((n + chunk - 1) // chunk):
        for k in range(c * chunk, min(n, (c + 1) * chunk)):
            v = np.float64(d[k])
            if not v > 0.0:  # (no depth, NaN)
                out[k] = 0
                continue
            out[k] = np.uint8(np.rint(255.0 - (min(max(v, near), far) - near) * scale))


def depth_to_u8(depth_mm: npt.ArrayLike, near_mm: float, far_mm: float) -> np.ndarray:
    """Map depth to an 8-bit image for optical flow: near → 255, far → 1, invalid → 0.

    Computed in float64 whatever the types (255 − (clip(d, near, far) − near) · 254 /
    (far − near), rounded half to even), in one compiled pass: the values of the NumPy
    expression it replaced, 0.7 instead of 5.4 ms at 1280×960 (once per frame, twice where
    the recursive mode brings a frame back by the scene's depth drift)."""
    d = np.ascontiguousarray(depth_mm, dtype=np.float32)
    near, far = float(near_mm), float(far_mm)
    out = np.empty(d.shape, np.uint8)
    _u8_kernel(d.ravel(), near, far, 254.0 / max(far - near, 1e-6), out.ravel())
    return out


def suppress_spurious_motion(
    first_mm: np.ndarray,
    second_mm: np.ndarray,
    flow: np.ndarray,
    *,
    window_px: int = 7,
    tolerance: float = 1.1,
    noise_mm: float = 0.0,
    edge_mm: float | None = None,
    edge_window_px: int | None = None,
    holes: bool = False,
) -> np.ndarray:
    """Set the flow to zero where "no motion" explains the depth as well as the flow does.

    Depth surfaces carry little texture, and a patch-based flow readily matches the noise of a
    static surface. For each pixel, the mean squared residual over a ``window_px`` window of
    the motion-compensated second frame, ``first − second∘flow``, is compared with that of the
    unwarped one, ``first − second``; where the latter is not larger than ``tolerance`` times
    the former plus ``noise_mm``², the motion is not supported by the data and is set to 0:
    either nothing moves there, or the motion changes the depth by less than the noise, so that
    it does not matter for the fusion. Pixels invalid in either frame are ignored.

    Parameters
    ----------
    first_mm, second_mm : ndarray (H, W)
        The (prefiltered, upsampled) depth frames the flow was estimated on, in mm; or two
        8-bit images of depth (uint8, e.g. :func:`depth_to_u8`: kept 8-bit, same result as
        their float32 values).
    flow : ndarray (H, W, 2)
        Flow from ``first`` to ``second``.
    window_px : int
        Side of the averaging window (px).
    tolerance : float
        Relative margin granted to the zero motion (≥ 1).
    noise_mm : float
        Absolute margin (mm, root mean square per pixel) granted to the zero motion.
    edge_mm : float or None
        If given, the flow is kept wherever the window holds a depth edge (a depth span larger
        than ``edge_mm``, invalid pixels included): at edges the motion is what places them,
        and the flow that chains pixels near an edge from frame to frame must stay intact.
    edge_window_px : int or None
        Side of the window of that edge test (px); default ``window_px``.
    holes : bool
        Also judge the flow of the pixels without depth in ``first`` (otherwise left alone),
        by the holes' pattern: zeroed where, over the window, the flow brings more pixels
        whose depth or lack of it disagrees with ``first`` (``second`` moved has depth where
        ``first`` has none and ``second`` unmoved none, or the other way round) than no motion
        does. A hole that every frame has keeps its place (the flow of a noisy static surface
        had carried its rim into it, 2 px on the output grid), a moving part's hole its flow.

    Returns
    -------
    ndarray (H, W, 2) float32, a copy of ``flow`` with the unsupported motion zeroed.
    """
    # 8-bit images (the guides of eq. 19) stay 8-bit: the same values, faster filters
    dtype = np.uint8 if np.result_type(first_mm, second_mm) == np.uint8 else np.float32
    first = np.ascontiguousarray(first_mm, dtype)
    second = np.ascontiguousarray(second_mm, dtype)
    warped = remap_by_flow(second, flow, cv2.INTER_NEAREST, cv2.BORDER_REPLICATE)
    # both squared residuals in one 2-channel image (and the holes' mismatches: 4 channels),
    # box-filtered in one call
    squared = np.empty((*first.shape, 4 if holes else 2), np.float32)
    (_residuals_and_holes if holes else _squared_residuals)(first, second, warped, squared)
    residuals = cv2.boxFilter(squared, -1, (window_px, window_px))
    if edge_mm is not None:
        side = max(edge_window_px or window_px, 1)
        kernel = np.ones((side, side), np.uint8)
        span = cv2.morphologyEx(first, cv2.MORPH_GRADIENT, kernel)  # dilate − erode
        edge = float(edge_mm)
    else:
        span = first  # unused: no edge test
        edge = np.inf
    out = np.empty(np.shape(flow), np.float32)
    _zero_unsupported(
        first,
        np.ascontiguousarray(flow, np.float32),
        residuals,
        span,
        float(tolerance),
        float(noise_mm) ** 2,
        edge,
        out,
        holes,
    )
    return out


@nb.njit(cache=True, nogil=True)
def _squared_residuals(first, second, warped, out):  # pragma: no cover - numba
    """out[..., 0] = (first − warped)², out[..., 1] = (first − second)² where all three are
    valid, else 0."""
    h, w = first.shape
    for i in range(h):
        fr = first[i]
        sr = second[i]
        wr = warped[i]
        orow = out[i]
        for j in range(w):  # branch-free (SIMD)
            a = fr[j]
            b = sr[j]
            c = wr[j]
            ok = (a > 0) & (b > 0) & (c > 0)
            d1 = np.float32(a) - np.float32(c)
            d2 = np.float32(a) - np.float32(b)
            orow[j, 0] = d1 * d1 if ok else np.float32(0.0)
            orow[j, 1] = d2 * d2 if ok else np.float32(0.0)


@nb.njit(cache=True, nogil=True)
def _residuals_and_holes(first, second, warped, out):  # pragma: no cover - numba
    """:func:`_squared_residuals` in channels 0, 1; channel 2 (3): 1 where the depth or lack
    of it of ``warped`` (``second``) disagrees with ``first``'s, and for a pixel without
    depth in ``first`` only where ``second`` (``warped``) agrees with it (a hole that both
    fill, a dropout, tells nothing of the motion)."""
    h, w = first.shape
    for i in range(h):
        fr = first[i]
        sr = second[i]
        wr = warped[i]
        orow = out[i]
        for j in range(w):
            a = fr[j]
            b = sr[j]
            c = wr[j]
            va = a > 0
            vb = b > 0
            vc = c > 0
            ok = va & vb & vc
            d1 = np.float32(a) - np.float32(c)
            d2 = np.float32(a) - np.float32(b)
            orow[j, 0] = d1 * d1 if ok else np.float32(0.0)
            orow[j, 1] = d2 * d2 if ok else np.float32(0.0)
            orow[j, 2] = np.float32((va & ~vc) | (~va & vc & ~vb))
            orow[j, 3] = np.float32((va & ~vb) | (~va & vb & ~vc))


@nb.njit(cache=True, nogil=True)
def _zero_unsupported(
    first, flow, residuals, span, tolerance, noise_sq, edge_mm, out, holes
):  # pragma: no cover - numba
    """out = flow, zero where the zero motion fits as well (and no edge is near); with
    ``holes``, zero at a pixel without depth where the flow's hole mismatches (channel 2)
    outnumber the zero motion's (channel 3)."""
    h, w = first.shape
    for i in range(h):
        fr = first[i]
        rr = residuals[i]
        sr = span[i]
        flr = flow[i]
        orow = out[i]
        for j in range(w):  # branch-free (SIMD)
            # pixels without depth carry no evidence of their depth: their flow (which
            # chaining reads when a moving surface's pixel lands just outside it) is left
            # alone, unless the holes' pattern is asked (``holes``)
            if fr[j] > 0:
                zero = (rr[j, 1] <= tolerance * rr[j, 0] + noise_sq) & (sr[j] <= edge_mm)
            else:
                zero = holes and rr[j, 2] > rr[j, 3] + np.float32(1e-6)
            orow[j, 0] = np.float32(0.0) if zero else flr[j, 0]
            orow[j, 1] = np.float32(0.0) if zero else flr[j, 1]


_MIN_FLOW_SIZE = 16

_DIS_PRESETS = {
    "ultrafast": cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST,
    "fast": cv2.DISOPTICAL_FLOW_PRESET_FAST,
    "medium": cv2.DISOPTICAL_FLOW_PRESET_MEDIUM,
}


def _dis_factory(preset: str = "medium") -> FlowBackend:
    """OpenCV's DIS optical flow (Kroeger et al. 2016): pyramidal, patch-based, fast."""
    code = _DIS_PRESETS[preset]
    probe = cv2.DISOpticalFlow_create(code)
    finest = probe.getFinestScale()
    # DIS reads out of bounds (SIGSEGV) or raises when a side of the image at its finest
    # pyramid level is shorter than one patch (e.g. 24×256 px with the fast presets, whose
    # finest level is 1/4): such frames are padded to patch · 2^finest px by edge replication.
    min_side = max(_MIN_FLOW_SIZE, probe.getPatchSize() << finest)
    # One OpenCV object per thread (one object must not compute two pairs at once), kept:
    # allocating a fresh one costs a third of a 192×168 px call. Its only state: on an image
    # too small for the preset's finest pyramid level, ``calc`` lowers that level for good,
    # so it is set again before every pair: the result is then a fresh object's, whatever
    # pairs came before (a chunk of a video gives what the whole run gives; tests check it).
    local = threading.local()

    def flow(first: np.ndarray, second: np.ndarray) -> np.ndarray:
        dis = getattr(local, "dis", None)
        if dis is None:
            dis = local.dis = cv2.DISOpticalFlow_create(code)
        dis.setFinestScale(finest)
        h, w = first.shape[:2]
        if min(h, w) >= min_side:
            return dis.calc(first, second, None)
        # too small for the pyramid: pad by edge replication, then crop
        ph, pw = max(min_side - h, 0), max(min_side - w, 0)
        a, b = (
            cv2.copyMakeBorder(im, 0, ph, 0, pw, cv2.BORDER_REPLICATE) for im in (first, second)
        )
        return np.ascontiguousarray(dis.calc(a, b, None)[:h, :w])

    return flow


def _farneback_factory(preset: str = "medium") -> FlowBackend:
    """OpenCV's Farnebäck polynomial-expansion flow (pyramidal)."""
    levels = {"ultrafast": 3, "fast": 4, "medium": 5}[preset]

    def flow(first: np.ndarray, second: np.ndarray) -> np.ndarray:
        return cv2.calcOpticalFlowFarneback(first, second, None, 0.5, levels, 15, 3, 5, 1.2, 0)

    return flow


_BACKENDS: dict[str, Callable[..., FlowBackend]] = {
    "dis": _dis_factory,
    "farneback": _farneback_factory,
}
#: Built-in factories whose flows keep no state and may run on two threads at once.
_THREAD_SAFE_FACTORIES = frozenset({_dis_factory, _farneback_factory})


def register_flow_backend(name: str, factory: Callable[..., FlowBackend]) -> None:
    """Make a flow backend available by name.

    ``factory(preset=...)`` must return a :class:`FlowBackend`; it is called once per video
    (backends may keep state between calls).
    """
    _BACKENDS[name] = factory


def flow_backend_is_thread_safe(name: str) -> bool:
    """Whether the backend ``name`` is a built-in one, safe to call from two threads at once
    (a registered backend may keep state between calls: it is always called in sequence)."""
    return _BACKENDS.get(name) in _THREAD_SAFE_FACTORIES


def available_flow_backends() -> list[str]:
    """Names accepted by :func:`make_flow_backend` (and ``UPSRConfig.flow``)."""
    return sorted(_BACKENDS)


def make_flow_backend(name: str = "dis", preset: str = "medium") -> FlowBackend:
    """Instantiate the flow backend ``name`` (see :func:`available_flow_backends`)."""
    try:
        factory = _BACKENDS[name]
    except KeyError:
        raise InputError(
            f"unknown flow backend {name!r} (available: {', '.join(available_flow_backends())})"
        ) from None
    return factory(preset=preset)
