"""All parameters of the UP-SR pipeline in one typed, documented, validated object.

Every length is in high-resolution pixels (px) unless the name says otherwise, every depth in
millimetres (mm). The defaults are tuned for depth in mm from ToF / structured-light cameras and
were chosen by measurement (see ``benchmarks/`` and the README).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from upsr.errors import InputError

__all__ = [
    "FLOW_GRID_MIN_WIDTH_PX",
    "MAX_BTV_RADIUS_PX",
    "MAX_N_FRAMES",
    "MAX_SCALE",
    "DeblurConfig",
    "UPSRConfig",
]

#: Width (px) from which a flow grid is fine enough for DIS's fixed-size (8 px) patches, also
#: at the 4× coarser finest level of the "ultrafast" preset (``UPSRConfig.flow_scale``,
#: ``UPSRConfig.refine_preset``). Measured: 64-px-wide ToF frames at r = 4 register better on
#: a 192 px grid (s = 3) than on 128 px (s = 2) or 256 px (s = 4).
FLOW_GRID_MIN_WIDTH_PX = 192

#: Upper bounds of the options: beyond them a run cannot finish in any sensible time or memory
#: (a BTV radius of 100000 px allocated 22 GB), so they are refused with one line.
MAX_SCALE = 16
MAX_N_FRAMES = 256
#: Depth-valued options (mm): 1000 km, far beyond any depth (``validation.MAX_DEPTH_MM``).
MAX_DEPTH_PARAM_MM = 1e9
#: Spatial stds (high-res px): kernels grow with them.
MAX_SIGMA_PX = 64.0
MAX_BTV_RADIUS_PX = 10
MAX_SPLAT_RADIUS_PX = 16.0
MAX_ITERATIONS = 1000
MAX_TOLERANCE = 1e6
#: Speckles (px): the largest output frame (MAX_SCALE² · the largest input frame).
MAX_SPECKLE_PX = MAX_SCALE * MAX_SCALE * (1 << 28)
#: Power of a noise profile σ₁·(z / 1 m)^p (disparity-based cameras: about 2).
MAX_NOISE_POWER = 4.0  # (noise.PROFILE_MAX_POWER: the same bound for a fitted one)
_PROFILE_NAMES = ("auto", "constant")

BlurModel = Literal["none", "box", "gaussian"]


@dataclass(frozen=True)
class DeblurConfig:
    r"""Parameters of the L1 + bilateral-TV deblurring step (paper eq. 29–30).

    Solves :math:`\hat x = \arg\min_x \|B x - z\|_1 + \lambda \Gamma_{BTV}(x)` with
    :math:`\Gamma_{BTV}(x) = \sum_{l,m=-P}^{P} \alpha^{|l|+|m|} \|x - S_x^l S_y^m x\|_1`
    by steepest descent on the subgradient (the paper's solver) with a geometric step schedule.

    Attributes
    ----------
    enabled : bool
        Run the deblurring step at all (``False`` returns the fused median, ``upsr_fused``).
    lam : float
        Regularisation weight λ of eq. 30 (unitless: both terms are L1 in mm).
    alpha : float
        Decay α ∈ (0, 1] of the BTV kernel, eq. 29.
    radius_px : int
        BTV half-window P (px); shifts l, m = −P … P.
    blur : {"none", "box", "gaussian"}
        Blur model B = A·H. ``"none"`` (B = I): pure BTV-L1 denoising of the fused image.
        ``"box"``: an r×r box (the upsampling blur A). ``"gaussian"``: a Gaussian of std
        ``blur_sigma_px``. Blurs are masked to valid pixels (they never mix in invalid ones).
    blur_sigma_px : float
        Standard deviation of the Gaussian blur model (px, high-res grid).
    iterations : int
        Number of subgradient steps. 15 by default: on Samba (σ = 10/30/60 mm) and the
        synthetic ToF scene, 15 steps give the same or a lower MSE and surface RMSE than 30
        (the step schedule has moved 83 % of its total length by then; the objective is
        1–9 % higher, but the extra steps fit the noise, not the surfaces).
    step_mm : float or None
        First step length β₀ (mm). ``None``: a robust estimate of the noise left in the fused
        image (:func:`upsr.method.noise.estimate_noise_mm` at a lag of r px), at least 0.5 mm.
    step_decay : float
        Geometric decay of the step: β_k = β₀ · step_decay^k.
    edge_mm : float or None
        Depth is not an image: BTV pairs whose fused depths differ by more than ``edge_mm`` are
        not regularised (no smoothing across depth discontinuities). ``None`` is the paper's
        plain BTV.
    smooth_sigma_mm : float or None
        Beyond the paper: a final edge-preserving smoothing of each surface
        (:func:`upsr.method.smoothing.smooth_surfaces`) with this range std (mm), which turns the
        staircase of dense upsampling on slanted surfaces into ramps. ``None`` disables it.
    smooth_sigma_px : float or None
        Its spatial std in high-res px; ``None``: r/2.
    """

    enabled: bool = True
    lam: float = 0.5
    alpha: float = 0.7
    radius_px: int = 2
    blur: BlurModel = "none"
    blur_sigma_px: float = 1.0
    iterations: int = 15
    step_mm: float | None = None
    step_decay: float = 0.9
    edge_mm: float | None = 100.0
    smooth_sigma_mm: float | None = 30.0
    smooth_sigma_px: float | None = None

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any]) -> DeblurConfig:
        """A config from a mapping of its fields; unknown names raise
        :class:`~upsr.errors.InputError`."""
        bad = sorted(map(str, set(options) - {f.name for f in dataclasses.fields(cls)}))
        if bad:
            raise InputError(f"unknown deblur option(s): {', '.join(bad)}")
        return cls(**options)

    def __post_init__(self) -> None:
        _check_flags(self)
        _number("deblur lam", self.lam, 0, MAX_DEPTH_PARAM_MM)
        _number("deblur alpha", self.alpha, 0, 1, lo_open=True)
        _number("deblur radius_px (P)", self.radius_px, 1, MAX_BTV_RADIUS_PX, integer=True)
        _check(
            self.blur in ("none", "box", "gaussian"),
            f"deblur blur must be 'none', 'box' or 'gaussian', not {_show(self.blur)}",
        )
        _number("deblur blur_sigma_px", self.blur_sigma_px, 0, MAX_SIGMA_PX, lo_open=True)
        _number("deblur iterations", self.iterations, 0, MAX_ITERATIONS, integer=True)
        _number("deblur step_mm", self.step_mm, 0, MAX_DEPTH_PARAM_MM, lo_open=True, none=True)
        _number("deblur step_decay", self.step_decay, 0, 1, lo_open=True)
        _number("deblur edge_mm", self.edge_mm, 0, MAX_DEPTH_PARAM_MM, lo_open=True, none=True)
        _number(
            "deblur smooth_sigma_mm",
            self.smooth_sigma_mm,
            0,
            MAX_DEPTH_PARAM_MM,
            lo_open=True,
            none=True,
        )
        _number(
            "deblur smooth_sigma_px", self.smooth_sigma_px, 0, MAX_SIGMA_PX, lo_open=True, none=True
        )


def _valid_range(value: Any) -> tuple[float, float]:
    """``valid_range_mm`` as (min, max) floats, checked (InputError)."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError("valid_range_mm must be (min, max) in mm or None") from None
    _check(
        math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi,
        f"valid_range_mm must be finite with 0 <= min < max, got ({lo:g}, {hi:g})",
    )
    return lo, hi


@dataclass(frozen=True)
class UPSRConfig:
    """Parameters of UP-SR (paper Table 1).

    Attributes
    ----------
    scale : int
        Super-resolution factor r ≥ 1 (output is r·h × r·w).
    n_frames : int
        Window length N ≥ 1. The reference frame sits in the middle of its window
        (``(N-1)//2`` frames before it); windows are shifted inwards near the ends of a video so
        that every window holds N frames.
    prefilter_sigma_mm : float
        Range std of the bilateral prefilter (mm), §5.2. Used for motion estimation only.
    prefilter_sigma_px : float or None
        Spatial std of the bilateral prefilter (high-res px). ``None``: 0.75·r + 0.5.
    flow : {"dis", "farneback"}
        Dense optical-flow backend between consecutive upsampled frames (§4). Other backends can
        be registered with :func:`upsr.method.motion.register_flow_backend`.
    flow_preset : {"ultrafast", "fast", "medium"}
        DIS preset (ignored by other backends).
    refine_preset : {"ultrafast", "fast", "medium"} or None
        DIS preset of the eq. 19 residual flows between registered frames, which are small
        (the consecutive flows already moved the frame most of the way). ``None``:
        ``"ultrafast"`` where the flow grid is at least 192 px wide (much cheaper, and as
        accurate on Samba and the synthetic scenes: ``benchmarks/flow_grid_eval.py``), else
        ``flow_preset`` (ultrafast matches on a 4× coarser grid, too coarse for tiny frames).
        See :meth:`residual_flow_preset`.
    flow_scale : int or None
        Upsampling factor s of the frames the motion is estimated on (1 ≤ s ≤ r): the flow
        grid is s·h × s·w and the motion is interpolated bilinearly to the r·h × r·w output
        grid where the frames are registered. The paper upsamples by r (§4, eq. 9–12).
        ``None``: the smallest s ≥ 2 that makes the flow grid at least 192 px wide, at most r
        (:meth:`flow_grid_scale`): DIS matches fixed-size patches, so small frames need a
        finer grid (64×56 at r = 4: s = 3), while large ones lose little on a coarser grid
        and gain a lot of speed (256×147 at r = 4: s = 2, 4.5× faster than s = 4 with DIS
        medium). Measured by ``benchmarks/flow_grid_eval.py`` (see the README). In recursive
        mode the smallest s ≥ 1: its one flow per frame on 320×240 frames is as accurate at
        s = 1 as at s = 2 on four realistic scenes at 320×240 (surface RMSE −0.8 to +1.2 %,
        edge accuracy −0.1 to +0.2 points; ``benchmarks/recursive_eval.py --sizes vga --modes
        recursive``) and the prefilter and flow take a fifth of the time.
    depth_range_mm : tuple of float or None
        (near, far) depths mapped to the 8-bit images the flow sees. ``None``: fixed once per
        video from the 1st–99th percentiles of the valid depths of the first window.
    zero_motion_tolerance : float or None
        Where zero motion explains two consecutive (prefiltered) frames as well as the flow,
        up to this factor on the local squared residual, the flow is set to 0
        (:func:`upsr.method.motion.suppress_spurious_motion`): the flow must not match the noise of
        static surfaces. ``None`` keeps the raw flow.
    noise_mm : float or None
        Noise std of the input (mm), which sets the edge threshold (≥ 4·noise) and the margin of
        the spurious-motion test. ``None``: estimated once per video from its first N frames
        (:func:`upsr.method.noise.estimate_noise_mm`). Give it (with ``depth_range_mm``) to
        process a chunk of a longer video exactly as the whole video would be.
    refine : bool
        Paper eq. 19: re-estimate each frame's motion against its already registered neighbour
        (a residual flow on the reference grid, composed into the cumulative motion).
    min_valid_fraction : float
        Fusion: a pixel is valid only if more than this share of the registered in-frame samples
        are valid (ties follow the reference frame). Out-of-frame samples abstain.
    edge_mm : float
        Fusion: registered samples further apart than this (mm) lie on different surfaces; the
        surface with the largest vote wins and only its samples are averaged by the median
        (never a depth between foreground and background). The threshold actually used is at
        least 4× the noise std estimated once per video, so noise never splits a surface (and
        scaled for a scene nearer than ``near_depth_mm``).
    near_depth_mm : float or None
        Beyond the paper: the depth thresholds in mm (``edge_mm``, the deblurring's
        ``edge_mm`` and ``smooth_sigma_mm``) are made for scenes at this depth or farther. A
        video whose first N frames have a median valid depth z̃ below it has them scaled by
        z̃ / ``near_depth_mm`` (fixed once per video: :func:`upsr.method.frontend.depth_scale`):
        a camera at close range (a D405 at 7–50 cm) then gets the thresholds the same scene
        gets at this depth, not surfaces a few cm apart merged (flying pixels). Nothing
        changes for scenes at 1 m or farther. ``None``: the thresholds as given.
    edge_weight_px : float or None
        Fusion at depth edges: a sample's vote is weighted by how close (in units of r px) the
        centre of the low-res pixel it comes from is to the registered position,
        ``floor + (1 − floor)·exp(−d²/(2·(edge_weight_px·r)²))``. ``None``: equal votes.
    edge_weight_floor : float
        Smallest vote weight (see ``edge_weight_px``).
    splat_radius_px : float or None
        Fusion at depth edges (beyond the paper): every low-res sample of the window is
        forward-registered to the reference at its sub-pixel position, and where the
        backward-registered samples of a pixel come from several surfaces, the surface of the
        nearest forward-registered sample within this radius (high-res px) wins
        (:func:`upsr.method.fusion.splat_points`). ``None``: vote only.
    edge_votes : bool
        Fusion at depth edges (beyond the paper): near the reference's depth edges, each
        pixel's surface from the bilinear votes of the four low-res samples around every
        frame's registered position, not only the nearest one (sub-pixel edges instead of the
        r×r block grid; :mod:`upsr.method.edges`). Depth is never interpolated. In recursive
        mode: each pixel's surface share over the last frames
        (:func:`upsr.method.edges.state_votes`; not where mixed pixels are removed).
    thin_parts : bool
        Where mixed pixels are removed (``remove_mixed``), also the parts narrower than a
        pixel, mixed along their whole length, and split the reference's between the depth
        of the surface they grow out of and what lies behind (:mod:`upsr.method.thin`), and
        the small clusters of like mixes of parts one to two pixels wide
        (:mod:`upsr.method.clusters`): fewer flying pixels and better edges, at some cost in
        rmse where a part's position inside its pixels is uncertain.
    speckle_px : int or None
        Beyond the paper: after the deblurring, connected regions of at most this many
        high-res px that no neighbour joins within ``edge_mm`` (isolated noise outliers that
        survived the median) are set to 0 = unknown (:func:`upsr.method.outliers.remove_speckles`).
        ``None``: r² (one low-res pixel's footprint); 0: keep everything.
    trust_k : float or None
        Fusion (beyond the paper): each registered sample is trusted only if it lies within
        τ = trust_k·σ + the local relief of the reference's surface of the reference's own
        robust depth there (the median of its 3×3 neighbours on its surface,
        :func:`upsr.method.trust.reference_anchor`; σ the larger of the per-video noise
        estimate and the std of its temporal noise, or σ(z) of ``trust_noise_profile``).
        Untrusted samples vote neither on the depth nor on whether there is depth; where the
        reference measured depth the output is never 0 (thin fast parts never vanish).
        ``None``: every sample votes (eq. 28).
    trust_noise_mm : float or None
        σ of the trust tolerance (mm). ``None``: ``noise_mm`` where given, else the larger of
        the per-video noise estimate and the std of the temporal noise of static pixels of the
        first window (which sees the quantisation steps of structured-light depth). Give it
        (with ``noise_mm``, ``depth_range_mm`` and ``fusion_estimator``) to process a chunk
        exactly as the whole video.
    reach_noise_mm : float or None
        σ of a single sample's noise (mm) in the per-pixel reach
        (:func:`upsr.method.memory.state_caps`: how many frames a pixel on a slope may draw
        on) and in the significance tests of the radial offsets
        (:func:`upsr.method.trust.radial_offsets`) and of the slopes
        (:func:`upsr.method.slopes.follow_slopes`). ``None``: the trust's σ where a noise,
        the trust's noise or a noise profile is given or found, else the smaller of the
        trust's σ and the noise from space (the larger of the per-video noise estimate and
        the std of the second differences of the first window over √6,
        :func:`upsr.method.noise.spatial_noise_mm`): a moving camera's temporal differences
        are no sample's noise. Give it (with ``trust_noise_mm``) to process a chunk exactly
        as the whole video.
    trust_noise_profile : "auto", "constant" or (float, float)
        How σ of the trust tolerance depends on depth. ``"auto"``: estimated once per video
        from its first frames (:func:`upsr.method.noise.noise_profile`): where the noise grows
        with depth (structured light, stereo: about as z²) the tolerance of each pixel follows
        σ(z) = σ₁·(z / 1 m)^p at its anchor, else (ToF, p ≈ 0) one σ for the video; one σ too
        where ``noise_mm`` or ``trust_noise_mm`` is given. ``"constant"``: one σ.
        ``(σ₁, p)``: this profile (mm at 1 m, power ≥ 0; p = 0: one σ).
    min_trusted : int or None
        With fewer trusted samples than this the output is the anchor (the reference denoised
        on its surface): the window length becomes per pixel. ``None``:
        ``max(2, ceil(N/3))`` (at most N).
    remove_mixed : bool or "auto"
        Drop the mixed ("flying") input pixels of every frame (a depth more than the edge
        threshold from both its nearest and its farthest 8-neighbour: a ToF footprint across
        an edge) before the fusion, so that the other frames fill them; where none does, the
        reference's mixed pixel is split between the surfaces around it
        (:func:`upsr.method.mixed.remove_mixed_pixels`,
        :func:`~upsr.method.mixed.split_mixed_pixels`). ``"auto"``: decided per video from
        its first N frames (the recursive mode: pooled as they arrive), on when its edges
        between flat surfaces have a pixel between them at least
        :data:`~upsr.method.footprint.MIXED_SHARE` times as often as a footprint sensor's would
        (:func:`upsr.method.footprint.footprint_share`, each straight run of edge pixels
        weighing √ its length; a point-sampling sensor only on steep slopes and surfaces
        seen edge-on, which would be taken for mixed).
    radial_compensation : bool
        Subtract from each frame's samples its depth offset to the reference (motion along
        the viewing ray, a masked median over (2·radial_radius_px+1)² low-res px of one
        surface, kept where significant; :func:`upsr.method.trust.radial_offsets`) before the
        trust test and the fusion; where the offset exceeds half the edge threshold (within
        which it is measured, so truncated) the frame's samples abstain.
    radial_radius_px : int
        Half-size (low-res px) of the neighbourhood of the radial offsets.
    check_registration : bool
        Drop the samples of a frame around the pixels where it is misregistered: where, among
        the reference's interior pixels of a 5×5 low-res neighbourhood, several see another
        surface in that frame registered to the reference (a fast deforming part the flow did
        not follow, an occlusion; :func:`upsr.method.consistency.misregistered`). They vote
        neither on the depth nor on whether there is depth.
    fusion_estimator : {"auto", "median", "mean"}
        Estimate of the fused samples of a surface: the median (eq. 28, ML under Laplacian
        noise), the mean (ML under Gaussian noise; falls between quantisation steps), or
        ``"auto"``: chosen once per video, the mean where the depth is quantised in steps of
        at least half a noise std (:func:`upsr.method.noise.quantisation_step`: structured
        light, stereo), else from the tails of the spatial noise (the median where they are
        heavier than halfway between Gaussian and Laplacian noise:
        :func:`upsr.method.noise.tail_ratio`); in recursive mode the mean of the trusted
        samples (:mod:`upsr.method.recursive`).
    follow_slopes : bool
        After the deblurring, set the linear trend of each output block that lies on one
        surface to that surface's slope, measured on the reference's anchor between the block
        and its neighbours on the same surface, where the slope is significant (walls and
        floors seen at grazing angles, whose sub-pixel detail the other frames cannot give;
        never across a depth edge: :func:`upsr.method.slopes.follow_slopes`).
    fill_holes : bool
        INVENTED depth, off by default: after the deblurring, every pixel without depth takes
        the farthest (background-side) depth within r px, repeatedly, as the hole filling of
        depth SDKs (:func:`upsr.method.trust.fill_holes`).
    mode : {"windowed", "recursive"}
        ``"windowed"``: the paper's sliding window (N frames around each output, latency
        N − 1 − (N−1)//2 frames). ``"recursive"`` (beyond the paper): a causal state carried
        from one output to the next, one flow per frame, latency 0 frames, memory
        independent of N, where N caps how many frames the state summarises
        (:mod:`upsr.method.recursive`).
    camera_motion : {"flow", "depth"}
        Beyond the paper (both modes). ``"flow"``: the motion between frames is the optical
        flow (eq. 16–19). ``"depth"``: for a camera moving along its axis in a static scene
        (a vehicle driving forward): its rigid motion between consecutive frames is estimated
        from the depth itself and each pixel's motion follows from its depth, which sees the
        sub-pixel zoom a flow misses (:mod:`upsr.method.camera_motion`; needs
        ``camera_intrinsics``). Used only in the windows whose every step goes along the
        optical axis (recursive mode: once the last N − 1 steps did) and at the pixels whose
        flow agrees with it;
        elsewhere, and where the video's mixed pixels are removed (a footprint sensor: its
        mixes show the flow the sub-pixel motion), the flow
        (``benchmarks/registration_oracle.py``).
    camera_intrinsics : (fx, fy, cx, cy) or None
        Intrinsics (px) of the low-res frames, pixel (i, j) centred at (u, v) = (j, i); needed
        by ``camera_motion="depth"``.
    compand_knee_mm : "auto", float or None
        Beyond the paper. Depth quantised in disparity (structured light, stereo) is companded
        beyond this depth (mm), where one level step reaches the edge threshold, so that one
        level is one surface (:mod:`upsr.method.companding`). ``"auto"``: fitted on the first
        frame with depth (windowed: among the first N; none for continuous depth); None:
        never; never with ``camera_motion="depth"``, whatever is given.
    valid_range_mm : (float, float) or None
        Beyond the paper. (min, max) mm: the frames' depths outside are no measurement (0),
        as a depth camera SDK's threshold filter makes them: a sensor's stray near or far
        values (a RealSense reports up to 65.535 m) then never vote, and the output is 0
        there unless other frames measured it. None: every depth > 0 counts.
    deblur : DeblurConfig
        Deblurring parameters (eq. 29–30).
    """

    scale: int = 2
    n_frames: int = 9
    prefilter_sigma_mm: float = 40.0
    prefilter_sigma_px: float | None = None
    flow: str = "dis"
    flow_preset: str = "medium"
    flow_scale: int | None = None
    refine_preset: str | None = None
    depth_range_mm: tuple[float, float] | None = None
    noise_mm: float | None = None
    zero_motion_tolerance: float | None = 1.1
    refine: bool = True
    splat_radius_px: float | None = 1.0
    edge_votes: bool = True
    thin_parts: bool = True
    speckle_px: int | None = None
    min_valid_fraction: float = 0.5
    edge_mm: float = 100.0
    near_depth_mm: float | None = 1000.0
    edge_weight_px: float | None = 0.35
    edge_weight_floor: float = 0.25
    trust_k: float | None = 3.0
    trust_noise_mm: float | None = None
    reach_noise_mm: float | None = None
    trust_noise_profile: tuple[float, float] | str = "auto"
    min_trusted: int | None = None
    remove_mixed: bool | str = "auto"
    radial_compensation: bool = True
    radial_radius_px: int = 2
    check_registration: bool = True
    fusion_estimator: str = "auto"
    follow_slopes: bool = True
    fill_holes: bool = False
    mode: str = "windowed"
    camera_motion: str = "flow"
    camera_intrinsics: tuple[float, float, float, float] | None = None
    compand_knee_mm: float | str | None = "auto"
    valid_range_mm: tuple[float, float] | None = None
    deblur: DeblurConfig = field(default_factory=DeblurConfig)

    def __post_init__(self) -> None:
        _check_flags(self)
        _number("scale r", self.scale, 1, MAX_SCALE, integer=True)
        _number("n_frames N", self.n_frames, 1, MAX_N_FRAMES, integer=True)
        _number("prefilter_sigma_mm", self.prefilter_sigma_mm, 0, MAX_DEPTH_PARAM_MM, lo_open=True)
        _number("flow_scale", self.flow_scale, 1, int(self.scale), integer=True, none=True)
        _number(
            "prefilter_sigma_px", self.prefilter_sigma_px, 0, MAX_SIGMA_PX, lo_open=True, none=True
        )
        _check(
            _is_str(self.flow) and len(self.flow) <= 64,
            f"flow must be a backend name, not {_show(self.flow)}",
        )
        _check(
            self.flow_preset in ("ultrafast", "fast", "medium"),
            f"flow_preset must be 'ultrafast', 'fast' or 'medium', not {_show(self.flow_preset)}",
        )
        _check(
            self.refine_preset in (None, "ultrafast", "fast", "medium"),
            "refine_preset must be 'ultrafast', 'fast' or 'medium', not "
            f"{_show(self.refine_preset)}",
        )
        if self.depth_range_mm is not None:
            try:
                near, far = self.depth_range_mm
            except (TypeError, ValueError):
                raise InputError("depth_range_mm must be (near, far) or None") from None
            near = _number("depth_range_mm near", near, 0, MAX_DEPTH_PARAM_MM)
            far = _number("depth_range_mm far", far, 0, MAX_DEPTH_PARAM_MM)
            _check(near < far, "depth_range_mm must be (near, far) with 0 <= near < far")
            object.__setattr__(self, "depth_range_mm", (near, far))  # (a list: unhashable)
        _number("noise_mm", self.noise_mm, 0, MAX_DEPTH_PARAM_MM, none=True)
        _number("zero_motion_tolerance", self.zero_motion_tolerance, 0, MAX_TOLERANCE,
                lo_open=True, none=True)  # fmt: skip
        _number("min_valid_fraction", self.min_valid_fraction, 0, 1, hi_open=True)
        _number("speckle_px", self.speckle_px, 0, MAX_SPECKLE_PX, integer=True, none=True)
        _number("edge_mm", self.edge_mm, 0, MAX_DEPTH_PARAM_MM, lo_open=True)
        _number("near_depth_mm", self.near_depth_mm, 0, MAX_DEPTH_PARAM_MM, lo_open=True, none=True)
        _number("edge_weight_px", self.edge_weight_px, 0, MAX_SIGMA_PX, lo_open=True, none=True)
        _number("edge_weight_floor", self.edge_weight_floor, 0, 1)
        _number(
            "splat_radius_px", self.splat_radius_px, 0, MAX_SPLAT_RADIUS_PX, lo_open=True, none=True
        )
        _check(
            isinstance(self.deblur, DeblurConfig),
            f"deblur must be a DeblurConfig, not {_show(self.deblur)}",
        )
        _number("trust_k", self.trust_k, 0, MAX_TOLERANCE, lo_open=True, none=True)
        _number("trust_noise_mm", self.trust_noise_mm, 0, MAX_DEPTH_PARAM_MM, none=True)
        _number("reach_noise_mm", self.reach_noise_mm, 0, MAX_DEPTH_PARAM_MM, none=True)
        if not (_is_str(self.trust_noise_profile) and self.trust_noise_profile in _PROFILE_NAMES):
            message = (
                "trust_noise_profile must be 'auto', 'constant' or (sigma_1m_mm, power), not "
                f"{_show(self.trust_noise_profile)}"
            )
            try:
                sigma_1m, power = self.trust_noise_profile  # type: ignore[misc]
            except (TypeError, ValueError):
                raise InputError(message) from None
            profile = (_number("trust_noise_profile sigma_1m_mm", sigma_1m, 0, MAX_DEPTH_PARAM_MM),
                       _number("trust_noise_profile power", power, 0, MAX_NOISE_POWER))  # fmt: skip
            object.__setattr__(self, "trust_noise_profile", profile)
        _number("min_trusted", self.min_trusted, 1, MAX_N_FRAMES, integer=True, none=True)
        _number("radial_radius_px", self.radial_radius_px, 1, MAX_BTV_RADIUS_PX, integer=True)
        _check(
            self.fusion_estimator in ("auto", "median", "mean"),
            "fusion_estimator must be 'auto', 'median' or 'mean', not "
            f"{_show(self.fusion_estimator)}",
        )
        _check(
            self.mode in ("windowed", "recursive"),
            f"mode must be 'windowed' or 'recursive', not {_show(self.mode)}",
        )
        _check(
            self.camera_motion in ("flow", "depth"),
            f"camera_motion must be 'flow' or 'depth', not {_show(self.camera_motion)}",
        )
        if self.camera_intrinsics is not None:
            try:
                fx, fy, cx, cy = (float(v) for v in self.camera_intrinsics)
            except (TypeError, ValueError):
                message = "camera_intrinsics must be (fx, fy, cx, cy) in px or None"
                raise InputError(message) from None
            _check(
                all(math.isfinite(v) for v in (fx, fy, cx, cy)) and fx > 0 and fy > 0,
                "camera_intrinsics must be finite with fx, fy > 0",
            )
            object.__setattr__(self, "camera_intrinsics", (fx, fy, cx, cy))
        if self.valid_range_mm is not None:
            object.__setattr__(self, "valid_range_mm", _valid_range(self.valid_range_mm))
        if not (_is_str(self.compand_knee_mm) and self.compand_knee_mm == "auto"):
            _number("compand_knee_mm ('auto' or)", self.compand_knee_mm, 0, MAX_DEPTH_PARAM_MM,
                    lo_open=True, none=True)  # fmt: skip
        if self.camera_motion == "depth":
            _check(
                self.camera_intrinsics is not None,
                "camera_motion='depth' needs camera_intrinsics (fx, fy, cx, cy) of the frames",
            )
        _check(
            isinstance(self.remove_mixed, bool)
            or (_is_str(self.remove_mixed) and self.remove_mixed == "auto"),
            f"remove_mixed must be True, False or 'auto', not {_show(self.remove_mixed)}",
        )
        object.__setattr__(self, "scale", int(self.scale))
        object.__setattr__(self, "n_frames", int(self.n_frames))

    @property
    def half_before(self) -> int:
        """Frames of the window before the reference: ``(N-1)//2``."""
        return (self.n_frames - 1) // 2

    def flow_grid_scale(self, width_px: int) -> int:
        """Upsampling factor s of the flow grid for frames ``width_px`` wide (``flow_scale``)."""
        if self.flow_scale is not None:
            return int(self.flow_scale)
        lowest = 1 if self.mode == "recursive" else 2
        s = max(lowest, math.ceil(FLOW_GRID_MIN_WIDTH_PX / max(width_px, 1)))
        return int(min(self.scale, s))

    def residual_flow_preset(self, grid_width_px: int) -> str:
        """DIS preset of the eq. 19 residual flows on a flow grid ``grid_width_px`` wide."""
        if self.refine_preset is not None:
            return self.refine_preset
        return "ultrafast" if grid_width_px >= FLOW_GRID_MIN_WIDTH_PX else self.flow_preset

    @property
    def min_trusted_samples(self) -> int:
        """Fewest trusted samples of a pixel whose estimate replaces the anchor."""
        if self.min_trusted is not None:
            return int(min(self.min_trusted, self.n_frames))
        return int(min(max(2, math.ceil(self.n_frames / 3)), self.n_frames))

    @property
    def speckle_size_px(self) -> int:
        """Largest isolated region removed from the output (high-res px, ``speckle_px``)."""
        return self.scale * self.scale if self.speckle_px is None else int(self.speckle_px)

    @property
    def spatial_sigma_px(self) -> float:
        """Spatial std of the bilateral prefilter in high-res px."""
        if self.prefilter_sigma_px is not None:
            return float(self.prefilter_sigma_px)
        return 0.75 * self.scale + 0.5

    @classmethod
    def of_call(
        cls, scale: int | None, n_frames: int | None, config: UPSRConfig | None, options: dict
    ) -> UPSRConfig:
        """The config of a call given ``scale`` (None: 2), ``n_frames`` (None: 9), a ``config``
        or ``options``: ``config`` when given, ``scale`` and ``n_frames`` agreeing where given,
        no options beside it (they were dropped); else :meth:`from_options`."""
        given = (2 if scale is None else scale, 9 if n_frames is None else n_frames)
        if config is None:
            return cls.from_options(*given, **options)
        if options or scale not in (None, config.scale) or n_frames not in (None, config.n_frames):
            raise InputError(
                f"config (r = {config.scale}, N = {config.n_frames}) and scale={scale}, "
                f"n_frames={n_frames}{', ' + ', '.join(sorted(options)) if options else ''} "
                f"disagree: give the options in the config"
            )
        return config

    @classmethod
    def from_options(cls, scale: int, n_frames: int = 9, **options: Any) -> UPSRConfig:
        """Build a config from flat keyword options.

        Deblurring options may be given with a ``deblur_`` prefix (``deblur_lam=0.1``) or as a
        :class:`DeblurConfig` in ``deblur``; ``deblur=False`` disables the step. Unknown names
        raise :class:`~upsr.errors.InputError`.
        """
        deblur = options.pop("deblur", None)
        deblur_opts = {
            k[len("deblur_") :]: options.pop(k) for k in list(options) if k.startswith("deblur_")
        }
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(options) - names)
        if unknown:
            raise InputError(f"unknown option(s): {', '.join(unknown)}")
        if isinstance(deblur, DeblurConfig):
            dcfg = dataclasses.replace(deblur, **deblur_opts)
        else:
            if isinstance(deblur, Mapping):  # (its options, as deblur_* keywords)
                deblur_opts = {**deblur, **deblur_opts}
            elif isinstance(deblur, (bool, np.bool_)):
                deblur_opts.setdefault("enabled", bool(deblur))
            elif deblur is not None:
                raise InputError(
                    f"deblur must be a DeblurConfig, a mapping of its options or True/False, "
                    f"not {_show(deblur)}"
                )
            dcfg = DeblurConfig.from_mapping(deblur_opts)
        return cls(scale=scale, n_frames=n_frames, deblur=dcfg, **options)


