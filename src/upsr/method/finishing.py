"""What follows the fusion of one output frame (windowed and recursive modes alike).

:func:`settle_fused`: the windowed mode's rules between a window's fusion and its deblurring;
:func:`finish_fused`: UP-SR's own last steps (the deblurring of eq. 29–30 and the removal of
isolated outliers); :func:`finish_frame`: the rules beyond the paper that keep the output
honest afterwards (what the reference measured is never erased, removed input pixels are
split between their neighbours, blocks follow the slope of their surface, each surface is
smoothed along its plane (:func:`upsr.method.smoothing.smooth_output`), optional hole
filling).
"""

from __future__ import annotations

import numpy as np

from upsr.method.config import UPSRConfig
from upsr.method.consistency import clear_stale_fills
from upsr.method.deblurring import _deblur
from upsr.method.memory import level_to_reference
from upsr.method.mixed import split_mixed_pixels
from upsr.method.outliers import remove_speckles
from upsr.method.slopes import follow_slopes
from upsr.method.smoothing import smooth_output
from upsr.method.thin import ThinParts
from upsr.method.trust import fill_holes, reference_anchor, surface_support

__all__ = ["NOISE_SAMPLE_PX", "finish_frame", "finish_fused", "settle_fused"]

#: The deblurring's first step comes from the noise of about this many output pixels (every
#: k-th row of a larger output: the estimate is made anew for every frame). Both modes: at
#: 1024×592 the estimate from every row took 6.6 ms of a frame's 235 ms of CPU.
NOISE_SAMPLE_PX = 65536


def settle_fused(
    fused: np.ndarray,
    reference: np.ndarray,
    measured: np.ndarray,
    anchor: np.ndarray | None,
    caps: np.ndarray | None,
    cfg: UPSRConfig,
    *,
    edge_mm: float,
    keep_mean: bool = False,
    thin: ThinParts | None = None,
) -> np.ndarray:
    """The rules between a window's fusion and its deblurring (the engine and the
    straightforward path alike): with ``cfg.check_registration`` no fill of a hole behind a
    nearer surface (:func:`upsr.method.consistency.clear_stale_fills`); with an anchor, the
    level of blocks on slopes steep for the noise from the reference
    (:func:`upsr.method.memory.level_to_reference`); the reference's removed pixels (mixed,
    lone outliers) that no frame filled, split between their neighbours
    (:func:`upsr.method.mixed.split_mixed_pixels`, ``keep_mean`` for a footprint sensor).

    Parameters
    ----------
    fused : ndarray float32 (r·h, r·w)
    reference, measured : ndarray float32 (h, w)
        The reference as fused (removed pixels marked) and as measured (mm).
    anchor, caps : ndarray float32 (h, w) or None
        :func:`upsr.method.trust.reference_anchor` of the reference and the
        :func:`upsr.method.memory.state_caps` of it (None: trust off).
    cfg : UPSRConfig
    edge_mm : float
        The edge threshold (mm).
    keep_mean : bool
        A split block keeps the footprint's mean the reference measured (a ToF sensor).
    thin : upsr.method.thin.ThinParts, optional
        The reference's thin parts, where its mixed pixels' removal found them.

    Returns
    -------
    ndarray float32 (r·h, r·w)
    """
    if cfg.check_registration:
        fused = clear_stale_fills(fused, reference, cfg.scale, edge_mm)
    if caps is not None:
        fused = level_to_reference(fused, reference, caps, cfg, edge_mm=edge_mm)
    source = reference if anchor is None else anchor
    return split_mixed_pixels(
        fused,
        measured,
        reference,
        source,
        keep_mean=keep_mean,
        edge_mm=edge_mm,
        thin_parts=cfg.thin_parts,
        thin=thin,
    )


