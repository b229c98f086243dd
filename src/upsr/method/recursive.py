"""Recursive (causal) UP-SR: zero latency, one flow per frame, memory independent of N.

Beyond the paper. The windowed engine (:mod:`upsr.method.windowed`) fuses, for every output
frame, the N frames around it: N/2 frames of latency and N − 1 registrations per output. The
recursive engine carries instead a high-resolution *state* from one output to the next, on the
r·h × r·w output grid:

* ``depth``: the fused estimate (mm, 0 = nothing known), before deblurring;
* ``count``: its confidence, the number of frames it summarises (capped at ``n_frames``, so
  the state forgets as a window of about N frames would).

Per frame t (only frame t and the state of t − 1 are read):

1. the motion front-end (:class:`~upsr.method.frontend.MotionFrontEnd`) prefilters frame t and
   computes ONE flow on the flow grid, from frame t to frame t − 1 (the backward lookup of the
   current grid into the previous one), with its spurious motion suppressed: the motion is
   kept where the state, moved by it, fits frame t better than the state unmoved
   (:func:`~upsr.method.motion.suppress_spurious_motion` between the prefiltered frame t and
   the state read on the flow grid, the zero motion's margin
   :data:`~upsr.method.state_update.STATE_NOISE_FACTOR` times the noise; against the
   previous frame, whose noise hides the motion of a smooth body, the flow of an animal
   without a wall behind it was zeroed on its body and the state left behind) (with
   ``camera_motion="depth"``, where the camera's last N − 1 steps went along its axis,
   that of :mod:`upsr.method.camera_motion` at the pixels whose flow agrees with it);
2. the new measurement is y_t↑ = U y_t after mixed-pixel removal
   (:func:`~upsr.method.mixed.remove_mixed_pixels`), and its anchor and tolerance τ = k·σ +
   relief are those of :func:`~upsr.method.trust.reference_anchor` (frame t is the reference;
   σ(z) of the noise profile measured on the first frame where the noise grows with depth);
3. registration: each output pixel p looks the state up at q = p + flow(q) (the flow read
   bilinearly on the flow grid, as the windowed fusion reads it); the state is never
   interpolated across a depth edge: it is read bilinearly among the (at most 4) state
   pixels around q that lie on the surface of the nearest one, or, when the nearest lies
   beyond τ of the anchor, of the one of the other three closest to the anchor within τ (so
   a depth edge of the state is moved, not blurred);
4. radial compensation: the state's depth offset against frame t (motion along the viewing
   ray), the masked, significance-tested median of the differences over a neighbourhood of one
   surface (the rule of :func:`~upsr.method.trust.radial_offsets`, significant from at most
   :data:`~upsr.method.state_update.STATE_SIGNIFICANCE` standard errors; where the state as
   a whole moved along the ray and the 5×5 neighbourhood is too noisy for it, from its wide
   neighbourhood; where the frame did not move, from
   :data:`~upsr.method.state_update.STATE_CONFIRMED_SIGNIFICANCE` standard errors when the
   same pixel's offset of the previous frame went the same way and the state is at its cap:
   a surface that comes nearer by less than 4 standard errors per frame is followed, not
   lagged behind), is subtracted;
5. robust update, per pixel, with the trust rules of the windowed fusion:

   - no state there (0, or outside the previous frame) and a measurement: start from the
     mean of the anchor a and the measurement m, m's pull limited to τ/3 (a + clip(m − a,
     ±τ/3)/2, a Huber-type mean of the two), which counts as 2 samples (the anchor, the
     median of up to 9 samples of the surface, alone where m lies beyond τ of it);
   - a state within τ of the anchor: update it with the measurement m and count ← min(count + 1,
     n*), where n* ≤ N is the pixel's cap of :func:`~upsr.method.memory.state_caps` (a slope's state
     gains the registration error times the slope every frame: on steep slopes the current frame
     weighs more, without noise it is the estimate), about halved where the pixel moved since the
     last frame (:func:`~upsr.method.memory.moving_caps`), and on a significant slope
     (:func:`~upsr.method.slopes.sloped_pixels`) lowered further where the registered state
     differs from frame t by more than the noise allows, the excess taken for the state's
     process noise (:func:`~upsr.method.memory.innovation_caps`: a flow that is off on a
     narrow slope makes its state drift): the mean ``d += (m − d)/count``
     (``fusion_estimator`` "mean": with count < N exactly the running mean of the registered
     samples; also for "auto": the trust test has cut the noise's tails, and on the dense scenes of
     ``benchmarks/recursive_eval.py`` at σ = 10 and 30 mm the mean gave a lower surface rmse than
     the recursive median in 10 of 12 cases, by up to 9 %, Laplacian noise included), or the
     recursive median ``d += sign(m − d)·min(|m − d|, √2·σ/count)`` ("median": the stochastic
     approximation of the median, whose step √2σ/n = 1/(n·f(median)) for Laplacian noise of std σ
     reaches the variance σ²/(2n) of the sample median);
   - otherwise (disagreement beyond what the noise allows: something moved, appeared, or the
     flow failed): the pixel restarts the same way;
   - no measurement (0, or a mixed pixel): the state is kept with its count halved, and
     forgotten (0) once the count drops below 1, or at once where it lies more than the edge
     threshold nearer than everything the frame measured around its hole (the projector
     shadow beside a moving body: :func:`upsr.method.consistency.hole_backgrounds`), or,
     on the half of the block towards a neighbour that measured a surface more than the
     edge threshold nearer than the state (a body that moved into the hole, where the state
     has the wall it saw before: the README's recursive section has the figures), or, in an
     open hole of the frame (not a removed mixed pixel, not inside measured surroundings:
     :func:`~upsr.method.consistency.enclosed_holes`), where none of the 3×3 pixels around
     it measured the state's surface (within the edge threshold): a leg that moved away from
     where nothing returns (no wall behind the animal) leaves no ghost; 0 stays 0 where
     nothing is known;
   - a noise outlier of the frame (:func:`~upsr.method.anchor.noise_outliers`: a surface of
     at most two pixels 3–8 σ off the median of its 3×3 neighbours; where the first frame's
     noise is heavy-tailed, :func:`~upsr.method.statistics.noise_estimator`, and mixed pixels
     are not removed) is outvoted by a state on the surface around it, kept with its count
     halved, as a window's other frames outvote it (a small object that persists restarts
     the pixel once the count has run out);

   so every pixel that frame t measured has depth in the output (the current frame anchors
   it), and a sample beyond τ never gets averaged in;
6. sub-pixel edges (``edge_votes``): near frame t's occlusion edges each pixel's surface
   follows its share over the last frames of the bilinear weight of frame t's four samples
   around it, carried as a third state image (:func:`~upsr.method.edges.state_votes`);
7. the windowed engine's finishing steps (:mod:`upsr.method.finishing`: deblurring, its
   first step from the noise of every k-th row of the state,
   :data:`~upsr.method.finishing.NOISE_SAMPLE_PX`; speckle removal, the speckle filter never
   erasing what frame t measured on a surface, frame t's removed pixels split between their
   neighbours, blocks following their surface's slope, optional hole filling) give the
   output; the state keeps the fused (not the deblurred) depth, so the deblurring is never
   applied on top of itself.

Relation to the windowed median (paper §5, eq. 28): on a static pixel the state with the mean
estimator is the running mean of the last ≈ N samples (exactly the mean of all of them until N
are seen), with the median estimator a recursive approximation of their median; a sample that
the windowed fusion would not trust (beyond τ of the reference's anchor) restarts the pixel
instead of being outvoted, which makes the recursive state follow what the current frame sees
at once (no flying pixels, no ghosts, thin fast parts kept). The windowed mode, which sees
frames after t too and the exact median of each registered window, stays the more accurate
offline choice.
"""

