"""How many frames each pixel's estimate may draw on (beyond the paper).

A fused estimate of a flat surface improves with every registered frame; one of a steep slope
does not: a registration error of ε low-res pixels moves a sample of a slope of g mm per
pixel by ε·g in depth, and the recursive state, carried from frame to frame, gathers such an
error every frame. :func:`state_caps` gives each low-res pixel the count at which the gain of
one more frame stops outweighing that error (the steady state of a scalar Kalman filter whose
process noise is (ε·g)²).

References
----------
Kalman, R. E. (1960). A new approach to linear filtering and prediction problems. *Journal of
Basic Engineering* 82(1), 35–45.
"""

from __future__ import annotations

import numpy as np

from upsr.method.trust import TOLERANCE_FLOOR_MM, _sigma_and_power

__all__ = ["REGISTRATION_ERROR_PX", "RELIEF_NOISE_FACTOR", "state_caps"]

#: ε of :func:`state_caps`: the registration error (low-res px) that the state of a slope
#: accumulates every frame. Measured (``benchmarks/realistic_eval.py --quick --no-oracle``,
#: seeds 0–2, and ``benchmarks/recursive_eval.py --sizes tof qvga --frames 16``): see the
#: README's recursive section.
REGISTRATION_ERROR_PX = 0.25
#: The relief (in σ) of a flat surface's noisy anchors, not counted as slope by
#: :func:`state_caps` (1: Laplace σ = 30 moving surfaces up to 5 % worse than without caps).
RELIEF_NOISE_FACTOR = 2.0


def state_caps(
    anchor: np.ndarray,
    tolerance: np.ndarray,
    cap: float,
    sigma_mm: float,
    k: float,
    *,
    noise_profile: tuple[float, float] | None = None,
    registration_px: float = REGISTRATION_ERROR_PX,
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
    s1, power = _sigma_and_power(sigma_mm, noise_profile)
    sigma = np.float32(s1) * (np.maximum(anchor, 1.0) / np.float32(1000.0)) ** np.float32(power)
    slope = np.maximum(tolerance - np.float32(k + RELIEF_NOISE_FACTOR) * sigma, 0.0)
    slope[tolerance <= TOLERANCE_FLOOR_MM] = 0.0  # no relief beyond the floor: flat
    q = (np.float32(registration_px) * slope) ** 2
    # σ²/q: ∞ on a flat surface
    ratio = np.divide(sigma * sigma, q, out=np.full(q.shape, np.inf, np.float32), where=q > 0)
    n = 0.5 * (1.0 + np.sqrt(1.0 + 4.0 * ratio))
    return np.clip(n, 1.0, cap).astype(np.float32)
