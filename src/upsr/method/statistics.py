"""The choices UP-SR makes once per video, from its first N frames (beyond the paper).

The windowed engine fixes them with the N-th frame, before its first window (the companding of
depth quantised in disparity first: :func:`video_knee_mm`), and never
changes them (a chunk of a video run with :func:`pinned_config` gives exactly what the whole
run gives): the front-end's depth range and noise
(:class:`~upsr.method.frontend.MotionFrontEnd`), the trust's noise and its profile over
depth, the fusion's estimator, and whether the sensor mixes depths at edges. The recursive
engine takes the noise profile from its first frame.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from upsr.method.companding import LevelSpacing, compand, knee_at_spacing, level_fit
from upsr.method.config import UPSRConfig
from upsr.method.footprint import footprint_share, has_mixed_pixels
from upsr.method.frontend import MotionFrontEnd, depth_scale, enough_for_statistics
from upsr.method.noise import (
    QUANTISED_STEPS,
    choose_estimator,
    noise_profile,
    quantisation_step,
    second_differences,
    spatial_noise_mm,
    tail_ratio,
    temporal_noise_mm,
)
from upsr.method.validation import within_range

__all__ = [
    "VideoStatistics",
    "first_frame_noise_mm",
    "fix_video_statistics",
    "noise_estimator",
    "pinned_config",
    "sensor_mixes",
    "triangulates",
    "trust_profile",
    "video_knee_mm",
    "video_level_spacing",
]


class VideoStatistics(NamedTuple):
    """The choices UP-SR makes once per video (:func:`fix_video_statistics`)."""

    #: Estimate of the fused samples of a surface: "median" or "mean".
    estimator: str
    #: σ (mm) of the trust tolerance.
    trust_noise_mm: float
    #: σ (mm) of a sample's noise in the reach of each pixel and the radial offsets' and
    #: slopes' tests (``UPSRConfig.reach_noise_mm``; at most ``trust_noise_mm``).
    reach_noise_mm: float
    #: Whether the mixed input pixels are removed.
    remove_mixed: bool
    #: (σ₁, p) of a trust tolerance that grows with depth, or None (one σ).
    trust_noise_profile: tuple[float, float] | None = None
    #: The factor of the depth thresholds in mm (< 1: a scene nearer than ``near_depth_mm``).
    depth_scale: float = 1.0
    #: The depth (mm) beyond which the depth is companded (:mod:`upsr.method.companding`;
    #: inf: nowhere). Beyond it the noises and the profile above are in companded mm.
    knee_mm: float = math.inf


def video_level_spacing(first_frames: np.ndarray) -> LevelSpacing | None:
    """The disparity quantisation of a video's sensor: the level step α (1/mm, q(z) = α·z²)
    and the span of depths it was fitted over (:func:`upsr.method.companding.level_fit`), of
    the first of its first frames (T, h, w) mm as measured that has depth
    (:func:`~upsr.method.frontend.enough_for_statistics`); None where that frame is not
    quantised in disparity or no frame has depth."""
    for frame in first_frames:
        if enough_for_statistics(frame):
            return level_fit(frame)
    return None


def video_knee_mm(first_frames: np.ndarray, cfg: UPSRConfig, spacing: LevelSpacing | None) -> float:
    """The companding knee (mm) of a video from its first frames (T, h, w) mm.

    ``cfg.compand_knee_mm`` where given; for ``"auto"``, the depth where the level step of
    the video's ``spacing`` (:func:`video_level_spacing`) reaches the edge step the method
    compares depths with (:func:`upsr.method.companding.knee_mm`): ``cfg.edge_mm`` scaled for
    a near scene by the frames' :func:`~upsr.method.frontend.depth_scale` (the windowed
    engine's first N frames, the recursive engine's first frame with depth: as each scales its
    thresholds; the same on companded frames, whose median below 1 m is not companded). inf
    (none) where ``spacing`` is None, for None and, whatever is given, with
    ``camera_motion="depth"`` (its motion is estimated from the depth as measured).
    """
    knee = cfg.compand_knee_mm
    if knee is None or cfg.camera_motion == "depth":
        return math.inf
    if knee != "auto":
        return float(knee)  # type: ignore[arg-type]
    if spacing is None:
        return math.inf
    scale = depth_scale(first_frames, cfg.near_depth_mm)
    return knee_at_spacing(spacing.alpha, cfg.edge_mm * scale)


def triangulates(spacing: LevelSpacing | None) -> bool:
    """Whether a video's sensor triangulates (structured light, stereo): its depth quantised
    in disparity (:func:`video_level_spacing`), the steps seen to grow as z²
    (``LevelSpacing.confirmed``)."""
    return spacing is not None and spacing.confirmed


def sensor_mixes(first_frames: np.ndarray, edge_mm: float, spacing: LevelSpacing | None) -> bool:
    """``remove_mixed="auto"``: whether a video's sensor mixes depths at edges, from its first
    frames (T, h, w) as measured: a share of mixes at its edges
    (:func:`upsr.method.footprint.footprint_share`) that a footprint gives
    (:func:`~upsr.method.footprint.has_mixed_pixels`), unless its depth is quantised in
    disparity (``spacing``, :func:`video_level_spacing`, its steps seen to grow as z²:
    ``LevelSpacing.confirmed``; over a narrow range a ToF camera's depth in 4 mm units fits
    an α too, and had kept its mixes at a share of 0.98): a sensor that triangulates
    (structured light, stereo) samples points, and the Kinect's noise beyond 4 m puts pixels
    between the surfaces of its far edges (a 14 m corridor pooled 0.48–0.52 over its first
    frames, ``benchmarks/outside_eval.py --seed 1``; its edge accuracy 81.8 → 77.0 % with its
    "mixes" removed)."""
    return not triangulates(spacing) and has_mixed_pixels(footprint_share(first_frames, edge_mm))


def fix_video_statistics(
    front: MotionFrontEnd,
    first_frames: np.ndarray,
    cfg: UPSRConfig,
    knee: float | None = None,
    spacing: LevelSpacing | None = None,
) -> VideoStatistics:
    """Fix every choice UP-SR makes once per video from its first N low-res frames (T, h, w)
    as measured, companded beyond ``knee`` mm (:func:`video_knee_mm`; None: not companded)
    for all but the sensor's mixing (:func:`sensor_mixes`, with the video's disparity
    quantisation ``spacing``, :func:`video_level_spacing`; None: not quantised so).

    The front-end's depth range and noise estimate (:meth:`MotionFrontEnd.fix_statistics`);
    the trust noise (at least the temporal noise, :func:`upsr.method.noise.temporal_noise_mm`);
    the noise of the reach and the radial offsets (at most the trust noise, from space:
    :func:`upsr.method.noise.spatial_noise_mm`);
    the fusion's estimator from the shape of the noise (:func:`upsr.method.noise.tail_ratio`):
    the median for Laplacian noise, the mean of the trusted samples for Gaussian noise or
    depth quantised in steps of at least :data:`~upsr.method.noise.QUANTISED_STEPS` noise
    stds (:func:`upsr.method.noise.quantisation_step`); and whether the sensor mixes depths at
    edges (:func:`upsr.method.footprint.footprint_share`) for ``remove_mixed="auto"``.
    """
    measured, first_frames = first_frames, compand(first_frames, math.inf if knee is None else knee)
    front.fix_statistics(first_frames)
    spatial = front.noise_mm or 0.0
    if cfg.trust_noise_mm is not None:
        trust_mm = cfg.trust_noise_mm
    elif cfg.noise_mm is not None:  # a given noise is the noise
        trust_mm = cfg.noise_mm
    else:
        # (the temporal differences also see the motion: a moving camera's slanted surfaces
        # read as 3× the noise, which loosens the trust; the spatial noise alone was measured
        # and not taken for the tolerance, see docs/notes/depth-rules.md; the reach takes it)
        trust_mm = max(spatial, temporal_noise_mm(first_frames, front.edge_mm))
    mixed = cfg.remove_mixed
    if mixed == "auto":
        # (a property of the sensor: of the depth as measured)
        mixed = sensor_mixes(measured, front.edge_mm, spacing)
    profile = trust_profile(first_frames, cfg, front.edge_mm)
    estimator = cfg.fusion_estimator
    # a given noise is a sample's noise; a profile gives σ(z)
    given = (cfg.reach_noise_mm, cfg.trust_noise_mm, cfg.noise_mm, profile)
    estimate_reach = all(v is None for v in given)
    # (slopes and motion cancel; noise-free: no shape to read; computed once, where needed)
    d2 = None
    if spatial > 0 and (estimator == "auto" or estimate_reach):
        d2 = second_differences(first_frames, front.edge_mm, spatial)
    if estimator == "auto":
        estimator = noise_estimator(first_frames, trust_mm, profile, d2)
    sample_mm = spatial if d2 is None else spatial_noise_mm(d2, spatial)  # (from space)
    if cfg.reach_noise_mm is not None:
        reach_mm = cfg.reach_noise_mm
    elif not estimate_reach:
        reach_mm = trust_mm
    else:
        reach_mm = min(trust_mm, sample_mm)
    # the final smoothing's range: at least a sample's noise (never the temporal differences,
    # which a moving camera's slanted surfaces inflate)
    front.smooth_at_least(reach_mm if d2 is None else min(reach_mm, sample_mm))
    return VideoStatistics(
        estimator, trust_mm, reach_mm, bool(mixed), profile, front.depth_scale,
        math.inf if knee is None else knee,
    )  # fmt: skip


def noise_estimator(
    frames: np.ndarray,
    noise_mm: float,
    profile: tuple[float, float] | None,
    differences: np.ndarray | None,
) -> str:
    """The estimator the shape of a video's noise asks for
    (:func:`upsr.method.noise.choose_estimator`): ``"median"`` for heavy tails
    (:func:`upsr.method.noise.tail_ratio` of the ``differences``, the
    :func:`upsr.method.noise.second_differences` of ``frames``; None: noise-free), ``"mean"``
    for Gaussian noise or depth quantised in steps of at least
    :data:`~upsr.method.noise.QUANTISED_STEPS` stds of ``noise_mm`` (σ(z) with a
    ``profile``)."""
    step = quantisation_step(frames, noise_mm, profile)
    tail = math.nan if differences is None else tail_ratio(differences)
    return choose_estimator(tail, quantised=step >= QUANTISED_STEPS)


def trust_profile(
    first_frames: np.ndarray, cfg: UPSRConfig, edge_mm: float
) -> tuple[float, float] | None:
    """The (σ₁, p) of ``cfg.trust_noise_profile``, estimated from the first frames (T, h, w)
    for ``"auto"`` (:func:`upsr.method.noise.noise_profile`, surfaces split at ``edge_mm``)
    unless a noise is given; None for one σ per video."""
    profile = cfg.trust_noise_profile
    if profile == "constant":
        return None
    if profile == "auto":
        if cfg.noise_mm is not None or cfg.trust_noise_mm is not None:
            return None  # a given noise is the noise
        profile = noise_profile(first_frames, edge_mm)
    sigma_1m, power = (float(v) for v in profile)  # type: ignore[misc]
    return (sigma_1m, power) if power > 0 else None


def first_frame_noise_mm(
    frame: np.ndarray,
    front: MotionFrontEnd,
    cfg: UPSRConfig,
    differences: np.ndarray | None = None,
) -> float:
    """A sample's noise std (mm) from a video's first frame (h, w) alone (the recursive mode's
    statistics): the given ``reach_noise_mm``, ``trust_noise_mm`` or ``noise_mm``, else from
    its second differences (:func:`upsr.method.noise.spatial_noise_mm`, at least the
    front-end's estimate; ``differences``: those of the frame, when already computed)."""
    for given in (cfg.reach_noise_mm, cfg.trust_noise_mm, cfg.noise_mm):
        if given is not None:
            return float(given)
    spatial = front.noise_mm or 0.0
    if not spatial > 0:
        return spatial
    if differences is None:
        differences = second_differences(frame[None], front.edge_mm, spatial)
    return spatial_noise_mm(differences, spatial)


def pinned_config(first_frames: np.ndarray, cfg: UPSRConfig) -> UPSRConfig:
    """``cfg`` with every per-video choice fixed from the first N frames (T, h, w) mm.

    A chunk of a video run with this config gives exactly what the whole run gives for its
    frames (``upsr batch`` splits long recordings so).
    """
    if cfg.valid_range_mm is not None:  # (the frames as the engine will see them)
        first_frames = within_range(np.array(first_frames, np.float32), cfg.valid_range_mm)
    spacing = video_level_spacing(first_frames)  # (as the windowed engine decides them)
    knee = video_knee_mm(first_frames, cfg, spacing)
    front = MotionFrontEnd(cfg, first_frames.shape[-1])
    stats = fix_video_statistics(front, first_frames, cfg, knee, spacing)
    return dataclasses.replace(
        front.fixed_config,  # (its depth steps fixed too)
        depth_range_mm=front.depth_range_mm,
        noise_mm=front.noise_mm,
        fusion_estimator=stats.estimator,
        trust_noise_mm=stats.trust_noise_mm,
        reach_noise_mm=stats.reach_noise_mm,
        remove_mixed=stats.remove_mixed,
        trust_noise_profile=stats.trust_noise_profile or "constant",
        compand_knee_mm=knee if math.isfinite(knee) else None,
    )
