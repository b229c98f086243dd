"""How many frames each pixel's estimate may draw on (beyond the paper).

A fused estimate of a flat surface improves with every registered frame; one of a steep slope
does not: a registration error of ε low-res pixels moves a sample of a slope of g mm per
pixel by ε·g in depth, and the recursive state, carried from frame to frame, gathers such an
error every frame. :func:`state_caps` gives each low-res pixel the count at which the gain of
one more frame stops outweighing that error (the steady state of a scalar Kalman filter whose
process noise is (ε·g)²). :func:`level_to_reference` applies the same weights to a window's
fused blocks: their shape comes from all the frames, their level, where the slope is steep
for the noise, from the reference's own measurement; :func:`beyond_reach` bounds how far in
time a window reaches for a pixel that moved; :func:`innovation_caps` lowers the recursive
state's caps on a slope where its differences from the frame show more process noise than
the assumed registration error gives.

References
----------
Kalman, R. E. (1960). A new approach to linear filtering and prediction problems. *Journal of
Basic Engineering* 82(1), 35–45.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from upsr.method.config import UPSRConfig
from upsr.method.consistency import maps_at_centres
from upsr.method.noise import _sigma_at
from upsr.method.trust import TOLERANCE_FLOOR_MM, _sigma_and_power

__all__ = [
    "INNOVATION_EXCESS",
    "INNOVATION_RADIUS_PX",
    "MOVED_PX",
    "REACH_MIN_FRAMES",
    "REGISTRATION_ERROR_PX",
    "RELIEF_NOISE_FACTOR",
    "beyond_reach",
    "innovation_caps",
    "level_to_reference",
    "moving_caps",
    "state_caps",
]

#: ε of :func:`state_caps`: the registration error (low-res px) that the state of a slope
#: accumulates every frame. Measured (``benchmarks/realistic_eval.py --quick --no-oracle``,
#: seeds 0–2, and ``benchmarks/recursive_eval.py --sizes tof qvga --frames 16``): see the
#: README's recursive section.
REGISTRATION_ERROR_PX = 0.25
#: The relief (in σ) of a flat surface's noisy anchors, not counted as slope by
#: :func:`state_caps` (1: Laplace σ = 30 moving surfaces up to 5 % worse than without caps).
RELIEF_NOISE_FACTOR = 2.0
#: :func:`beyond_reach`: the frames this close to the reference always take part.
REACH_MIN_FRAMES = 2
#: :func:`beyond_reach`: a pixel whose motion to a frame exceeds this (low-res px) moved.
MOVED_PX = 0.5
#: :func:`moving_caps`: the most frames a moving pixel's recursive state summarises, on any
#: surface (``benchmarks/recursive_eval.py --scenes deforming room toward_wall gallop --sizes
#: tof --frames 16 --modes recursive``: the animal's surface rmse 1.408 → 1.384 mm with 5,
#: 1.402 with 7, 1.422 with 4 and 1.440 with 3, where the static wall beside the body, to
#: which the flow spreads the body's motion, starts to lose).
MOVING_STATE_FRAMES = 5.0
#: :func:`innovation_caps`: the half-size (low-res px) of the neighbourhood whose differences
#: between the registered state and the frame measure the state's process noise.
INNOVATION_RADIUS_PX = 2
#: :func:`innovation_caps`: the share of the noise's variance by which those differences must
#: exceed it before the excess counts (their mean square over 25 pixels scatters by about
#: half the variance under Laplacian noise: 2 is two of those spreads above).
INNOVATION_EXCESS = 2.0
#: :func:`innovation_caps`: the plane slope (noise σ per low-res px) from which a pixel's cap
#: follows its state's innovation (:func:`upsr.method.slopes.sloped_pixels`).
INNOVATION_SLOPE_SIGNIFICANCE = 1.0


def state_caps(
    anchor: np.ndarray,
    tolerance: np.ndarray,
    cap: float,
    sigma_mm: float,
    k: float,
    *,
    noise_profile: tuple[float, float] | None = None,
    registration_px: float = REGISTRATION_ERROR_PX,
    tolerance_sigma_mm: float | None = None,
) -> np.ndarray:
    """The largest count of the state per low-res pixel: how many frames its surface lets it
    summarise.

    The state of a pixel on a slope of g mm per low-res pixel, carried by a flow that is off
    by ε = ``registration_px``, gains an error of about ε·g every frame: a random walk of
    variance q = (ε·g)² (the process noise of a Kalman filter), against the measurement's σ².
    A running mean whose error variance v is the steady state of that filter, v² + q·v =
    q·σ², i.e. v = (√(q² + 4qσ²) − q) / 2, weighs the measurement 1/n with n = σ²/v =
    (1 + √(1 + 4σ²/q)) / 2: about σ/(ε·g) frames where ε·g ≪ σ, one frame where ε·g ≥ σ (a
    steep slope: the current frame alone is the best estimate; without noise, every slope),
    ``cap`` on a flat surface.

    The slope is the relief of the reference's surface over one low-res pixel in
    :func:`~upsr.method.trust.reference_anchor`'s ``tolerance`` (τ = k·σ + relief), less
    :data:`RELIEF_NOISE_FACTOR`·σ, the relief of a flat surface's noisy anchors; a tolerance
    at its floor (:data:`~upsr.method.trust.TOLERANCE_FLOOR_MM`) is a flat surface.

    Parameters
    ----------
    anchor, tolerance : ndarray float32 (h, w)
        :func:`~upsr.method.trust.reference_anchor` of the measurement with ``k``.
    cap : float
        The state's largest count anywhere (``n_frames``).
    sigma_mm : float
        Noise std (mm).
    k : float
        The ``k`` of the tolerance; 0 (no trust test): ``cap`` everywhere.
    noise_profile : (float, float), optional
        (σ₁, p): σ(z) = σ₁·(z / 1 m)^p at each pixel's anchor (p > 0) instead of ``sigma_mm``.
    registration_px : float
        ε, the registration error of the state (low-res px).
    tolerance_sigma_mm : float, optional
        The σ ``tolerance`` was computed with, where it is not the sample's noise
        ``sigma_mm`` (the trust's σ, which a moving camera inflates: ``reach_noise_mm`` of
        :class:`~upsr.method.config.UPSRConfig`); the relief is the tolerance less k times it.

    Returns
    -------
    ndarray float32 (h, w) in [1, cap].

    Examples
    --------
    A wall beside a box side seen at a grazing angle (400 mm per pixel), σ = 10 mm:

    >>> from upsr.method.trust import reference_anchor
    >>> z = np.tile(np.r_[[3000.0] * 4, 1000.0 + 400.0 * np.arange(4)], (5, 1))
    >>> anchor, tol = reference_anchor(z, 10.0, 3.0, 1000.0)
    >>> state_caps(anchor, tol, 9.0, 10.0, 3.0)[2].astype(float).round(2).tolist()
    [9.0, 9.0, 9.0, 9.0, 1.05, 1.01, 1.01, 1.05]
    """
    if not (registration_px > 0 and k > 0):
        return np.full(anchor.shape, np.float32(cap))
    if tolerance_sigma_mm is not None:  # the same relief, against the sample's noise
        tolerance = tolerance - np.float32(k * (tolerance_sigma_mm - sigma_mm))
    s1, power = _sigma_and_power(sigma_mm, noise_profile)
    sigma = np.float32(s1) * (np.maximum(anchor, 1.0) / np.float32(1000.0)) ** np.float32(power)
    slope = np.maximum(tolerance - np.float32(k + RELIEF_NOISE_FACTOR) * sigma, 0.0)
    slope[tolerance <= TOLERANCE_FLOOR_MM] = 0.0  # no relief beyond the floor: flat
    q = (np.float32(registration_px) * slope) ** 2
    # σ²/q: ∞ on a flat surface
    ratio = np.divide(sigma * sigma, q, out=np.full(q.shape, np.inf, np.float32), where=q > 0)
    n = 0.5 * (1.0 + np.sqrt(1.0 + 4.0 * ratio))
    return np.clip(n, 1.0, cap).astype(np.float32)


@nb.njit(cache=True, nogil=True, parallel=True)
def _level_kernel(fused, reference, weight, scale, edge, out):  # pragma: no cover - numba
    h, w = reference.shape
    n_px = scale * scale
    for i in nb.prange(h):
        for j in range(w):
            wt = weight[i, j]
            m = reference[i, j]
            if not (wt > 0 and m > 0):
                continue
            total = 0.0
            lo = np.inf
            hi = -np.inf
            full = True
            for y in range(i * scale, (i + 1) * scale):
                for x in range(j * scale, (j + 1) * scale):
                    v = fused[y, x]
                    full = full and v > 0
                    total += v
                    lo = min(lo, v)
                    hi = max(hi, v)
            if not full or hi - lo > edge:
                continue
            shift = wt * (m - total / n_px)
            for y in range(i * scale, (i + 1) * scale):
                for x in range(j * scale, (j + 1) * scale):
                    out[y, x] = max(fused[y, x] + shift, 1e-3)


def level_to_reference(
    fused: np.ndarray,
    reference: np.ndarray,
    caps: np.ndarray,
    cfg: UPSRConfig,
    *,
    edge_mm: float,
) -> np.ndarray:
    """A window's fused blocks moved towards the reference's own measurement where the other
    frames cannot be trusted to carry their level.

    The fused block of low-res pixel (i, j) is the registered samples of N frames; on a slope
    steep for the noise their registration errors move its level (a box side seen at a
    grazing angle by a camera walking towards it: ramps of 80–400 mm per pixel whose other
    frames' samples come from the zoomed neighbourhood). Each block whose r×r pixels all have
    depth and lie on one surface (a span of at most ``edge_mm``) is shifted by
    w·(m − its mean), m the reference's sample, w = (1/n* − 1/N) / (1 − 1/N) with n* the
    pixel's cap (:func:`state_caps`): 0 on a flat surface (the fusion's level is kept), 1
    where n* = 1 (the level is the reference's; without noise, on every slope). The block's
    shape, the sub-pixel detail of the other frames, is kept; a block across a depth edge is
    left alone (no flying pixels).

    Parameters
    ----------
    fused : ndarray float32 (r·h, r·w)
        The fused frame (mm, 0 = none).
    reference : ndarray float32 (h, w)
        The reference frame as fused (mm; 0, negative or NaN: no measurement).
    caps : ndarray float32 (h, w)
        :func:`state_caps` of the reference's anchor and tolerance with ``cfg.trust_k``.
    cfg : UPSRConfig
        N (``n_frames``), r (``scale``) and k (``trust_k``; None: nothing moves).
    edge_mm : float
        Depth step that separates two surfaces.

    Returns
    -------
    ndarray float32 (r·h, r·w): a new frame; 0 stays 0.
    """
    src = np.ascontiguousarray(fused, np.float32)
    out = src.copy()
    n = float(cfg.n_frames)
    if not (n > 1 and cfg.trust_k is not None):
        return out
    weight = (1.0 / caps - 1.0 / n) / (1.0 - 1.0 / n)
    _level_kernel(
        src,
        np.ascontiguousarray(reference, np.float32),
        np.clip(weight, 0.0, 1.0).astype(np.float32),
        int(cfg.scale),
        float(edge_mm),
        out,
    )
    return out


def beyond_reach(
    maps: np.ndarray,
    caps: np.ndarray,
    ref: int,
    *,
    grid_scale: float,
    centres: np.ndarray | None = None,
) -> np.ndarray:
    """The samples of a window farther in time than its pixel's estimate may reach.

    A pixel whose cap n* (:func:`state_caps`) is below N summarises about n* frames before
    the registration errors on its slope outweigh the noise they average; a window centred on
    it spans (n* − 1)/2 frames on each side. Where the pixel moved (its motion to the frame
    beyond :data:`MOVED_PX`), the frames farther from the reference than
    max(:data:`REACH_MIN_FRAMES`, ⌊(n* − 1)/2⌋) abstain there: near the ends of a clip, where
    the window is shifted inwards, a moving body's samples 5–8 frames away from its reference
    no longer vote (realistic scenes, seeds 0–2, `benchmarks/realistic_eval.py --quick
    --no-oracle`: the Kinect deforming body's moving surface rmse 2.51 / 2.68 / 2.66 →
    2.42 / 2.57 / 2.57 mm, below the per-frame bilateral filter's 2.67 / 2.65 / 2.65; the rooms'
    −2 to −7 % except under Kinect noise, +3 %). Static pixels, flat surfaces (n* = N) and
    the frames near the reference are never affected.

    Parameters
    ----------
    maps : array_like (N, s·h, s·w, 2)
        Motion from the reference to each frame on the flow grid (flow px).
    caps : ndarray float32 (h, w)
        :func:`state_caps` of the reference's anchor and tolerance, with cap N.
    ref : int
        Index of the reference in the window.
    grid_scale : float
        s, flow-grid pixels per low-res pixel.
    centres : ndarray (N, h, w, 2), optional
        :func:`upsr.method.consistency.maps_at_centres` of ``maps``, when already computed.

    Returns
    -------
    ndarray bool (N, h, w): True where frame k's sample registered to reference pixel (i, j)
    abstains.
    """
    n = len(maps)
    out = np.zeros((n, *caps.shape), bool)
    if n <= 2 * REACH_MIN_FRAMES + 1:
        return out
    far = np.abs(np.arange(n) - int(ref))[:, None, None] > _reach(caps, n)[None]
    np.logical_and(_moved(maps, caps.shape, grid_scale, centres), far, out=out)
    return out


def moving_caps(
    caps: np.ndarray,
    flow: np.ndarray,
    n_frames: int,
    *,
    grid_scale: float,
    centres: np.ndarray | None = None,
) -> np.ndarray:
    """The recursive mode's :func:`state_caps` where the pixel moved since the last frame.

    The recursive counterpart of :func:`beyond_reach`: where a pixel whose cap n* is below
    N moved (its motion to the previous frame beyond :data:`MOVED_PX`), its state summarises
    at most max(:data:`REACH_MIN_FRAMES`, ⌊(n* − 1)/2⌋) frames, and any moving pixel at most
    :data:`MOVING_STATE_FRAMES` (a flat moving surface's state also gathers the registration
    error of the frames it carries: the realistic scenes' recursive surface rmse −0.2 /
    −0.2 / −0.3 % geomean on seeds 0 / 1 / 2, at most +0.3 % on any case): a moving slope's state
    carried over many frames gathers the registration error of each (realistic scenes, seeds
    0–2, ``benchmarks/realistic_eval.py --quick --no-oracle``, recursive rows: the Kinect
    deforming body's moving surface rmse 2.74 / 2.76 / 2.74 → 2.62 / 2.68 / 2.63 mm, the
    rooms under Laplace σ = 30 and Gaussian σ = 20 noise −2 to −3 %, the galloping animal at
    Laplace σ = 30 +2 to +5 %; edges, flying and missing pixels unchanged). A reach of one
    more frame (the state's count counts the current frame) gained a third as much.

    Parameters
    ----------
    caps : ndarray float32 (h, w)
        :func:`state_caps` of the current frame's anchor and tolerance, with cap N.
    flow : ndarray float32 (s·h, s·w, 2)
        Motion from the current frame to the previous one on the flow grid (flow px).
    n_frames : int
        N, the largest cap.
    grid_scale : float
        s, flow-grid pixels per low-res pixel.
    centres : ndarray (1, h, w, 2), optional
        :func:`upsr.method.consistency.maps_at_centres` of ``flow[None]``, when already
        computed.

    Returns
    -------
    ndarray float32 (h, w): ``caps``, lowered where the pixel moved.
    """
    moved = _moved(flow[None], caps.shape, grid_scale, centres)[0]
    reach = np.minimum(np.minimum(caps, _reach(caps, n_frames)), MOVING_STATE_FRAMES)
    return np.where(moved, reach, caps).astype(np.float32)


def _reach(caps: np.ndarray, n_frames: int) -> np.ndarray:
    """max(:data:`REACH_MIN_FRAMES`, ⌊(n* − 1)/2⌋) frames where n* < N, ∞ elsewhere."""
    reach = np.maximum(np.floor((caps - 1.0) / 2.0), REACH_MIN_FRAMES)
    reach[caps >= n_frames] = np.inf
    return reach


def _moved(
    maps: np.ndarray, shape: tuple[int, int], grid_scale: float, centres: np.ndarray | None
) -> np.ndarray:
    """Where each map moves the low-res pixel centre by more than :data:`MOVED_PX`
    (``centres``: :func:`maps_at_centres` of ``maps``, or None)."""
    at = (maps_at_centres(maps, shape) if centres is None else centres) / float(grid_scale)
    return at[..., 0] ** 2 + at[..., 1] ** 2 > MOVED_PX**2


def innovation_caps(
    caps: np.ndarray,
    registered: np.ndarray,
    measurement: np.ndarray,
    offsets: np.ndarray,
    count: np.ndarray,
    sloped: np.ndarray,
    sigma_mm: float,
    *,
    noise_profile: tuple[float, float] | None = None,
) -> np.ndarray:
    """The recursive mode's caps where the state of a slope strays from the frames: the
    process noise of :func:`state_caps` measured rather than assumed.

    :func:`state_caps` takes the state's registration error for ε =
    :data:`REGISTRATION_ERROR_PX` everywhere and a slope from the tolerance's relief, which
    counts a slope below (k + :data:`RELIEF_NOISE_FACTOR`)·σ per pixel as flat. Where the flow
    is off on a slope by more (an approaching camera's narrow box tops: the state of those
    slopes drifts nearer frame after frame, its error over N frames above that of one frame
    alone, ``benchmarks/surface_errors.py``), the registered state differs from the frame by
    more than their noise allows: on the pixels of a significant slope (``sloped``), the mean
    square of those differences over the (2·:data:`INNOVATION_RADIUS_PX` + 1)² pixels around
    (each clipped at 3 standard deviations; the applied radial ``offsets`` removed) beyond
    :data:`INNOVATION_EXCESS` times the variance σ²·(1 + 1/n) that the noise gives a state of
    count n is the process noise q of the Kalman filter of :func:`state_caps`, and the cap
    there is at most (1 + √(1 + 4σ²/q)) / 2. Flat surfaces keep their caps: a moving body's
    state differs from the frame where the flow does not follow it, which the trust rules
    handle (lowering its caps too cost the realistic animal and deforming body 5–18 % of
    surface rmse at σ = 30).

    Parameters
    ----------
    caps : ndarray float32 (h, w)
        The caps so far (:func:`state_caps`, :func:`moving_caps`).
    registered : ndarray float32 (h, w)
        The previous state at each low-res pixel's centre, moved by the flow (mm, 0 = none).
    measurement : ndarray float32 (h, w)
        The current frame (mm, 0 = none).
    offsets : ndarray float32 (h, w)
        The radial offsets applied to the registered state (mm).
    count : ndarray float32 (h, w)
        The state's count at each low-res pixel.
    sloped : ndarray bool (h, w)
        The pixels on a significant slope.
    sigma_mm : float
        Noise std (mm); with ``noise_profile`` (σ₁, p), σ₁ of σ(z) = σ₁·(z / 1 m)^p at the
        measurement's depth.

    Returns
    -------
    ndarray float32 (h, w): ``caps``, lowered where the differences say so.
    """
    if not sigma_mm > 0 or not sloped.any():
        return caps
    s1, power = _sigma_and_power(sigma_mm, noise_profile)
    out = np.array(caps, np.float32)
    _innovation_kernel(
        np.ascontiguousarray(registered, np.float32),
        np.ascontiguousarray(measurement, np.float32),
        np.ascontiguousarray(offsets, np.float32),
        np.ascontiguousarray(count, np.float32),
        np.ascontiguousarray(sloped, np.bool_),
        float(s1), float(power), INNOVATION_RADIUS_PX, INNOVATION_EXCESS, out,
    )  # fmt: skip
    return out


@nb.njit(cache=True, nogil=True, parallel=True)
def _innovation_kernel(
    registered, measurement, offsets, count, sloped, s1, power, radius, excess, out
):  # pragma: no cover - numba
    h, w = measurement.shape
    # each pixel's clipped square difference (−1: none) and the variance the noise allows it
    square = np.full((h, w), -1.0)
    expected = np.zeros((h, w))
    for i in nb.prange(h):
        for j in range(w):
            m = measurement[i, j]
            if not m > 0:
                continue
            sig = _sigma_at(s1, power, max(m, 1.0))
            e = sig * sig * (1.0 + 1.0 / max(count[i, j], 1.0))
            expected[i, j] = e
            v = registered[i, j]
            if v > 0:
                d = v - offsets[i, j] - m
                square[i, j] = min(d * d, 9.0 * e)
    for i in nb.prange(h):
        for j in range(w):
            if not (sloped[i, j] and expected[i, j] > 0.0):
                continue
            total = 0.0
            n = 0
            for a in range(max(i - radius, 0), min(i + radius + 1, h)):
                for b in range(max(j - radius, 0), min(j + radius + 1, w)):
                    if square[a, b] >= 0.0:
                        total += square[a, b]
                        n += 1
            if n < 9:
                continue
            q = total / n - excess * expected[i, j]
            if q > 0.0:
                sig2 = expected[i, j] / (1.0 + 1.0 / max(count[i, j], 1.0))
                cap = 0.5 * (1.0 + math.sqrt(1.0 + 4.0 * sig2 / q))
                if cap < out[i, j]:
                    out[i, j] = cap