from __future__ import annotations

import collections
import contextlib
import math
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method._parallel import resolve_workers
from upsr.method.anchor import noise_outliers
from upsr.method.camera_motion import agreeing, along_axis, grid_intrinsics, pair_motion, pose_maps
from upsr.method.companding import compand, expand
from upsr.method.config import UPSRConfig
from upsr.method.consistency import enclosed_holes, hole_backgrounds, maps_at_centres
from upsr.method.finishing import finish_frame, finish_fused
from upsr.method.footprint import _share_of, footprint_counts, has_mixed_pixels
from upsr.method.frontend import MotionFrontEnd, enough_for_statistics
from upsr.method.memory import INNOVATION_SLOPE_SIGNIFICANCE, moving_caps, state_caps
from upsr.method.mixed import remove_mixed_pixels, split_mixed_pixels
from upsr.method.motion import FlowBackend, make_flow_backend
from upsr.method.noise import NOISE_FREE_MM, second_differences, temporal_noise_mm
from upsr.method.pipeline import TwoStagePipeline
from upsr.method.slopes import plane_slopes, sloped_pixels
from upsr.method.state_update import STATE_NOISE_FACTOR, recursive_update
from upsr.method.statistics import (
    VideoStatistics,
    first_frame_noise_mm,
    noise_estimator,
    triangulates,
    trust_profile,
    video_knee_mm,
    video_level_spacing,
)
from upsr.method.thin import ThinParts
from upsr.method.trust import reference_anchor
from upsr.method.upsampling import resample_nearest, upsample_nearest
from upsr.method.validation import as_depth_frame, no_valid_depth
from upsr.method.windowed import STAGES

