"""Cumulative registration of a window of frames to its reference (paper §5.2, eq. 16–21).

Only consecutive motions are estimated; the motion from the reference t0 to a frame t is the
*composition* of the consecutive ones (eq. 20–21, ``SPEC.md`` §2.4): a pixel p of the reference
moves to q = p + C_{t+1}(p) in frame t+1, and from there to q + F_{t+1→t}(q) in frame t, so
C_t(p) = C_{t+1}(p) + F_{t+1→t}(p + C_{t+1}(p)) — the next flow is sampled at the already
displaced position, it is not simply added.

Eq. 19 (re-estimation against the already registered neighbour) is applied as a residual flow
on the reference grid between the registered neighbour and the newly registered frame, composed
into the cumulative motion: drift along the chain is measured and removed at every step.

Flows are (H, W, 2) float32 arrays, ``flow[i, j] = (dx, dy)``; a flow "from a to b" is defined on
a's grid and maps a's pixel p to p + flow(p) in b.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence

import cv2
import numba as nb
import numpy as np
import numpy.typing as npt

from upsr._numba import SAFE_FASTMATH
from upsr.method._parallel import both

__all__ = [
    "advance_positions",
    "compose_flows",
    "cumulative_flows",
    "flow_positions",
    "flows_to_reference",
    "identity_grid",
    "interpolation_tables",
    "remap_by_flow",
    "sample_centres",
    "sample_offsets",
    "to_output_grid",
    "trace_to_reference",
    "warp_guide",
    "warp_nearest",
    "weight_table",
]


@functools.lru_cache(maxsize=8)
def identity_grid(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates (x, y) of an (height, width) grid as float32 arrays (cached, read-only)."""
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    xs.flags.writeable = False
    ys.flags.writeable = False
    return xs, ys


@functools.lru_cache(maxsize=8)
def _identity_xy(height: int, width: int) -> np.ndarray:
    """Pixel coordinates of an (height, width) grid as one (H, W, 2) float32 array (x, y),
    the layout of a flow: ``_identity_xy + flow`` is the map of ``cv2.remap`` (cached)."""
    xs, ys = identity_grid(height, width)
    xy = np.dstack([xs, ys])
    xy.flags.writeable = False
    return xy


def remap_by_flow(
    image: np.ndarray, flow: np.ndarray, interpolation: int, border: int, value: float = 0.0
) -> np.ndarray:
    """``cv2.remap`` of ``image`` at p + flow(p) (one interleaved map: no channel copies)."""
    h, w = flow.shape[:2]
    return cv2.remap(
        image, _identity_xy(h, w) + flow, None, interpolation, borderMode=border, borderValue=value
    )