def finish_fused(
    fused_mm: np.ndarray,
    cfg: UPSRConfig,
    *,
    noise_profile: tuple[float, float] | None = None,
) -> np.ndarray:
    """UP-SR's steps after the fusion of a window: the deblurring (eq. 29–30, ``cfg.deblur``;
    its first step from the noise of every k-th row, about :data:`NOISE_SAMPLE_PX` pixels,
    each pixel's step following the ``noise_profile`` where it grows with depth), then the
    removal of isolated outliers (:func:`upsr.method.outliers.remove_speckles`). Not the
    deblurring's final smoothing: :func:`finish_frame` smooths last
    (:func:`upsr.method.smoothing.smooth_output`)."""
    out = _deblur(
        fused_mm,
        cfg.deblur,
        scale=cfg.scale,
        noise_row_step=max(1, fused_mm.size // NOISE_SAMPLE_PX),
        noise_profile=noise_profile,
    )
    return remove_speckles(out, cfg.speckle_size_px, cfg.edge_mm)


def finish_frame(
    out: np.ndarray,
    fused: np.ndarray,
    reference: np.ndarray,
    anchor: np.ndarray | None,
    cfg: UPSRConfig,
    *,
    edge_mm: float,
    noise_mm: float,
    measured: np.ndarray | None = None,
    slopes: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """The steps beyond the paper after :func:`finish_fused`, for one output frame.

    With an ``anchor`` (the trust rules are on), the speckle filter never erases what the
    reference measured on a surface (:func:`upsr.method.trust.surface_support`; or where a
    steep surface one pixel wide has an anchor of its own,
    :func:`upsr.method.anchor.steep_runs`: a thin fast part kept by its anchor is an island,
    not noise: there ``fused`` comes back); the blocks of the reference's removed pixels (mixed,
    lone outliers) that it emptied are split between their neighbours again
    (:func:`upsr.method.mixed.split_mixed_pixels`: never a hole where the camera measured
    something); with ``cfg.follow_slopes`` the blocks on one surface
    follow its slope (:func:`upsr.method.slopes.follow_slopes`); each surface is smoothed
    along its plane (:func:`upsr.method.smoothing.smooth_output`); with ``cfg.fill_holes`` the
    pixels without depth are filled from the background side (invented depth).

    Parameters
    ----------
    out, fused : ndarray float32 (r·h, r·w)
        :func:`finish_fused` of ``fused``, and ``fused`` (mm).
    reference : ndarray float32 (h, w)
        The reference frame as fused (mm; 0: none; mixed pixels removed).
    anchor : ndarray float32 (h, w) or None
        :func:`upsr.method.trust.reference_anchor` of ``reference``; None: computed here
        where the slopes need it.
    cfg : UPSRConfig
        The video's fixed configuration (``fixed_config`` of
        :class:`upsr.method.frontend.MotionFrontEnd`: the smoothing's range std scaled).
    edge_mm, noise_mm : float
        The video's edge threshold and noise std (mm).
    measured : ndarray float32 (h, w), optional
        The reference as measured, before its mixed pixels and lone outliers were removed.
    slopes : (ndarray, ndarray), optional
        :func:`upsr.method.slopes.plane_slopes` of ``reference`` and ``anchor``, when
        already computed.

    Returns
    -------
    ndarray float32 (r·h, r·w)
    """
    r = cfg.scale
    erased = None if anchor is None else (out == 0) & (fused > 0)
    if erased is not None and erased.any():
        # (and the steep surfaces one pixel wide that have an anchor of their own; looked
        # for only where the finishing erased something)
        keep = surface_support(reference, edge_mm) | (np.asarray(anchor) > 0)
        lost = np.repeat(np.repeat(keep, r, axis=0), r, axis=1) & erased
        if lost.any():
            out = np.where(lost, fused, out)
    if measured is not None:
        out = split_mixed_pixels(
            out, measured, reference, reference if anchor is None else anchor, edge_mm=edge_mm
        )
    if cfg.follow_slopes:
        if anchor is None:
            anchor = reference_anchor(reference, noise_mm, 1.0, edge_mm)[0]
        out = follow_slopes(
            out, anchor, sigma_mm=noise_mm, edge_mm=edge_mm, frame=reference, measured=measured,
            slopes=slopes,
        )  # fmt: skip
    out = smooth_output(out, cfg.deblur, r, edge_mm=edge_mm)
    if cfg.fill_holes:
        out = fill_holes(out, r, iterations=64)  # invented depth (off by default)
    return out