__all__ = [
    "RecursiveUPSR",
    "recursive_update",
]

# ---------------------------------------------------------------------------------------------
# the engine
# ---------------------------------------------------------------------------------------------
#: The options of the windowed mode (its registration of a window and its fusion), with their
#: command-line flags: the recursive mode refuses them rather than ignore them.
WINDOWED_ONLY = {
    "refine": "--no-refine",
    "refine_preset": "--refine-preset",
    "check_registration": "--no-registration-check",
    "splat_radius_px": None,
    "min_valid_fraction": None,
    "edge_weight_px": None,
    "edge_weight_floor": None,
    "min_trusted": None,
}
_DEFAULTS = UPSRConfig()


class RecursiveUPSR(TwoStagePipeline):
    """Recursive (causal) UP-SR: each pushed frame's high-res output comes back at once.

    Same interface as :class:`upsr.method.windowed.UPSR`: :meth:`push` returns the frame's
    output (latency 0 frames), :meth:`feed` a list of it, :meth:`flush` nothing more (it
    resets), :meth:`process` yields one output per input, :attr:`timings` the seconds per
    stage; :meth:`push_async` and :meth:`wait` finish frames on a second thread
    (:class:`~upsr.method.pipeline.TwoStagePipeline`). Memory: the state (the depth and the
    count, r·h × r·w float32 each, and with the edge votes the surface shares, a third) and
    the previous frame's prefiltered and 8-bit guide images and offset signs, whatever N.
    ``n_frames`` caps the state's count (how many frames it summarises); see the module for
    the update rule.

    Parameters
    ----------
    scale, n_frames, config, flow_backend, **options
        As :class:`~upsr.method.windowed.UPSR`.
    workers : int, optional
        0: :meth:`process` runs everything on the calling thread (numba's kernels on every
        core); ≥ 1 (default on two cores or more): one helper thread finishes each frame while
        the next one updates the state (same output; see :meth:`process`).
    """

    def __init__(
        self,
        scale: int | None = None,
        n_frames: int | None = None,
        *,
        config: UPSRConfig | None = None,
        flow_backend: FlowBackend | None = None,
        workers: int | None = None,
        **options: Any,
    ) -> None:
        if config is None:
            options = {"mode": "recursive", **options}
        elif options.get("mode") == config.mode:
            options = {k: v for k, v in options.items() if k != "mode"}  # (UPSR's own choice)
        config = UPSRConfig.of_call(scale, n_frames, config, options)
        if config.mode != "recursive":
            # (the mode picks defaults, the flow grid's among them: the engine and the mode agree)
            raise InputError(f"RecursiveUPSR is the recursive engine, not mode={config.mode!r}")
        unused = [f"{name} ({flag})" if flag else name for name, flag in WINDOWED_ONLY.items()
                  if getattr(config, name) != getattr(_DEFAULTS, name)]  # fmt: skip
        if unused:
            raise InputError(
                f"{', '.join(unused)}: options of the windowed mode, which the recursive mode "
                "does not use (one flow per frame, no window to register or splat): leave out"
            )
        self.config = config
        self._custom_flow = flow_backend
        # a two-stage pipeline: one helper
        self.workers = min(resolve_workers(workers, 1), 1)
        #: Seconds per stage since the engine was made: "prefilter", "flow" (one flow per
        #: frame), "registration" (radial offsets of the registered state), "fusion" (mixed
        #: pixels, anchor, registration and update of the state), "deblur" (finishing).
        self.timings: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        self._front: MotionFrontEnd | None = None
        self._last_stats: VideoStatistics | None = None
        self.reset()

    def reset(self) -> None:
        """Forget the state (start a new video), once a frame still finishing is done."""
        self._reset_pipeline()
        self._last_stats = self.statistics
        cfg = self.config
        self._flow = self._custom_flow or make_flow_backend(cfg.flow, cfg.flow_preset)
        self._front: MotionFrontEnd | None = None
        self._shape: tuple[int, int] | None = None
        self._count = 0
        self._first: np.ndarray | None = None
        self._start = 0  # the first frame with depth (the statistics' frame)
        self._knee = math.inf  # (video_knee_mm, from that frame)
        self._prev_pre: np.ndarray | None = None
        self._prev_guide: np.ndarray | None = None
        self._prev_frame: np.ndarray | None = None
        self._axial: collections.deque[bool] = collections.deque(maxlen=cfg.n_frames - 1)
        self._depth: np.ndarray | None = None
        self._conf: np.ndarray | None = None
        self._share: np.ndarray | None = None  # the surface shares (edge votes)
        self._signs: np.ndarray | None = None  # the last frame's offset signs (step 4)
        self._temporal_mm = 0.0
        self._profile: tuple[float, float] | None = None
        # "auto": the mean of the trusted samples (see the module), whatever the noise
        self._estimator = "mean" if cfg.fusion_estimator == "auto" else cfg.fusion_estimator
        self._remove_mixed = cfg.remove_mixed is True
        self._mixes = np.zeros(2)  # footprint_counts of the frames so far (remove_mixed="auto")
        self._triangulates = False  # depth quantised in disparity: no mixes (sensor_mixes)
        self._any_valid = False  # (before the statistics; a video may end in empty frames)
        self._heavy = False  # heavy-tailed noise (from the first frame)

    @property
    def frames_seen(self) -> int:
        """Number of frames pushed since the last reset/flush."""
        return self._count

    @property
    def statistics(self) -> VideoStatistics | None:
        """The choices made once per video, as :attr:`upsr.method.windowed.UPSR.statistics`
        (from its first frame with depth; the mixed-pixel removal as decided so far): those of
        the current video, else of the last one (after :meth:`flush`); None before."""
        if self._front is None:
            return self._last_stats
        noise = self._noise()
        return VideoStatistics(
            self._estimator, noise, noise, self._remove_mixed, self._profile,
            self._front.depth_scale, self._knee,
        )  # fmt: skip

    @property
    def output_shape(self) -> tuple[int, int] | None:
        """(r·h, r·w) once the first frame has been pushed."""
        r = self.config.scale
        return None if self._shape is None else (self._shape[0] * r, self._shape[1] * r)

    @property
    def state(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(depth, count) of the last frame (the fused depth before deblurring), or None."""
        if self._depth is None or self._conf is None:
            return None
        return self._depth, self._conf

    @contextlib.contextmanager
    def _timed(self, stage: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.timings[stage] += time.perf_counter() - start

    def _noise(self) -> float:
        cfg = self.config
        if cfg.trust_noise_mm is not None:
            return float(cfg.trust_noise_mm)
        spatial = self._front.noise_mm or 0.0  # type: ignore[union-attr]
        # the temporal differences of the first two frames also see the motion (a moving
        # camera: twice the noise), which the windowed mode's first window averages out;
        # they are the noise only where the spatial estimate sees none (quantised depth)
        return spatial if spatial >= NOISE_FREE_MM else max(spatial, self._temporal_mm)

    def _frame_flow(self, pre: np.ndarray, guide: np.ndarray) -> np.ndarray:
        """The one flow of a frame, current -> previous (the backward lookup of the state), its
        motion judged against the state it moves rather than the previous frame: far less noisy,
        so that the motion of a smooth moving body shows (step 1 of the module)."""
        front = self._front
        assert front is not None
        second, factor = (
            (self._prev_pre, 1.0)
            if self._depth is None
            else (resample_nearest(self._depth, pre.shape), STATE_NOISE_FACTOR)
        )
        # (the frame brought back by the scene's depth drift: MotionFrontEnd.depth_drift_mm)
        drift = front.depth_drift_mm(self._prev_pre, pre)
        if drift != 0.0:
            pre, guide = front.shifted(pre, drift)
        # (the flow of its holes judged by their pattern: the state's rim did not leak into a
        # hole that every frame has; recursive notes)
        return front.consecutive_flow(
            pre, second, guide, self._prev_guide, noise_factor=factor, holes=True
        )

    def _by_camera(self, flow: np.ndarray, pre: np.ndarray, frame: np.ndarray) -> np.ndarray:
        """``camera_motion="depth"``: the flow from ``frame`` to the previous frame replaced by
        the camera's motion at the pixels whose flow agrees with it, where that step and the
        N − 2 before it (a window's; one noisy step alone can pass) went along the axis
        (``pre``: the frame's prefiltered depth on the flow grid)."""
        cfg = self.config
        intrinsics = cfg.camera_intrinsics
        assert intrinsics is not None and self._prev_frame is not None
        edge, noise = self._front.edge_mm, self._noise()  # type: ignore[union-attr]
        step = pair_motion(self._prev_frame, frame, intrinsics, noise_mm=noise, edge_mm=edge)
        self._axial.append(along_axis(step))
        if len(self._axial) < self._axial.maxlen or not all(self._axial):  # type: ignore[operator]
            return flow
        s = flow.shape[1] / frame.shape[1]
        poses = np.stack([np.eye(4), step])  # (the previous frame, this one)
        by_pose = np.empty((2, *flow.shape), np.float32)
        pose_maps(pre, grid_intrinsics(intrinsics, s), poses, 1, by_pose)
        return agreeing(flow, by_pose[0], s)

    def _fix_statistics(self, f: np.ndarray) -> None:
        """The per-video statistics from the first frame with depth (latency 0: nothing later
        is known): the front-end's, the noise profile, whether the noise is heavy-tailed."""
        cfg = self.config
        self._front = front = MotionFrontEnd(
            cfg, f.shape[1], flow_backend=self._flow, residual_flow_backend=self._custom_flow
        )
        front.fix_statistics([f])
        spatial = front.noise_mm or 0.0
        d2 = second_differences(f[None], front.edge_mm, spatial) if spatial > 0 else None
        sample_mm = first_frame_noise_mm(f, front, cfg, d2)
        front.smooth_at_least(sample_mm)
        self._first = f
        self._profile = trust_profile(f[None], cfg, front.edge_mm)
        # heavy-tailed noise (not a quantised sensor's steps; noise-free depth has no
        # outliers): its outliers are outvoted
        self._heavy = (
            spatial >= NOISE_FREE_MM
            and noise_estimator(f[None], sample_mm, self._profile, d2) == "median"
        )

    def push(self, frame: npt.ArrayLike) -> np.ndarray:
        """Add the next low-res frame (h, w) in mm; return its high-res frame (r·h, r·w)."""
        return self._finish(*self._update(frame))

    def _update(self, frame: npt.ArrayLike) -> tuple:
        """:meth:`push` up to the new state; returns :meth:`_finish`'s (read-only) inputs."""
        t = self._count
        cfg = self.config
        r = cfg.scale
        f = as_depth_frame(frame, name=f"frame {t}", valid_range_mm=cfg.valid_range_mm)
        if f.shape != (self._shape or f.shape):
            raise InputError(
                f"frame {t}: shape {f.shape} differs from the first frame's {self._shape}"
            )
        self._shape = f.shape
        if self._front is None and not enough_for_statistics(f):
            # a camera's first frames are often empty or scattered: the statistics wait for
            # depth (from such a frame a room's surfaces were 80 % worse for the whole video)
            self._count, self._any_valid = t + 1, self._any_valid or bool((f > 0).any())
            return (None, f)
        first_with_depth = self._front is None
        if first_with_depth:  # (companding of depth quantised in disparity, from this frame)
            spacing = video_level_spacing(f[None])
            self._knee = video_knee_mm(f[None], cfg, spacing)
            self._triangulates = triangulates(spacing)
        raw, f = f, compand(f, self._knee)
        if first_with_depth:
            self._fix_statistics(f)
            self._start = t
        front = self._front
        if cfg.remove_mixed == "auto" and not self._triangulates and t - self._start < cfg.n_frames:
            # does the sensor mix (sensor_mixes)? The first N frames pooled as they arrive
            self._mixes += footprint_counts(raw, front.edge_mm)  # (the sensor's, as measured)
            share = _share_of(*self._mixes)
            self._remove_mixed = has_mixed_pixels(share, was=self._remove_mixed)
            if self._remove_mixed:
                self._share = None  # (no edge votes where mixed pixels are removed)
        remove_mixed = self._remove_mixed
        if not first_with_depth and self._first is not None:
            # (the frame after the first with depth, whatever empty frames came before)
            if cfg.noise_mm is None:
                self._temporal_mm = temporal_noise_mm(np.stack([self._first, f]), front.edge_mm)
            self._first = None
        with self._timed("prefilter"):
            pre = front.prefilter(f)
            guide = front.guide(pre)
        flow = None
        if self._prev_pre is not None:
            with self._timed("flow"):
                flow = self._frame_flow(pre, guide)
                if cfg.camera_motion == "depth" and not remove_mixed:
                    flow = self._by_camera(flow, pre, f)
        with self._timed("fusion"):
            meas, thin = (
                remove_mixed_pixels(
                    f, front.edge_mm, thin_parts=cfg.thin_parts, return_thin_parts=True
                )
                if remove_mixed
                else (f, None)
            )
            noise = self._noise()
            k = cfg.trust_k
            # (on its own surface: a pixel restarts from it)
            anchor, tol = reference_anchor(
                meas, noise, k if k is not None else 1.0, front.edge_mm,
                noise_profile=self._profile, own_surface="always", keep_steep=not remove_mixed,
            )  # fmt: skip
            if k is None:
                tol = np.zeros_like(tol)  # every state sample is trusted
            if flow is None or self._depth is None:
                flow = np.zeros((*pre.shape, 2), np.float32)
                depth = np.zeros((f.shape[0] * r, f.shape[1] * r), np.float32)
                conf = np.zeros_like(depth)
                # (not where mixed pixels are removed: the samples beside the edges, whose
                # weights the votes compare, are the removed ones; measured worse)
                votes = cfg.edge_votes and not remove_mixed
                self._share = np.zeros_like(depth) if votes else None
                self._signs = np.zeros(f.shape, np.int8)
            else:
                depth, conf = self._depth, self._conf
            caps, centres, slopes, sloped = self._caps(meas, anchor, tol, noise, flow)
            fused, conf, *share = recursive_update(
                depth,
                conf,  # type: ignore[arg-type]
                flow,
                meas,
                anchor,
                tol,
                scale=r,
                cap=caps,
                estimator=self._estimator,
                sigma_mm=noise,
                edge_mm=front.edge_mm,
                # (measured on the realistic scenes: 2× or 1.5× the windowed radius helps the
                # room seen by a walking camera but costs a quantised sensor's walls and the
                # approaching camera's edges; recursive notes)
                radial_radius_px=cfg.radial_radius_px if cfg.radial_compensation else None,
                noise_profile=self._profile,
                # (the holes of the frame as measured: its removed mixed pixels are not holes)
                holes=np.where(f > 0, np.float32(0.0), hole_backgrounds(meas)),
                # (its removed mixed pixels and its holes inside measured surroundings)
                enclosed=((f > 0) & ~(meas > 0)) | enclosed_holes(f),
                share=self._share,
                centres=centres,
                # (a state on the surface around outvotes the frame's noise outliers)
                outliers=noise_outliers(meas, noise, noise_profile=self._profile)
                if k is not None and self._heavy and not remove_mixed
                else None,
                kept=(kept := np.empty(f.shape, np.bool_)),
                offset_signs=self._signs,
                sloped=sloped,
            )
            if kept.any():
                # the finishing sees the samples the state outvoted as removed
                meas = np.where(kept, np.float32(0.0), meas)
                anchor = np.where(kept, np.float32(0.0), anchor)
        self._depth, self._conf = fused, conf
        self._share = share[0] if share else None
        self._prev_pre, self._prev_guide, self._prev_frame = pre, guide, f
        self._count = t + 1
        return fused, f, meas, anchor, noise, thin, remove_mixed, slopes

    def _caps(
        self, meas: np.ndarray, anchor: np.ndarray, tol: np.ndarray, noise: float, flow: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | None, tuple | None, np.ndarray | None]:
        """The frame's caps of the state (:func:`~upsr.method.memory.state_caps`, and where a
        state was carried :func:`~upsr.method.memory.moving_caps`), the flow at the low-res
        pixel centres (read by the caps and the radial test), the frame's slopes
        (:func:`~upsr.method.slopes.plane_slopes`, those the finishing's blocks follow too:
        its outliers the state outvotes, removed there, barely move a symmetric median) and
        the pixels on a significant slope (:func:`~upsr.method.slopes.sloped_pixels`: their
        caps follow the state's differences from the frame,
        :func:`~upsr.method.memory.innovation_caps`)."""
        cfg = self.config
        k = cfg.trust_k
        caps = state_caps(
            anchor, tol, float(cfg.n_frames), noise, k or 0.0, noise_profile=self._profile
        )
        moved = self._depth is not None
        centres = slopes = sloped = None
        if moved and (k or cfg.radial_compensation):
            centres = maps_at_centres(flow[None], meas.shape)
        if moved and k:
            # (a moving slope's state: fewer frames; a slope's state that strays: fewer still)
            s = flow.shape[1] / meas.shape[1]
            caps = moving_caps(caps, flow, cfg.n_frames, grid_scale=s, centres=centres)
            slopes = plane_slopes(meas, anchor, self._front.edge_mm, noise)  # type: ignore[union-attr]
            sloped = sloped_pixels(
                anchor, slopes, noise, noise_profile=self._profile,
                significance=INNOVATION_SLOPE_SIGNIFICANCE,
            )  # fmt: skip
        return caps, centres, slopes, sloped

    def _finish(
        self,
        fused: np.ndarray | None,
        f: np.ndarray,
        meas: np.ndarray | None = None,
        anchor: np.ndarray | None = None,
        noise: float = 0.0,
        thin: ThinParts | None = None,
        remove_mixed: bool = False,
        slopes: tuple | None = None,
    ) -> np.ndarray:
        """The output frame from the new state (the deblurring and the rules after it); the
        frame itself, nearest-upsampled, before the video's statistics (``fused`` None)."""
        cfg = self.config
        if fused is None:
            return upsample_nearest(f, cfg.scale)
        with self._timed("deblur"):
            if remove_mixed:
                # the mixed pixels the state did not fill: split between their neighbours
                # (in the output only, the state holds measurements)
                fused = split_mixed_pixels(
                    fused, f, meas, anchor, keep_mean=True, thin_parts=cfg.thin_parts, thin=thin,
                    edge_mm=self._front.edge_mm,  # type: ignore[union-attr]
                )  # fmt: skip
            return expand(finish_frame(
                finish_fused(
                    fused,
                    self._front.fixed_config,  # type: ignore[union-attr]
                    noise_profile=self._profile,
                ),
                fused,
                meas,
                anchor,
                self._front.fixed_config,  # type: ignore[union-attr]
                edge_mm=self._front.edge_mm,  # type: ignore[union-attr]
                noise_mm=noise,
                measured=f,
                slopes=slopes,
            ), self._knee)  # fmt: skip

    def feed(self, frame: npt.ArrayLike) -> list[np.ndarray]:
        """Add the next low-res frame; return ``[its high-res frame]`` (latency 0)."""
        return [self.push(frame)]

    def flush(self) -> list[np.ndarray]:
        """Finish the video (nothing is pending: returns ``[]``) and reset.

        Raises
        ------
        InputError
            None of the pushed frames had any valid depth.
        """
        try:
            self.wait()
            if self._count and self._front is None and not self._any_valid:
                raise InputError(no_valid_depth(self.config.valid_range_mm))
            return []
        finally:
            self.reset()