def compose_flows(
    first: np.ndarray, second: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """Chain two dense motions (eq. 20): first a→b (on a's grid), then b→c (on b's grid).

    Returns the a→c flow ``first(p) + second(p + first(p))``, ``second`` sampled bilinearly at the
    displaced positions (clamped at the border); in ``out`` if given.
    """
    sampled = remap_by_flow(second, first, cv2.INTER_LINEAR, cv2.BORDER_REPLICATE)
    return np.add(first, sampled, out=out)


def warp_nearest(image: npt.ArrayLike, flow: np.ndarray, fill: float = np.nan) -> np.ndarray:
    """Register ``image`` (frame t) to the reference grid: ``out(p) = image(round(p + flow(p)))``.

    Nearest-neighbour sampling (never interpolates depth). Samples that fall outside the frame
    get ``fill`` (NaN by default: "outside", which abstains in the fusion, unlike 0 = "no
    return").
    """
    img = np.asarray(image)
    h, w = img.shape[:2]
    xs, ys = identity_grid(h, w)
    xi = np.floor(xs + flow[..., 0] + 0.5).astype(np.intp)
    yi = np.floor(ys + flow[..., 1] + 0.5).astype(np.intp)
    inside = (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
    out = np.full(
        img.shape,
        fill,
        dtype=np.result_type(img.dtype, np.float32) if np.isnan(fill) else img.dtype,
    )
    out[inside] = img[yi[inside], xi[inside]]
    return out


def flows_to_reference(
    ref: int,
    backward: Sequence[np.ndarray | None],
    forward: Sequence[np.ndarray | None],
    shape: tuple[int, int],
) -> list[np.ndarray]:
    """Motion from every frame of a window back to its reference, by composition.

    The mirror of :func:`cumulative_flows`: for t < t0, C_{t→t0} = F_{t→t+1} then C_{t+1→t0}
    (and symmetrically after t0). Used to forward-register the low-res samples of a window
    (:func:`upsr.method.fusion.splat_nearest`).
    """
    n = len(forward)
    maps: list[np.ndarray | None] = [None] * n
    maps[ref] = np.zeros((*shape, 2), np.float32)
    for direction, consecutive in ((-1, forward), (1, backward)):
        j = ref + direction
        while 0 <= j < n:
            step = consecutive[j]
            assert step is not None
            maps[j] = compose_flows(step, maps[j - direction])  # type: ignore[arg-type]
            j += direction
    return maps  # type: ignore[return-value]


def sample_offsets(flow: np.ndarray, scale: int) -> np.ndarray:
    """Distance (high-res px) between where each reference pixel lands in frame t and the centre
    of the low-res pixel that :func:`warp_nearest` samples there.

    A low-res pixel is a point sample of the scene at its centre ((i+0.5)·r − 0.5, ``SPEC.md``
    §1); its value describes the reference pixel the better, the closer that centre is to the
    registered position. Used to weight the votes of the fusion at depth edges.
    """
    h, w = flow.shape[:2]
    xs, ys = identity_grid(h, w)
    qx = xs + flow[..., 0]
    qy = ys + flow[..., 1]
    cx = (np.floor(np.floor(qx + 0.5) / scale) + 0.5) * scale - 0.5
    cy = (np.floor(np.floor(qy + 0.5) / scale) + 0.5) * scale - 0.5
    return np.hypot(qx - cx, qy - cy).astype(np.float32)


def warp_guide(image: np.ndarray, flow: np.ndarray) -> np.ndarray:
    """Register an 8-bit motion guide image with bilinear sampling (0 outside the frame).

    Only for the images the flow is estimated on (eq. 19): sub-pixel accuracy matters there,
    and they are never fused. Depth itself is only ever warped by :func:`warp_nearest`.
    """
    return remap_by_flow(image, flow, cv2.INTER_LINEAR, cv2.BORDER_CONSTANT)


def cumulative_flows(
    ref: int,
    backward: Sequence[np.ndarray | None],
    forward: Sequence[np.ndarray | None],
    shape: tuple[int, int],
    *,
    refine: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    guides: Sequence[np.ndarray] | None = None,
    parallel: bool = False,
    out: np.ndarray | None = None,
) -> list[np.ndarray]:
    """Motion from the reference to every frame of a window, by composition (eq. 20–21).

    Parameters
    ----------
    ref : int
        Index of the reference frame in the window (0 … N−1).
    backward : sequence of N flows
        ``backward[j]`` is the consecutive flow from frame j to frame j−1 (``backward[0]`` unused).
    forward : sequence of N flows
        ``forward[j]`` is the consecutive flow from frame j to frame j+1 (``forward[N-1]`` unused).
    shape : (H, W)
        Size of the (upsampled) frames in px.
    refine : callable, optional
        Flow backend used for the eq. 19 re-estimation: for each frame two or more steps from
        the reference, in order of distance, the residual flow between its registered neighbour
        and its own registered image (``guides`` warped with the current cumulative flow) is
        composed into the motion. (The reference's direct neighbours are registered by a
        consecutive flow estimated against the reference itself; re-estimating it would repeat
        the same estimate — measured: no gain, 25 % more flows at N = 9.)
    guides : sequence of N uint8 images, optional
        The images the flow is computed on (required with ``refine``).
    parallel : bool
        Compute the frames before and after the reference side by side
        (:func:`upsr.method._parallel.both`; same result). Only for a thread-safe ``refine``.
    out : ndarray (N, H, W, 2) float32, optional
        Where to write the flows (the list then holds views of it).

    Returns
    -------
    list of N flows from the reference grid to each frame (zero for the reference itself).
    """
    n = len(forward)
    h, w = shape
    if out is None:
        out = np.empty((n, h, w, 2), np.float32)
    maps: list[np.ndarray | None] = [None] * n
    out[ref] = 0.0
    maps[ref] = out[ref]
    registered: list[np.ndarray | None] = [None] * n
    if refine is not None:
        if guides is None:
            raise ValueError("refine needs the guide images")
        registered[ref] = guides[ref]

    def chain(direction: int, consecutive: Sequence[np.ndarray | None]) -> None:
        j = ref + direction
        while 0 <= j < n:
            prev = j - direction
            step = consecutive[prev]
            assert step is not None and maps[prev] is not None
            if refine is not None and abs(j - ref) > 1:
                # eq. 19; the reference's direct neighbours are skipped: their motion *is* an
                # estimate against the (trivially registered) reference already
                cum = compose_flows(maps[prev], step)
                residual = refine(registered[prev], warp_guide(guides[j], cum))  # type: ignore
                compose_flows(residual, cum, out=out[j])
            elif prev == ref:
                out[j] = step  # composed with the reference's zero motion: the step itself
            else:
                compose_flows(maps[prev], step, out=out[j])
            maps[j] = out[j]
            if refine is not None and 0 <= j + direction < n:
                # the registered image of the next frame's neighbour (none after the last)
                registered[j] = warp_guide(guides[j], maps[j])  # type: ignore[index]
            j += direction

    # the frames before and after the reference are independent chains: one per core
    both(lambda: chain(-1, backward), lambda: chain(1, forward), enabled=parallel)
    return maps  # type: ignore[return-value]


# --------------------------------------------------------------------------------------------
# Compiled registration of a window: motion estimated on a coarser grid than the output
# --------------------------------------------------------------------------------------------
#
# The flow may be estimated on frames upsampled by a factor ``flow_scale`` = s ≤ r (the "flow
# grid", s·h × s·w) rather than by r: a pixel centre x of the high-res grid sits at
# (x + 0.5)·s/r − 0.5 on the flow grid, and a displacement of 1 flow px is r/s high-res px.
# With s = r, upsr.method.fusion.register_and_fuse reproduces warp_nearest / sample_offsets exactly.


@nb.njit(cache=True, nogil=True, inline="always")
def _bilinear(field, u, v, c):  # pragma: no cover - numba
    """Channel c of field (H, W, 2) at (u, v), bilinear, clamped to the border."""
    hf, wf = field.shape[0], field.shape[1]
    u = min(max(u, 0.0), wf - 1.0)
    v = min(max(v, 0.0), hf - 1.0)
    x0 = min(int(u), wf - 2) if wf > 1 else 0
    y0 = min(int(v), hf - 2) if hf > 1 else 0
    x1 = min(x0 + 1, wf - 1)
    y1 = min(y0 + 1, hf - 1)
    fx = u - x0
    fy = v - y0
    top = field[y0, x0, c] * (1.0 - fx) + field[y0, x1, c] * fx
    bot = field[y1, x0, c] * (1.0 - fx) + field[y1, x1, c] * fx
    return top * (1.0 - fy) + bot * fy


def interpolation_tables(
    out_shape: tuple[int, int], flow_shape: tuple[int, int]
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], float]:
    """Column and row tables of the bilinear interpolation from the flow grid to the output
    grid, and the ratio r/s of their pixel sizes."""
    ratio = out_shape[1] / flow_shape[1]
    cols = _interpolation_table(out_shape[1], flow_shape[1], ratio)
    rows = _interpolation_table(out_shape[0], flow_shape[0], ratio)
    return cols, rows, float(ratio)


@nb.njit(cache=True, nogil=True, parallel=True, fastmath=SAFE_FASTMATH, error_model="numpy")
def _positions_kernel(flow, ratio, cols, fx, rows, fy, qx, qy):  # pragma: no cover - numba
    """(qx, qy)[y, x] = (x, y) + ratio · the flow read bilinearly at the pixel's centre on
    the flow grid (the tables of :func:`interpolation_tables`)."""
    hh, ww = qx.shape
    for y in nb.prange(hh):
        r0 = rows[y, 0]
        r1 = rows[y, 1]
        wy = fy[y]
        for x in range(ww):
            c0 = cols[x, 0]
            c1 = cols[x, 1]
            wx = fx[x]
            for c in range(2):
                top = flow[r0, c0, c] + (flow[r0, c1, c] - flow[r0, c0, c]) * wx
                bot = flow[r1, c0, c] + (flow[r1, c1, c] - flow[r1, c0, c]) * wx
                v = top + (bot - top) * wy
                if c == 0:
                    qx[y, x] = x + v * ratio
                else:
                    qy[y, x] = y + v * ratio


def flow_positions(
    flow: npt.ArrayLike, out_shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Where each pixel of an output grid comes from, through a flow on a coarser grid.

    Parameters
    ----------
    flow : array_like float32 (fh, fw, 2)
        Backward flow (dx, dy) on the flow grid (flow-grid px), e.g. from the current frame
        to the previous one.
    out_shape : (H, W)
        The output grid, whose pixel size is W / fw flow-grid px.

    Returns
    -------
    (qx, qy) : ndarray float32 (H, W)
        Position (output-grid px) of each output pixel (x, y) in the other frame: (x, y) +
        (W / fw) · the flow read bilinearly at the pixel's centre (pixel centres aligned, as
        ``cv2.resize``).
    """
    fl = np.ascontiguousarray(flow, np.float32)
    (cols, fx), (rows, fy), ratio = interpolation_tables(tuple(out_shape), fl.shape[:2])
    qx = np.empty(tuple(out_shape), np.float32)
    qy = np.empty(tuple(out_shape), np.float32)
    _positions_kernel(fl, ratio, cols, fx, rows, fy, qx, qy)
    return qx, qy


def weight_table(scale: int, sigma_px: float | None) -> tuple[np.ndarray, float]:
    """g(d) = exp(−d²/(2σ²)) tabulated every 1/64 px for 0 ≤ d ≤ r + 1/32 px (all ones
    without σ), and the number of entries per px: exp(−(dx² + dy²)/(2σ²)) = g(dx)·g(dy)."""
    steps = 64.0
    d = np.arange(int(np.ceil(scale * steps)) + 2) / steps
    if not sigma_px:
        return np.ones(d.size, np.float32), steps
    return np.exp(-(d**2) / (2.0 * float(sigma_px) ** 2)).astype(np.float32), steps


def _interpolation_table(n_out: int, n_in: int, ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """Neighbours (n_out, 2) and weights of the bilinear interpolation from n_in to n_out
    samples with pixel centres aligned ((x + 0.5)/ratio − 0.5, clamped; like cv2.resize)."""
    u = np.clip((np.arange(n_out) + 0.5) / ratio - 0.5, 0.0, n_in - 1.0)
    lo = np.minimum(np.floor(u).astype(np.int64), max(n_in - 2, 0))
    hi = np.minimum(lo + 1, n_in - 1)
    return np.stack([lo, hi], axis=1), (u - lo).astype(np.float32)


def sample_centres(lowres_shape: tuple[int, int], grid_scale: int) -> np.ndarray:
    """The centres of the low-res pixels (``SPEC.md`` §1) on a flow grid upsampled by
    ``grid_scale``: (h, w, 2) float64 (x, y) = ((j + 0.5)·s − 0.5, (i + 0.5)·s − 0.5)."""
    h, w = lowres_shape
    s = float(grid_scale)
    out = np.empty((h, w, 2), np.float64)
    out[..., 0] = (np.arange(w) + 0.5) * s - 0.5
    out[..., 1] = ((np.arange(h) + 0.5) * s - 0.5)[:, None]
    return out


@nb.njit(cache=True, nogil=True)
def _advance_kernel(pos, flow, out):  # pragma: no cover - numba
    h, w = pos.shape[0], pos.shape[1]
    for i in range(h):
        for j in range(w):
            u = pos[i, j, 0]
            v = pos[i, j, 1]
            du = _bilinear(flow, u, v, 0)
            dv = _bilinear(flow, u, v, 1)
            out[i, j, 0] = u + du
            out[i, j, 1] = v + dv


def advance_positions(positions: np.ndarray, flow: np.ndarray) -> np.ndarray:
    """One step of a chain of consecutive flows: ``p + flow(p)`` for each position p (flow
    grid px, (…, 2) float64), the flow read bilinearly at p (clamped to the border)."""
    out = np.empty_like(positions)
    _advance_kernel(positions, np.ascontiguousarray(flow, np.float32), out)
    return out


def to_output_grid(
    positions: np.ndarray, ratio: float, out: np.ndarray | None = None
) -> np.ndarray:
    """Flow-grid positions (float64) as high-res px of the output grid, float32
    (pixel centres aligned: (p + 0.5)·r/s − 0.5)."""
    res = (positions + 0.5) * float(ratio) - 0.5
    if out is None:
        return res.astype(np.float32)
    out[...] = res
    return out


def trace_to_reference(
    ref: int,
    forward: Sequence[np.ndarray | None],
    backward: Sequence[np.ndarray | None],
    lowres_shape: tuple[int, int],
    scale: int,
) -> np.ndarray:
    """Where each low-res sample of a window lands in the reference frame (high-res px).

    The centre of low-res pixel (i, j) of frame t (``SPEC.md`` §1) is followed through the
    consecutive flows towards the reference (``forward[t]``, ``forward[t+1]``, … before it,
    ``backward[t]``, … after it), each read bilinearly at the current position: the exact
    chain of :func:`flows_to_reference`, evaluated only at the N·h·w sample points. Used to
    forward-register the samples (:func:`upsr.method.fusion.splat_points`). The streaming engine
    keeps each frame's chain from one window to the next (:func:`advance_positions`).

    Parameters
    ----------
    ref : int
        Index of the reference in the window.
    forward, backward : sequences of N flows on the flow grid (s·h, s·w, 2)
        ``forward[j]``: frame j → j+1 (needed for j < ref); ``backward[j]``: j → j−1 (j > ref).
    lowres_shape : (h, w)
    scale : int
        SR factor r.

    Returns
    -------
    ndarray float32 (N, h, w, 2): (x, y) in high-res px of the reference grid.
    """
    h, w = lowres_shape
    n = len(forward)
    some = next((f for f in (*forward, *backward) if f is not None), None)
    wf = some.shape[1] if some is not None else w * scale
    s = wf // w
    out = np.empty((n, h, w, 2), np.float32)
    centres = sample_centres((h, w), s)
    for k in range(n):
        pos = centres  # (advance_positions makes new arrays)
        for m in range(k, ref) if k < ref else range(k, ref, -1):
            pos = advance_positions(pos, (forward if k < ref else backward)[m])  # type: ignore[arg-type]
        to_output_grid(pos, scale / s, out=out[k])
    return out


@nb.njit(cache=True, nogil=True, parallel=True, fastmath=SAFE_FASTMATH, error_model="numpy")
def _registered_state_kernel(depth, qx, qy, scale, out):  # pragma: no cover - numba
    """out[i, j]: the state at low-res pixel (i, j)'s centre, moved by the flow: the mean of
    the (nearest) state at the 1 (odd r) or 2×2 (even r) output pixels around the centre, 0
    where one of them has no state or they lie on different surfaces."""
    h, w = out.shape
    hh, ww = depth.shape
    c = scale // 2
    lo = c - 1 if scale % 2 == 0 else c
    for i in nb.prange(h):
        for j in range(w):
            total = 0.0
            vmin = np.inf
            vmax = 0.0
            m = 0
            for y in range(i * scale + lo, i * scale + c + 1):
                for x in range(j * scale + lo, j * scale + c + 1):
                    xi = math.floor(qx[y, x] + 0.5)
                    yi = math.floor(qy[y, x] + 0.5)
                    v = 0.0
                    if 0 <= xi < ww and 0 <= yi < hh:
                        v = depth[yi, xi]
                    if v > 0:
                        total += v
                        vmin = min(vmin, v)
                        vmax = max(vmax, v)
                        m += 1
            n_px = (c + 1 - lo) * (c + 1 - lo)
            out[i, j] = total / m if m == n_px and vmax - vmin < 100.0 else 0.0
