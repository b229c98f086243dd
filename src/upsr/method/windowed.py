"""The UP-SR video pipeline (paper Table 1) as a streaming engine and a batch function.

For each reference frame t0 (every frame of the video):

1. dense upsampling (eq. 13–15) by s ≤ r for motion (the flow grid,
   :meth:`UPSRConfig.flow_grid_scale <upsr.method.config.UPSRConfig.flow_grid_scale>`),
   :mod:`upsr.method.upsampling`;
2. bilateral prefilter and fixed 8-bit mapping, for motion only (§5.2), and
3. optical flow between consecutive upsampled frames (§4, eq. 16–17), both by the motion
   front-end :class:`upsr.method.frontend.MotionFrontEnd` (:mod:`upsr.method.motion`);
4. cumulative motion to t0 by composition, with eq. 19 re-estimation,
   :mod:`upsr.method.registration`;
5. nearest-neighbour warping of y_t↑ = U y_t to t0 (eq. 20) and 6. the invalid-aware temporal
   median (eq. 28), in one compiled pass on the r·h × r·w grid that reads the samples from the
   low-res frames (:func:`upsr.method.fusion.register_and_fuse`);
7. L1 + BTV deblurring (eq. 29–30), then (beyond the paper) an edge-preserving smoothing of
   each surface (the staircase of dense upsampling into ramps), :mod:`upsr.method.deblurring`.

Windows: N frames with the reference in the middle (``(N-1)//2`` before it); near the ends of a
video the window is shifted inwards so that it still holds N frames. Each consecutive flow (both
directions) and each prefiltered frame is computed once per video and shared by every window
that needs it, and each frame's chain of sample positions (the forward splat) is extended by
one flow per window; the engine keeps only what later windows need (about N frames of state).
Complete windows are finished on ``workers`` threads side by side (same output).
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Iterable, Iterator
from concurrent.futures import Future, wait
from typing import Any

import numpy as np
import numpy.typing as npt

from upsr.errors import InputError
from upsr.method._parallel import WINDOWED_WORKERS, resolve_workers, window_pool
from upsr.method.alternatives import thin_fronts
from upsr.method.camera_motion import (
    agreeing,
    along_axis,
    grid_intrinsics,
    pair_motion,
    pose_maps,
    pose_samples,
    window_poses,
)
from upsr.method.companding import compand, expand
from upsr.method.config import UPSRConfig
from upsr.method.consistency import (
    maps_at_centres,
    misregistered,
    registered_samples,
    thin_parts_followed,
)
from upsr.method.finishing import finish_frame, finish_fused, settle_fused
from upsr.method.frontend import MotionFrontEnd
from upsr.method.fusion import register_and_fuse, splat_points
from upsr.method.memory import beyond_reach, state_caps
from upsr.method.mixed import ABSTAIN, remove_mixed_pixels, removed_depths
from upsr.method.motion import FlowBackend, flow_backend_is_thread_safe, make_flow_backend
from upsr.method.registration import (
    advance_positions,
    cumulative_flows,
    sample_centres,
    to_output_grid,
)
from upsr.method.statistics import (
    VideoStatistics,
    fix_video_statistics,
    video_knee_mm,
    video_level_spacing,
)
from upsr.method.thin import ThinParts
from upsr.method.trust import abstain_lone_outliers, far_offsets, radial_offsets, reference_anchor
from upsr.method.validation import as_depth_frame, as_depth_video, no_valid_depth

__all__ = [
    "STAGES",
    "UPSR",
    "super_resolve",
    "window_start",
]

#: The stages of :attr:`UPSR.timings`.
STAGES = ("prefilter", "flow", "registration", "fusion", "deblur")


def window_start(t: int, n_total: int, cfg: UPSRConfig) -> int:
    """First frame of the window of reference frame ``t`` in a video of ``n_total`` frames."""
    return int(min(max(t - cfg.half_before, 0), n_total - cfg.n_frames))


class UPSR:
    """Streaming UP-SR: push low-res frames one by one, get high-res frames back in order.

    ``push(frame)`` returns the next finished high-res frame, or ``None`` while the first window
    fills (the latency is N−1 frames); ``feed(frame)`` returns every frame whose window is
    complete (latency N−1−(N−1)//2 frames, for live use); ``flush()`` returns the remaining ones
    at the end of the video and makes the object ready for a new video; ``reset()`` forgets
    everything. The output is identical to :func:`super_resolve` on the whole video.

    Parameters
    ----------
    scale : int, optional
        SR factor r (default 2).
    n_frames : int, optional
        Window length N (default 9).
    config : UPSRConfig, optional
        Full configuration: ``scale`` and ``n_frames`` given beside it must agree with it, and
        ``options`` are refused (:meth:`UPSRConfig.of_call`; they were ignored).
    flow_backend : FlowBackend, optional
        A flow estimator to use instead of ``config.flow``.
    workers : int, optional
        Threads that finish windows in the background, several at a time (beyond the paper;
        the output is the same). ``None``: 2 on a machine with 2 or more cores, else 0.
        0: each window is finished on the calling thread. Without effect (0) with a
        ``flow_backend`` or a registered flow backend, which may not be thread-safe.
        :meth:`push` and :meth:`process` finish up to 2·``workers`` windows ahead of the one
        they return; :meth:`feed` returns its frames as early as without workers. The
        threads are shared by the engines of a process (:func:`upsr.method._parallel.window_pool`):
        engines already run side by side (several processes or threads) want ``workers=0``.
    **options
        Any :class:`~upsr.method.config.UPSRConfig` field (``deblur_*`` for :class:`DeblurConfig`).

    Examples
    --------
    >>> import numpy as np, upsr
    >>> engine = upsr.UPSR(scale=2, n_frames=3)
    >>> video = np.full((5, 8, 8), 1500.0, np.float32)
    >>> outs = [engine.push(f) for f in video]
    >>> [o is None for o in outs]
    [True, True, False, False, False]
    >>> len(engine.flush())
    2
    """

    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        """``UPSR(..., mode="recursive")`` (or a config with that mode) makes a
        :class:`upsr.method.recursive.RecursiveUPSR`."""
        config = kwargs.get("config")
        mode = kwargs.get("mode", config.mode if config is not None else "windowed")
        if cls is UPSR and mode == "recursive":
            from upsr.method.recursive import RecursiveUPSR

            return RecursiveUPSR(*args, **kwargs)
        return super().__new__(cls)

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
        self.config = UPSRConfig.of_call(scale, n_frames, config, options)
        if self.config.mode != "windowed":
            raise InputError(f"UPSR is the windowed engine, not mode={self.config.mode!r}")
        workers = resolve_workers(workers, WINDOWED_WORKERS)
        self._custom_flow = flow_backend
        self._timing_lock = threading.Lock()
        self._pending: dict[int, Future[np.ndarray]] = {}
        #: Seconds spent in each stage since the engine was made (kept across videos):
        #: "prefilter", "flow" (consecutive flows), "registration" (cumulative motion with
        #: eq. 19), "fusion" (forward splat, registration of the samples and median), "deblur"
        #: (deblurring and speckle removal). With ``workers``, the time of all threads.
        self.timings: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        self._stats: VideoStatistics | None = None
        self._last_stats: VideoStatistics | None = None  # (of the video before a reset)
        self.reset()
        # windows in the background only with a built-in (thread-safe) flow backend
        self._pool = window_pool(workers) if self._parallel else None
        #: Threads that finish windows in the background (0: none).
        self.workers = workers if self._pool is not None else 0

    # -- state -------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget all frames and flows (start a new video)."""
        pending, self._pending = self._pending, {}
        for future in pending.values():
            future.cancel()
        wait(pending.values())  # none still reads the frames of this video
        cfg = self.config
        self._flow = self._custom_flow or make_flow_backend(cfg.flow, cfg.flow_preset)
        # prefilter, 8-bit mapping and flows of this video (the residual flow backend of
        # eq. 19 too, unless one is given), made by the first frame
        self._front: MotionFrontEnd | None = None
        # flows on two threads at once only with a built-in backend (others may keep state)
        self._parallel = self._custom_flow is None and flow_backend_is_thread_safe(cfg.flow)
        self._s = 1  # upsampling factor of the flow grid, set by the first frame
        self._shape: tuple[int, int] | None = None
        self._count = 0
        self._next_out = 0
        self._next_submit = 0
        self._any_valid = False
        # the per-video choices, fixed from the first window (fix_video_statistics)
        if self._stats is not None:
            self._last_stats = self._stats
        self._stats = None
        self._knee: float | None = None  # (video_knee_mm, with the N-th frame)
        self._lowres: dict[int, np.ndarray] = {}
        self._clean: dict[int, tuple] = {}  # (_cleaned)
        self._pre: dict[int, np.ndarray] = {}
        self._guide: dict[int, np.ndarray] = {}
        self._fwd: dict[int, np.ndarray] = {}
        self._bwd: dict[int, np.ndarray] = {}
        # (k, m): frame k's low-res sample centres carried by the consecutive flows to frame m
        self._chains: dict[tuple[int, int], np.ndarray] = {}
        # camera_motion="depth": the camera's motion from frame k - 1 to frame k (or None)
        self._steps: dict[int, np.ndarray | None] = {}

    @property
    def frames_seen(self) -> int:
        """Number of frames pushed since the last reset/flush."""
        return self._count

    @property
    def statistics(self) -> VideoStatistics | None:
        """The choices made once per video (estimator, trust noise, mixed-pixel removal, noise
        profile: :func:`~upsr.method.statistics.fix_video_statistics`) from its first N frames:
        those of the current video, else of the last one (after :meth:`flush`); None before."""
        return self._stats if self._stats is not None else self._last_stats

    @property
    def output_shape(self) -> tuple[int, int] | None:
        """(r·h, r·w) once the first frame has been pushed."""
        if self._shape is None:
            return None
        r = self.config.scale
        return self._shape[0] * r, self._shape[1] * r

    @contextlib.contextmanager
    def _timed(self, stage: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            elapsed = time.perf_counter() - start
            with self._timing_lock:
                self.timings[stage] += elapsed

    # -- per-frame work (once per video) --------------------------------------------------------
    def _ingest(self, frame: npt.ArrayLike) -> None:
        t = self._count
        cfg = self.config
        f = as_depth_frame(frame, name=f"frame {t}", valid_range_mm=cfg.valid_range_mm)
        if self._front is None:
            self._shape = f.shape
            self._front = MotionFrontEnd(
                cfg, f.shape[1], flow_backend=self._flow, residual_flow_backend=self._custom_flow
            )
            self._s = self._front.grid_scale
        elif f.shape != self._shape:
            raise InputError(
                f"frame {t}: shape {f.shape} differs from the first frame's {self._shape}"
            )
        self._any_valid = self._any_valid or bool((f > 0).any())
        front = self._front
        self._lowres[t] = f = compand(f, self._knee or math.inf)  # (decided with the N-th)
        with self._timed("prefilter"):
            self._pre[t] = front.prefilter(f)
        self._count = t + 1
        if self._count == cfg.n_frames:
            # per-video statistics, fixed once from the first window (never per frame), the
            # companding first: the first N frames companded, their flow images made again
            first = np.stack([self._lowres[k] for k in sorted(self._lowres)])
            spacing = video_level_spacing(first)
            self._knee = video_knee_mm(first, cfg, spacing)
            for k in self._lowres if math.isfinite(self._knee) else ():
                self._lowres[k] = compand(self._lowres[k], self._knee)
                self._pre[k] = front.prefilter(self._lowres[k])
                self._guide.pop(k, None)  # (and its flows)
            self._stats = fix_video_statistics(front, first, cfg, self._knee, spacing)
        if front.ready:
            for k in sorted(self._pre):
                if k not in self._guide:
                    self._guide[k] = front.guide(self._pre[k])
                    if k - 1 in self._guide:
                        with self._timed("flow"):
                            self._fwd[k - 1], self._bwd[k] = front.flow_pair(
                                self._pre[k - 1],
                                self._pre[k],
                                self._guide[k - 1],
                                self._guide[k],
                                parallel=self._parallel,
                            )

    def _finish(self, t: int, n_total: int) -> np.ndarray:
        cfg = self.config
        s = window_start(t, n_total, cfg)
        idx = range(s, s + cfg.n_frames)
        ref = t - s
        h, w = self._shape  # type: ignore[misc]
        r = cfg.scale
        with self._timed("registration"):
            maps, poses = self._register(t, idx, ref)
        with self._timed("fusion"):
            measured = self._lowres[t]  # the reference as measured
            stats = self._stats
            assert stats is not None  # fixed with the N-th frame, before any window
            # mixed (flying) input pixels abstain: the other frames fill them
            lowres = np.stack(
                [self._cleaned(k)[0] if stats.remove_mixed else self._lowres[k] for k in idx]
            )
            noise = stats.trust_noise_mm  # (cfg.trust_noise_mm where given)
            reach_noise = stats.reach_noise_mm  # a sample's noise (at most the trust's σ)
            anchor = tolerance = caps = None
            if cfg.trust_k is not None:
                anchor, tolerance = reference_anchor(
                    lowres[ref], noise, cfg.trust_k, self._front.edge_mm,
                    noise_profile=stats.trust_noise_profile, own_surface="except_rims",
                    keep_steep=not stats.remove_mixed,
                )  # fmt: skip
                # how many frames each pixel's estimate may draw on (the reach, the level)
                caps = state_caps(
                    anchor, tolerance, float(cfg.n_frames), reach_noise, cfg.trust_k,
                    noise_profile=stats.trust_noise_profile, tolerance_sigma_mm=noise,
                )  # fmt: skip
                lowres = abstain_lone_outliers(lowres, ref, anchor)
            offsets = untrusted = followed = None
            # each frame's motion at the low-res pixel centres (the radial test, the reach)
            needed = cfg.n_frames > 1 and (cfg.radial_compensation or caps is not None)
            centres = maps_at_centres(maps, (h, w)) if needed else None
            if cfg.n_frames > 1 and (cfg.radial_compensation or cfg.check_registration):
                registered = registered_samples(lowres, maps, r)
                if cfg.radial_compensation:
                    offsets = radial_offsets(
                        lowres, maps, r, ref, sigma_mm=reach_noise, edge_mm=self._front.edge_mm,
                        radius_px=cfg.radial_radius_px, registered=registered, anchor=anchor,
                        noise_profile=stats.trust_noise_profile, centres=centres,
                    )  # fmt: skip
                if cfg.check_registration:
                    untrusted, followed = self._unfollowed(
                        registered, maps, lowres[ref], ref, anchor, tolerance, offsets
                    )
                if offsets is not None:
                    # an offset near the edge threshold (within which it is measured) is
                    # truncated: those samples abstain rather than bias the output
                    far = far_offsets(offsets, self._front.edge_mm)
                    untrusted = far if untrusted is None else untrusted | far
            if caps is not None:
                far = beyond_reach(maps, caps, ref, grid_scale=self._s, centres=centres)
                untrusted = far if untrusted is None else untrusted | far
            guide = None
            if cfg.splat_radius_px and cfg.n_frames > 1:
                # where each sample lands in the reference (upsr.method.registration.
                # trace_to_reference), each frame's chain kept from one window to the next
                positions = np.empty((cfg.n_frames, h, w, 2), np.float32)
                for k in idx:
                    pos = self._chain(k, t)
                    if poses is not None:
                        pos = agreeing(pos, pose_samples(
                            self._lowres[k], cfg.camera_intrinsics, self._s,  # type: ignore[arg-type]
                            poses[k - s], poses[ref],
                        ), self._s)  # fmt: skip
                    to_output_grid(pos, r / self._s, out=positions[k - s])
                guide = splat_points(lowres, positions, (h * r, w * r), cfg.splat_radius_px)
            # registration (eq. 20) and the invalid-aware median (eq. 28), one compiled pass
            fused = register_and_fuse(
                lowres,
                maps,
                r,
                ref,
                weight_sigma_px=cfg.edge_weight_px * r if cfg.edge_weight_px else None,
                weight_floor=cfg.edge_weight_floor,
                guide=guide,
                min_valid_fraction=cfg.min_valid_fraction,
                edge_mm=self._front.edge_mm,  # type: ignore[union-attr]
                measured_only=True,  # never invent depth where no frame measured anything
                anchor=anchor,
                tolerance=tolerance,
                offsets=offsets,
                untrusted=untrusted,
                edge_votes=cfg.edge_votes,
                min_trusted=cfg.min_trusted_samples,
                estimator=stats.estimator,
                hole_floors=cfg.check_registration,
                mixes_mm=(
                    removed_depths(self._lowres[t], self._cleaned(t)[0])
                    if stats.remove_mixed
                    else None
                ),
                followed=followed,
                border_strips=not stats.remove_mixed,
            )
            # stale hole fills, steep blocks' level, the reference's unfilled removed pixels
            fused = settle_fused(
                fused, lowres[ref], measured, anchor, caps, cfg,
                edge_mm=self._front.edge_mm, keep_mean=stats.remove_mixed,
                thin=self._cleaned(t)[1] if stats.remove_mixed else None,
            )  # fmt: skip
        with self._timed("deblur"):
            front = self._front
            finished = finish_fused(
                fused, front.fixed_config, noise_profile=stats.trust_noise_profile
            )
            return expand(finish_frame(
                finished, fused, lowres[ref], anchor, front.fixed_config, edge_mm=front.edge_mm,
                noise_mm=reach_noise, measured=measured,
            ), stats.knee_mm)  # fmt: skip

    def _unfollowed(
        self,
        registered: np.ndarray,
        maps: np.ndarray,
        reference: np.ndarray,
        ref: int,
        anchor: np.ndarray | None,
        tolerance: np.ndarray | None,
        offsets: np.ndarray | None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The frames of the window the motion did not follow around each reference pixel
        (misregistered), and on sensors that do not mix, those that did not follow a thin
        part in front that the others followed; and those parts (None: none)."""
        edge = self._front.edge_mm  # type: ignore[union-attr]
        untrusted = misregistered(registered, reference, ref, edge_mm=edge, offsets=offsets)
        if anchor is None or self._stats.remove_mixed:  # type: ignore[union-attr]
            return untrusted, None
        # there the frames that did not follow the part abstain, the surfaces around compete
        followed, lost = thin_parts_followed(
            registered, anchor, tolerance, thin_fronts(anchor, tolerance, edge, border_strips=True),
            ref, edge_mm=edge, offsets=offsets, min_trusted=self.config.min_trusted_samples,
            maps=maps,
        )  # fmt: skip
        return untrusted | lost, followed

    def _cleaned(self, k: int) -> tuple[np.ndarray, ThinParts | None]:
        """Frame k with its mixed pixels marked to abstain, and its thin parts, once per
        frame."""
        out = self._clean.get(k)
        if out is None:
            edge = self._front.edge_mm  # type: ignore[union-attr]
            out = remove_mixed_pixels(
                self._lowres[k],
                edge,
                marker=ABSTAIN,
                thin_parts=self.config.thin_parts,
                return_thin_parts=True,
            )
            self._clean[k] = out
        return out  # type: ignore[return-value]

    def _register(self, t: int, idx: range, ref: int) -> tuple[np.ndarray, np.ndarray | None]:
        """The motion from the reference t to every frame of its window ``idx`` on the flow
        grid (eq. 19–21), and the frames' poses where the camera's motion registers it."""
        cfg = self.config
        maps = np.empty((cfg.n_frames, *self._guide[t].shape, 2), np.float32)
        cumulative_flows(
            ref,
            [self._bwd.get(k) for k in idx],
            [self._fwd.get(k) for k in idx],
            self._guide[t].shape,
            refine=self._front.residual_flow if cfg.refine else None,  # type: ignore[union-attr]
            guides=[self._guide[k] for k in idx],
            parallel=self._parallel,
            out=maps,
        )
        # (a footprint sensor's mixes move with the edges' sub-pixel motion: the flow sees it)
        if (
            cfg.camera_motion != "depth"
            or self._stats.remove_mixed  # type: ignore[union-attr]
            or not all(along_axis(self._camera_step(k)) for k in list(idx)[1:])
        ):
            return maps, None
        # (beyond the paper: the camera moves along its axis; each pixel moved by its depth)
        poses = window_poses(idx, self._camera_step)
        grid = grid_intrinsics(cfg.camera_intrinsics, self._s)  # type: ignore[arg-type]
        by_pose = pose_maps(self._pre[t], grid, poses, ref, np.empty_like(maps))
        return agreeing(maps, by_pose, self._s, out=maps), poses

    def _camera_step(self, k: int) -> np.ndarray | None:
        """The camera's motion from frame k − 1 to frame k (``camera_motion="depth"``), once
        per frame (windows finished at once may compute it twice: the same values)."""
        if k in self._steps:
            return self._steps[k]
        step = pair_motion(
            self._lowres[k - 1],
            self._lowres[k],
            self.config.camera_intrinsics,  # type: ignore[arg-type]
            noise_mm=self._stats.reach_noise_mm,  # type: ignore[union-attr]
            edge_mm=self._front.edge_mm,  # type: ignore[union-attr]
        )
        self._steps[k] = step
        return step

    def _chain(self, k: int, m: int) -> np.ndarray:
        """Frame k's low-res sample centres carried by the consecutive flows to frame m (flow
        grid px), one flow step beyond what an earlier window computed. Windows finished at
        once may compute a step twice (same values); never a wrong one."""
        pos = self._chains.get((k, m))
        if pos is None:
            if m == k:
                pos = sample_centres(self._shape, self._s)  # type: ignore[arg-type]
            elif m > k:
                pos = advance_positions(self._chain(k, m - 1), self._fwd[m - 1])
            else:
                pos = advance_positions(self._chain(k, m + 1), self._bwd[m + 1])
            self._chains[(k, m)] = pos
        return pos

    # -- windows in order, some finished ahead in the background --------------------------------
    def _submit_ready(self, n_total: int, ahead: int) -> None:
        """Start finishing, in the background, the windows (up to ``ahead`` beyond the next
        output) that lie in the frames seen so far (final for a video of ``n_total``)."""
        if self._pool is None:
            return
        cfg = self.config
        t = max(self._next_submit, self._next_out)
        while (
            t < self._count
            and t - self._next_out < ahead
            and window_start(t, n_total, cfg) + cfg.n_frames <= self._count
        ):
            self._pending[t] = self._pool.submit(self._finish, t, n_total)
            t += 1
        self._next_submit = t

    def _take(self, n_total: int) -> np.ndarray:
        """The next output frame (finished in the background, or now), then forget what no
        later window needs."""
        t = self._next_out
        future = self._pending.pop(t, None)
        out = future.result() if future is not None else self._finish(t, n_total)
        self._next_out = t + 1
        # the next window starts at window_start(t + 1, T) for a video of T >= frames_seen
        # frames, which is at least this; windows in the background start later still
        cfg = self.config
        keep_from = max(min(t + 1 - cfg.half_before, self._count - cfg.n_frames), 0)
        stores = (self._lowres, self._clean, self._pre, self._guide, self._fwd, self._bwd)
        for store in (*stores, self._steps):
            for k in [k for k in list(store) if k < keep_from]:  # (workers add to _clean)
                store.pop(k, None)
        for key in list(self._chains):  # (list(): workers may add chains meanwhile)
            if key[0] < keep_from:
                self._chains.pop(key, None)
        return out

    def _complete(self, n_total: int) -> bool:
        """Whether the window of the next output frame lies in the frames seen so far."""
        t = self._next_out
        n = self.config.n_frames
        return t < self._count and window_start(t, n_total, self.config) + n <= self._count

    # -- public streaming API -------------------------------------------------------------------
    def push(self, frame: npt.ArrayLike) -> np.ndarray | None:
        """Add the next low-res frame (h, w) in mm; return the next finished high-res frame.

        Returns
        -------
        ndarray float32 (r·h, r·w) or None
            Output frame number ``frames_seen - N`` once N frames have been pushed, else None.
        """
        self._ingest(frame)
        n = self.config.n_frames
        if self._count < n:
            return None
        self._submit_ready(self._count + n, ahead=2 * self.workers)
        return self._take(n_total=self._count + n)

    def flush(self) -> list[np.ndarray]:
        """Finish the video: return the high-res frames not returned yet, then reset.

        Raises
        ------
        InputError
            Fewer than N frames were pushed, or none of them had any valid depth.
        """
        try:
            if self._count == 0:
                return []
            if self._count < self.config.n_frames:
                raise InputError(
                    f"N={self.config.n_frames} frames per window but the video has "
                    f"only {self._count} frame(s)"
                )
            if not self._any_valid:
                raise InputError(no_valid_depth(self.config.valid_range_mm))
            self._submit_ready(self._count, ahead=self._count)
            return [self._take(self._count) for _ in range(self._next_out, self._count)]
        finally:
            self.reset()

    def feed(self, frame: npt.ArrayLike) -> list[np.ndarray]:
        """Add the next low-res frame; return every high-res frame whose window is now complete.

        The low-latency form of :meth:`push` for live use: output frame t comes out as soon as
        frame t + N − 1 − (N−1)//2 has been fed (4 frames later at N = 9, against N − 1 = 8
        for :meth:`push`); the first call that completes a window returns the first
        (N−1)//2 + 1 frames at once. Use either ``push`` or ``feed`` for a video, then
        :meth:`flush`. The frames are the same as :func:`super_resolve`'s.

        Returns
        -------
        list of ndarray float32 (r·h, r·w), in order (possibly empty)
        """
        self._ingest(frame)
        n = self.config.n_frames
        outs: list[np.ndarray] = []
        if self._count < n:
            return outs
        # a window that lies in the frames seen so far is final whatever the video's length
        horizon = self._count + n
        self._submit_ready(horizon, ahead=self._count)
        while self._complete(horizon):
            outs.append(self._take(horizon))
        return outs

    def process(self, frames: Iterable[npt.ArrayLike]) -> Iterator[np.ndarray]:
        """Super-resolve a stream of frames; yields one output per frame, in order: without
        workers as soon as its window is complete (:meth:`feed`), with workers once finished
        (up to 2·``workers`` windows ahead). A failed (or abandoned) video resets the engine."""
        try:
            if self._pool is None:
                for frame in frames:
                    yield from self.feed(frame)
            else:
                n, ahead = self.config.n_frames, 2 * self.workers
                for frame in frames:
                    self._ingest(frame)
                    horizon = self._count + n
                    self._submit_ready(horizon, ahead)
                    # in order, as the background finishes them; wait only with enough ahead
                    while self._complete(horizon) and (
                        self._next_submit - (k := self._next_out) >= ahead
                        or (k in self._pending and self._pending[k].done())
                    ):
                        yield self._take(horizon)
        except BaseException:
            self.reset()
            raise
        yield from self.flush()


def super_resolve(
    frames: npt.ArrayLike,
    scale: int,
    n_frames: int | None = None,
    *,
    config: UPSRConfig | None = None,
    progress: bool | None = None,
    workers: int | None = None,
    **options: Any,
) -> np.ndarray:
    """Super-resolve a depth video with UP-SR (paper Table 1).

    Parameters
    ----------
    frames : array_like, (T, h, w)
        Depth in mm, float or integer; 0 or NaN = no measurement.
    scale : int
        SR factor r ≥ 1.
    n_frames : int, optional
        Frames per window N (1 ≤ N ≤ T, default 9), reference in the middle; with
        ``mode="recursive"`` the most frames the state summarises (any T).
    config : UPSRConfig, optional
        Full configuration: ``scale`` (and ``n_frames`` when given) must be its own, and no
        ``options`` beside it.
    progress : bool, optional
        Show a progress bar on stderr.
    workers : int, optional
        Threads that finish windows side by side (see :class:`UPSR`), or in recursive mode
        frames while the next one updates the state (see
        :class:`~upsr.method.recursive.RecursiveUPSR`); the output is the same.
    **options
        Any :class:`~upsr.method.config.UPSRConfig` field, ``deblur_*`` for deblurring options.

    Returns
    -------
    ndarray float32 (T, r·h, r·w)
        Depth in mm, 0 where nothing is known.

    Raises
    ------
    InputError
        Bad data (shape, dtype, ±inf, negative depth, no valid depth) or parameters.
    """
    cfg = UPSRConfig.of_call(scale, n_frames, config, options)
    video = as_depth_video(frames, valid_range_mm=cfg.valid_range_mm)
    t_total, h, w = video.shape
    if cfg.mode == "windowed" and cfg.n_frames > t_total:
        raise InputError(
            f"N={cfg.n_frames} frames per window but the video has only {t_total} frame(s)"
        )
    out = np.empty((t_total, h * cfg.scale, w * cfg.scale), np.float32)
    engine = UPSR(config=cfg, workers=workers)
    results = engine.process(video)
    if progress:
        from tqdm import tqdm

        results = tqdm(results, total=t_total, unit="frame", desc="upsr", leave=False)
    for t, frame in enumerate(results):
        out[t] = frame
    return out