def _check_flags(config: Any) -> None:
    """Every field of ``config`` typed ``bool`` holds a bool (``enabled="no"`` was taken as
    true)."""
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        _check(
            f.type != "bool" or isinstance(value, (bool, np.bool_)),
            f"{f.name} must be True or False, not {_show(value)}",
        )


def _is_int(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _is_str(value: Any) -> bool:
    return isinstance(value, str)


def _show(value: Any) -> str:
    """``repr(value)``, at most 40 characters (messages stay one short line)."""
    try:
        text = repr(value)
    except Exception:  # a hostile __repr__
        text = f"<{type(value).__name__}>"
    return text if len(text) <= 40 else text[:37] + "..."


def _number(
    name: str,
    value: Any,
    lo: float,
    hi: float,
    *,
    integer: bool = False,
    none: bool = False,
    lo_open: bool = False,
    hi_open: bool = False,
) -> Any:
    """Check a numeric option: a finite number (an integer if ``integer``) in its bounds.

    Bounds are ``lo <= value <= hi`` (``<`` where ``lo_open`` / ``hi_open``); None is accepted
    if ``none``. Huge integers, inf, NaN, strings: InputError (never OverflowError/TypeError).
    Returns the value as a float (an int if ``integer``), or None.
    """
    if value is None and none:
        return None
    lo_s, hi_s = "(" if lo_open else "[", ")" if hi_open else "]"
    bounds = f"{lo_s}{lo:g}, {hi:g}{hi_s}" + (" or None" if none else "")
    kind = "an integer" if integer else "a number"
    if integer:
        ok = _is_int(value)
        v: Any = int(value) if ok else None
    else:
        ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
            value, bool
        )
        v = None
        if ok:
            try:
                v = float(value)
            except (OverflowError, ValueError):  # an int beyond float range
                ok = False
            ok = ok and math.isfinite(v)
    if not ok:
        raise InputError(f"{name} must be {kind} in {bounds}, got {_show(value)}")
    if not (v > lo if lo_open else v >= lo):
        rel = ">" if lo_open else ">="
        raise InputError(f"{name} must be {kind} {rel} {lo:g}, got {_show(value)}")
    if not (v < hi if hi_open else v <= hi):
        rel = "<" if hi_open else "<="
        raise InputError(f"{name} must be {kind} {rel} {hi:g}, got {_show(value)}")
    return v


def _check(condition: bool, message: str) -> None:
    if not condition:
        raise InputError(message)
