"""The motion front-end of UP-SR (paper §4, §5.2; steps 1–3 of Table 1), one object per video.

The chain that turns low-res depth frames into the consecutive flows the registration chains:

1. dense upsampling by s (the flow grid, :meth:`UPSRConfig.flow_grid_scale
   <upsr.method.config.UPSRConfig.flow_grid_scale>`; s = r in the paper) and the bilateral
   prefilter, for motion only (§5.2, :func:`upsr.method.motion.bilateral_prefilter_nearest`);
2. one fixed 8-bit mapping of depth per video (:func:`upsr.method.motion.depth_to_u8`), its
   range, the noise level and the scale of the depth thresholds fixed once from the first
   window (never per frame: :meth:`MotionFrontEnd.fix_statistics`, :func:`depth_scale`);
3. optical flow between consecutive frames, both directions (eq. 16–17), with the motion that
   the depth does not support zeroed (:func:`upsr.method.motion.suppress_spurious_motion`);
   the same test for the residual flows of eq. 19 on the registered 8-bit guides.

:class:`upsr.method.windowed.UPSR` (which caches what it computes, once per video), the
multi-frame baselines (:func:`upsr.research.baselines.upsampled_flows`) and the NumPy oracle
(:func:`upsr.research.oracle.super_resolve_straightforward`) all estimate motion with it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable

import numpy as np
import numpy.typing as npt

from upsr.method._parallel import both
from upsr.method.config import UPSRConfig
from upsr.method.motion import (
    FlowBackend,
    bilateral_prefilter,
    bilateral_prefilter_nearest,
    depth_range,
    depth_to_u8,
    flow_backend_is_thread_safe,
    make_flow_backend,
    suppress_spurious_motion,
)
from upsr.method.noise import estimate_noise_mm
from upsr.method.upsampling import upsample_nearest

__all__ = [
    "DRIFT_AGREEING_SHARE",
    "DRIFT_MIN_SAMPLES",
    "DRIFT_SIGNIFICANCE",
    "DRIFT_STEP_PX",
    "MIN_STATISTICS_PAIRS",
    "MotionFrontEnd",
    "depth_scale",
    "enough_for_statistics",
]

#: :meth:`MotionFrontEnd.depth_drift_mm` reads every this-many-th pixel of each axis.
DRIFT_STEP_PX = 4
#: ... from at least this many pixels measured in both frames (a frame of 4×4 pixels has one
#: sample: its noise was a drift) ...
DRIFT_MIN_SAMPLES = 16
#: ... keeps a drift beyond the changes' median deviation from it and beyond this many
#: standard errors of its median, ...
DRIFT_SIGNIFICANCE = 4.0
#: ... and finds a drift where at least this share of the pixels measured in both frames
#: changed by it within half the edge threshold (a camera approaching a wall, not a scene
#: whose parts change depth each their own way).
DRIFT_AGREEING_SHARE = 0.5

#: :func:`enough_for_statistics`: the pairs of neighbouring measurements (along rows and
#: columns) a frame needs before the recursive mode fixes the video's statistics from it (or
#: half of a full frame's, for frames smaller than that).
MIN_STATISTICS_PAIRS = 100


def enough_for_statistics(frame: np.ndarray) -> bool:
    """Whether a frame (h, w) mm holds enough neighbouring measurements to fix a video's
    statistics from it (its noise is estimated from neighbouring pairs): a camera's first
    frames are often empty or hold a few scattered pixels, whose noise estimate is 0 (a room's
    surfaces 80 % worse for the whole video)."""
    valid = np.asarray(frame) > 0
    h, w = valid.shape
    pairs = int((valid[:, 1:] & valid[:, :-1]).sum() + (valid[1:] & valid[:-1]).sum())
    return pairs >= min(MIN_STATISTICS_PAIRS, (h * (w - 1) + (h - 1) * w) // 2) and pairs > 0


def depth_scale(first_frames: np.ndarray, near_depth_mm: float | None) -> float:
    """The factor k ≤ 1 of a video's depth thresholds in mm: its first frames' (T, h, w) mm
    median valid depth over ``near_depth_mm``, at most 1.

    UP-SR's thresholds in mm (the step between two surfaces, 100 mm; the final smoothing's
    range std, 30 mm) are made for scenes a metre away or more; a camera at close range (a
    D405 at 7–50 cm, a ToF sensor on a hand) sees steps of a few cm between surfaces, which
    they merge and smooth across (flying pixels). Scaled by k, a scene at 30 cm gets the
    thresholds the same scene gets at 1 m (beyond the paper, ``UPSRConfig.near_depth_mm``).
    Only the frames with enough neighbouring measurements count
    (:func:`enough_for_statistics`): a few stray values of a few mm in an otherwise empty
    first window would scale a scene metres away to thresholds below its noise.
    ``near_depth_mm`` None, or no such frame: 1.
    """
    if near_depth_mm is None:
        return 1.0
    frames = [f for f in np.asarray(first_frames) if enough_for_statistics(f)]
    if not frames:
        return 1.0
    stack = np.stack(frames)
    return float(min(1.0, float(np.median(stack[stack > 0])) / near_depth_mm))


class MotionFrontEnd:
    """Prefilter, fixed 8-bit mapping, consecutive flows and spurious-motion suppression.

    Parameters
    ----------
    config : UPSRConfig
        Prefilter (``prefilter_sigma_mm``, ``prefilter_sigma_px``), flow backend and presets,
        ``flow_scale``, ``depth_range_mm``, ``noise_mm``, ``edge_mm`` and
        ``zero_motion_tolerance``.
    width_px : int
        Width w of the low-res frames (it sets the flow grid and the residual flow preset).
    grid_scale : int, optional
        Upsampling factor s of the flow grid; default ``config.flow_grid_scale(width_px)``.
    flow_backend : FlowBackend, optional
        Flow estimator of the consecutive flows; default ``config.flow`` with
        ``config.flow_preset``.
    residual_flow_backend : FlowBackend, optional
        Flow estimator of the eq. 19 residual flows; default ``config.flow`` with
        ``config.residual_flow_preset(s·w)``.
    blockwise : bool
        Prefilter on the low-res grid (:func:`~upsr.method.motion.bilateral_prefilter_nearest`,
        the engine's) or, ``False``, the upsampled frame with OpenCV
        (:func:`~upsr.method.motion.bilateral_prefilter`, the straightforward path; equal up
        to float rounding).

    Attributes
    ----------
    grid_scale : int
        s: the flows live on the (s·h, s·w) grid.
    depth_range_mm : (float, float) or None
        (near, far) of the 8-bit mapping; None until :meth:`fix_statistics`.
    noise_mm : float or None
        Noise std of the video (mm); None until :meth:`fix_statistics`.
    depth_scale : float
        k ≤ 1, the factor of the depth thresholds in mm (:func:`depth_scale`); 1 until
        :meth:`fix_statistics`.
    edge_mm : float
        Depth step that separates surfaces: k · ``config.edge_mm``, at least 4× the noise.
    fixed_config : UPSRConfig
        ``config`` with its thresholds as fixed for this video (k · ``edge_mm``, the
        deblurring's k · ``edge_mm`` and k · ``smooth_sigma_mm``, ``near_depth_mm`` None):
        what the steps after the fusion use, and what a chunk of the video runs with.
    thread_safe : bool
        Whether two flows may run at once (a built-in backend, not a given one).
    """

    def __init__(
        self,
        config: UPSRConfig,
        width_px: int,
        *,
        grid_scale: int | None = None,
        flow_backend: FlowBackend | None = None,
        residual_flow_backend: FlowBackend | None = None,
        blockwise: bool = True,
    ) -> None:
        cfg = config
        self.config = cfg
        self.grid_scale = (
            int(grid_scale) if grid_scale is not None else cfg.flow_grid_scale(width_px)
        )
        s = self.grid_scale
        self.thread_safe = flow_backend is None and flow_backend_is_thread_safe(cfg.flow)
        self.flow_backend = flow_backend or make_flow_backend(cfg.flow, cfg.flow_preset)
        self.residual_flow_backend = residual_flow_backend or make_flow_backend(
            cfg.flow, cfg.residual_flow_preset(s * width_px)
        )
        self.blockwise = blockwise
        #: Spatial std of the prefilter on the flow grid (px).
        self.prefilter_sigma_px = cfg.spatial_sigma_px * s / cfg.scale
        self.depth_range_mm: tuple[float, float] | None = cfg.depth_range_mm
        self.noise_mm: float | None = cfg.noise_mm
        self.depth_scale = 1.0
        self.edge_mm = self._edge_for(self.noise_mm or 0.0)
        self.fixed_config = cfg
        self._scaled = False  # (depth_scale and fixed_config fixed: once per video)

    # -- per-video statistics ------------------------------------------------------------------
    def _edge_for(self, noise_mm: float) -> float:
        return max(self.depth_scale * self.config.edge_mm, 4.0 * noise_mm)

    @property
    def ready(self) -> bool:
        """Whether the 8-bit mapping and the noise level are fixed (guides and flows can be
        made)."""
        return self.depth_range_mm is not None and self.noise_mm is not None

    def fix_statistics(
        self,
        first_frames: Iterable[np.ndarray],
        *,
        estimate_noise: Callable[[np.ndarray], float] = estimate_noise_mm,
    ) -> None:
        """Fix what the config leaves open from the first window's low-res frames (h, w) mm:
        the depth range of the 8-bit mapping (:func:`~upsr.method.motion.depth_range`), the
        noise (median over the frames of ``estimate_noise``) and the factor of the depth
        thresholds (:func:`depth_scale`), once per video."""
        first = np.stack(list(first_frames))
        cfg = self.config
        if self.depth_range_mm is None:
            self.depth_range_mm = depth_range(first)
        if self.noise_mm is None:
            self.noise_mm = float(np.median([estimate_noise(f) for f in first]))
        if self._scaled:
            return  # (a second call, e.g. the straightforward path's: nothing left to fix)
        self._scaled = True
        k = self.depth_scale = depth_scale(first, cfg.near_depth_mm)
        self.edge_mm = self._edge_for(self.noise_mm)
        d = cfg.deblur
        self.fixed_config = dataclasses.replace(
            cfg,
            edge_mm=k * cfg.edge_mm,
            near_depth_mm=None,
            deblur=dataclasses.replace(
                d,
                edge_mm=None if d.edge_mm is None else k * d.edge_mm,
                smooth_sigma_mm=None if d.smooth_sigma_mm is None else k * d.smooth_sigma_mm,
            ),
        )

    def smooth_at_least(self, noise_mm: float) -> None:
        """The final smoothing's range std (``fixed_config.deblur.smooth_sigma_mm``) at least
        ``noise_mm``, a sample's noise in the video (once, with its statistics): at high
        noise the fused surfaces keep more than 30 mm of it, which a narrower range leaves
        (beyond the paper; steps of 4σ or less are one surface for the fusion already)."""
        d = self.fixed_config.deblur
        if d.smooth_sigma_mm is not None and noise_mm > d.smooth_sigma_mm:
            self.fixed_config = dataclasses.replace(
                self.fixed_config, deblur=dataclasses.replace(d, smooth_sigma_mm=noise_mm)
            )

    # -- per frame -----------------------------------------------------------------------------
    def prefilter(self, frame_mm: npt.ArrayLike) -> np.ndarray:
        """A low-res frame (h, w) in mm, upsampled by s and bilateral-filtered: float32
        (s·h, s·w) mm, for motion only (§5.2)."""
        cfg = self.config
        if self.blockwise:
            return bilateral_prefilter_nearest(
                frame_mm, self.grid_scale, cfg.prefilter_sigma_mm, self.prefilter_sigma_px
            )
        up = upsample_nearest(np.asarray(frame_mm, np.float32), self.grid_scale)
        return bilateral_prefilter(up, cfg.prefilter_sigma_mm, self.prefilter_sigma_px)

    def guide(self, prefiltered_mm: np.ndarray) -> np.ndarray:
        """The 8-bit image (uint8, same shape) the flow sees, with the video's fixed mapping."""
        if self.depth_range_mm is None:
            raise RuntimeError("fix_statistics() first: the depth range is not fixed yet")
        return depth_to_u8(prefiltered_mm, *self.depth_range_mm)

    # -- depth drift (beyond the paper) ---------------------------------------------------------
    def depth_drift_mm(self, first_mm: np.ndarray, second_mm: np.ndarray) -> float:
        """How much nearer or farther the whole scene came from one prefiltered frame to the
        next (mm, second − first); 0 where it did not.

        A camera moving along its axis changes the depth of every pixel alike. The flow reads
        8-bit depth as brightness, and on a slanted surface a change of depth looks like a
        motion along its slope: the flow explained part of the approach away, the samples it
        registered were taken at other points of the slope, and the radial offsets measured
        on them fell short (a camera 25 mm per frame toward a wall yawed 25°, σ = 30 mm:
        50 mm between two frames measured as 35; the recursive state lagged, +1.9 mm of
        surface bias). The recursive mode estimates its flow on the frame brought back by
        the drift (:meth:`shifted`); the windowed mode, whose windows lie on both sides of
        the reference, does not (measured: a moving camera's room lost 1.9 % of moving-surface
        rmse, docs/notes/depth-rules.md). The drift is the median change of depth at a
        pixel (every :data:`DRIFT_STEP_PX`-th of each axis, measured in both frames, a
        quarter of the frame at least), kept where it is at most ``edge_mm``, beyond the
        changes' median deviation from it (a camera moving sideways and turning in a room:
        its pixels change each their own way, and a drift there made the recursive room's
        surfaces up to 5 % worse) and :data:`DRIFT_SIGNIFICANCE` standard errors of the
        median, and :data:`DRIFT_AGREEING_SHARE` of those pixels changed by it within half of
        ``edge_mm``; and at least half a level of the guide (below, 0: a static scene's
        flows stay as they were)."""
        step = DRIFT_STEP_PX
        a, b = (np.asarray(f, np.float32)[::step, ::step] for f in (first_mm, second_mm))
        both = (a > 0) & (b > 0)
        if self.depth_range_mm is None or both.sum() < max(0.25 * a.size, DRIFT_MIN_SAMPLES):
            return 0.0
        change = b[both] - a[both]
        drift = float(np.median(change))
        spread = np.abs(change - drift)
        if not abs(drift) <= self.edge_mm:
            return 0.0
        if np.mean(spread <= 0.5 * self.edge_mm) < DRIFT_AGREEING_SHARE:
            return 0.0
        # the scene's common change: beyond the changes' median deviation from it (a camera
        # moving sideways and turning in a room changes its pixels each their own way) and
        # beyond DRIFT_SIGNIFICANCE standard errors of the median (noise alone moves the
        # median of a small or noisy frame)
        mad = float(np.median(spread))
        if not abs(drift) > mad * max(1.0, DRIFT_SIGNIFICANCE * 1.8581 / np.sqrt(change.size)):
            return 0.0
        near, far = self.depth_range_mm
        return drift if abs(drift) >= 0.5 * (far - near) / 254.0 else 0.0

    def shifted(self, prefiltered_mm: np.ndarray, drift_mm: float) -> tuple[np.ndarray, np.ndarray]:
        """A prefiltered frame brought back by a depth drift (its measured pixels minus
        ``drift_mm``), and its guide."""
        d = np.asarray(prefiltered_mm, np.float32) - np.float32(drift_mm)
        d[~((prefiltered_mm > 0) & (d > 0))] = 0.0  # (none where nothing or nothing is left)
        return d, self.guide(d)

    # -- flows ---------------------------------------------------------------------------------
    def consecutive_flow(
        self,
        first_mm: np.ndarray,
        second_mm: np.ndarray,
        first_u8: np.ndarray,
        second_u8: np.ndarray,
        *,
        noise_factor: float = 1.0,
        holes: bool = False,
    ) -> np.ndarray:
        """Flow (s·h, s·w, 2) from one frame to the next (eq. 17), given their prefiltered
        frames and guides, without the motion the depth does not support (judged against
        ``second_mm``, with :meth:`supported_flow`'s ``noise_factor`` and ``holes``)."""
        flow = self.flow_backend(first_u8, second_u8)
        return self.supported_flow(
            first_mm, second_mm, flow, units_per_mm=1.0, noise_factor=noise_factor, holes=holes
        )

    def flow_pair(
        self,
        first_mm: np.ndarray,
        second_mm: np.ndarray,
        first_u8: np.ndarray,
        second_u8: np.ndarray,
        *,
        parallel: bool = False,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(first → second, second → first) consecutive flows, on two threads if
        ``parallel`` (same result)."""
        return both(
            lambda: self.consecutive_flow(first_mm, second_mm, first_u8, second_u8),
            lambda: self.consecutive_flow(second_mm, first_mm, second_u8, first_u8),
            enabled=parallel,
        )

    def residual_flow(self, first_u8: np.ndarray, second_u8: np.ndarray) -> np.ndarray:
        """Residual flow between registered guide images (eq. 19), spurious motion removed."""
        near, far = self.depth_range_mm  # type: ignore[misc]
        flow = self.residual_flow_backend(first_u8, second_u8)
        return self.supported_flow(
            first_u8, second_u8, flow, units_per_mm=254.0 / max(far - near, 1e-6)
        )

    def supported_flow(
        self,
        first: np.ndarray,
        second: np.ndarray,
        flow: np.ndarray,
        units_per_mm: float,
        noise_factor: float = 1.0,
        holes: bool = False,
    ) -> np.ndarray:
        """:func:`~upsr.method.motion.suppress_spurious_motion` on images in
        mm × ``units_per_mm`` (1 for prefiltered depth, 254/(far − near) for guides), the zero
        motion's margin ``noise_factor`` times the video's noise (below 1 where ``second`` is
        less noisy than a frame: the recursive state)."""
        cfg = self.config
        if cfg.zero_motion_tolerance is None:
            return flow
        s = self.grid_scale
        return suppress_spurious_motion(
            first,
            second,
            flow,
            window_px=2 * s + 1,
            tolerance=cfg.zero_motion_tolerance,
            noise_mm=self.noise_mm * units_per_mm * noise_factor,  # type: ignore[operator]
            edge_mm=self.edge_mm * units_per_mm,
            edge_window_px=4 * s + 1,
            holes=holes,
        )
