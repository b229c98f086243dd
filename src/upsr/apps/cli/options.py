"""The options the ``upsr`` commands share, each defined once (typer ``Annotated`` aliases).

* method options (``upsr run`` and ``upsr batch``): ``--scale``, ``--frames`` and the options
  of :class:`upsr.method.config.UPSRConfig`, turned into a config by :func:`config_from_options`;
* read options (every command that reads a video): ``--key``, ``--topic``, ``--input-format``,
  ``--depth-scale``, ``--intrinsics``;
* units, identity and resources (``upsr run`` and ``upsr batch``): ``--input-depth-scale``,
  ``--output-depth-scale``, ``--sensor``, ``--strict-units``, ``--keep-names/--renumber``,
  ``--max-memory``;
* ``--format`` choices (:class:`OutFormat`; the choices' types are
  :mod:`upsr.apps.cli.choices`'s), ``--overwrite``, ``--quiet``.

Importing this module does not import NumPy or the method (``upsr --version`` stays fast): the
defaults shown in the help texts are written here and checked against
:class:`~upsr.method.config.UPSRConfig` by the tests.
"""

from __future__ import annotations

import math
from enum import Enum
from typing import TYPE_CHECKING, Annotated, Any

import typer

from upsr.apps.cli.choices import (
    Blur,
    CameraMotion,
    Flow,
    FlowPreset,
    FusionEstimator,
    InFormat,
    NoiseModel,
    OutFormat,
    Sensor,
    fmt,
)

if TYPE_CHECKING:
    from upsr.method.config import UPSRConfig

__all__ = [
    "DEFAULT_FRAMES",
    "HELP_DEFAULTS",
    "Blur",
    "Flow",
    "FlowPreset",
    "FusionEstimator",
    "InFormat",
    "NoiseModel",
    "OutFormat",
    "Sensor",
    "config_from_options",
    "fmt",
    "method_config",
]

DEFAULT_FRAMES = 9

#: The defaults of :class:`~upsr.method.config.UPSRConfig` the help texts show (tested equal).
HELP_DEFAULTS: dict[str, Any] = {
    "deblur.lam": 0.5,
    "deblur.alpha": 0.7,
    "deblur.radius_px": 2,
    "deblur.iterations": 15,
    "deblur.blur": "none",
    "flow": "dis",
    "flow_preset": "medium",
    "trust_k": 3.0,
    "edge_mm": 100.0,
    "deblur.smooth_sigma_mm": 30.0,
    "fusion_estimator": "auto",
    "trust_noise_profile": "auto",
}
_D = HELP_DEFAULTS


# ---------------------------------------------------------------------------------------------
# read options
# ---------------------------------------------------------------------------------------------
KeyOpt = Annotated[
    str | None,
    typer.Option("--key", help="Array of a .npz input, or channel of an EXR [default: auto]."),
]
TopicOpt = Annotated[
    str | None,
    typer.Option("--topic", help="ROS bag: the depth image topic [default: the only one]."),
]
InFormatOpt = Annotated[
    InFormat | None,
    typer.Option(
        "--input-format", case_sensitive=False, help="Input format [default: from the name]."
    ),
]
DepthScaleOpt = Annotated[
    float | None,
    typer.Option(
        "--depth-scale",
        "--input-depth-scale",
        metavar="UNITS_PER_M",
        show_default=False,
        help="Input raw units per metre (1000 = mm, 1 = metres, 5000 = TUM) of PNG/TIFF/EXR/PGM "
        "frames and .npy/.npz arrays [default: 1000]; bags and datasets fix theirs.",
    ),
]
#: ``--depth-scale`` of the commands that also write (``run``, ``batch``): the input's only.
DepthScaleAliasOpt = Annotated[
    float | None,
    typer.Option(
        "--depth-scale",
        show_default=False,
        help="Alias of --input-depth-scale (the input's raw units per metre only; the "
        "output's is --output-depth-scale).",
    ),
]
InputDepthScaleOpt = Annotated[
    float | None,
    typer.Option(
        "--input-depth-scale",
        metavar="UNITS_PER_M",
        show_default=False,
        help="Input raw units per metre (1000 = mm, 1 = metres, 5000 = TUM) of PNG/TIFF/"
        "EXR/PGM frames and .npy/.npz arrays [default: 1000]; bags and datasets fix theirs.",
    ),
]
OutputDepthScaleOpt = Annotated[
    float | None,
    typer.Option(
        "--output-depth-scale",
        metavar="UNITS_PER_M",
        show_default=False,
        help="PNG/TIFF/EXR output: raw units per metre (1000 = mm, 1 = metres) "
        "[default: 1000]. .npy/.npz/bags: always mm/m.",
    ),
]
SensorOpt = Annotated[
    Sensor,
    typer.Option(
        "--sensor",
        case_sensitive=False,
        help="Plausible depth range checked on the first frame (wrong units are warned "
        "about; refused with --strict-units).",
    ),
]
StrictUnitsOpt = Annotated[
    bool,
    typer.Option(
        "--strict-units",
        help="Refuse (exit 2) instead of warn when the first frame's depth is implausible "
        "for --sensor.",
    ),
]
KeepNamesOpt = Annotated[
    bool,
    typer.Option(
        "--keep-names/--renumber",
        help="PNG/EXR folder output: keep the input's frame names [default] or number the "
        "frames 000000, 000001, ...",
    ),
]
MaxMemoryOpt = Annotated[
    str | None,
    typer.Option(
        "--max-memory",
        metavar="SIZE",
        help="Memory the run may use (e.g. 4G, 512M) instead of what the machine has "
        "available; also skips the free-disk check [default: available memory].",
    ),
]
IntrinsicsOpt = Annotated[
    str | None,
    typer.Option(
        "--intrinsics",
        metavar="FX,FY,CX,CY|FILE.json",
        help="Camera intrinsics of the input (px), or a JSON file of them (an "
        "*.intrinsics.json, an Open3D PinholeCameraIntrinsic) [default: from the file: ROS "
        "CameraInfo, RealSense, or INPUT.intrinsics.json].",
    ),
]
#: ``--intrinsics`` of the commands that write OUTPUT.intrinsics.json (``run``, ``batch``).
OutIntrinsicsOpt = Annotated[
    str | None,
    typer.Option(
        "--intrinsics",
        metavar="FX,FY,CX,CY|FILE.json",
        help="Camera intrinsics of the input (px), or a JSON file of them (an "
        "*.intrinsics.json, an Open3D PinholeCameraIntrinsic) [default: from the file: ROS "
        "CameraInfo, RealSense, or INPUT.intrinsics.json]; scaled by r and written to "
        "OUTPUT.intrinsics.json.",
    ),
]
CameraMotionOpt = Annotated[
    CameraMotion,
    typer.Option(
        "--camera-motion",
        help="How the frames are registered: 'flow' (optical flow, any motion) or 'depth': "
        "where the camera moves along its axis in a static scene (a vehicle driving forward), "
        "its own motion estimated from the depth (needs the intrinsics), which sees the small "
        "zoom the flow misses; frames moved otherwise, bodies moving on their own and a "
        "time-of-flight sensor's frames keep the flow.",
    ),
]
OverwriteOpt = Annotated[bool, typer.Option("--overwrite", help="Replace existing outputs.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar on stderr.")]


# ---------------------------------------------------------------------------------------------
# method options (upsr run, upsr batch)
# ---------------------------------------------------------------------------------------------
ScaleOpt = Annotated[
    int,
    typer.Option(
        "--scale",
        "-r",
        show_default=False,
        help="Super-resolution factor r (integer, 1 <= r <= 16): output frames are (r*h) x (r*w).",
    ),
]
_FRAMES_HELP = (
    "Window length N: frames fused per output frame (1 <= N <= 256 and the number of "
    "frames) [default: 9, or all the frames of a shorter video]"
)
FramesOpt = Annotated[
    int | None,
    typer.Option(
        "--frames",
        "-n",
        show_default=False,
        help=f"{_FRAMES_HELP}; with --recursive the most frames a pixel's state counts (any "
        "video length).",
    ),
]
WindowedFramesOpt = Annotated[
    int | None, typer.Option("--frames", "-n", show_default=False, help=f"{_FRAMES_HELP}.")
]
NoDeblurOpt = Annotated[
    bool,
    typer.Option("--no-deblur", help="Skip the deblurring step (output the fused image)."),
]
LamOpt = Annotated[
    float | None,
    typer.Option(
        "--lam", help=f"Deblurring: BTV weight lambda >= 0 [default: {_D['deblur.lam']:g}]."
    ),
]
AlphaOpt = Annotated[
    float | None,
    typer.Option(
        "--alpha",
        help=f"Deblurring: BTV decay alpha in (0, 1] [default: {_D['deblur.alpha']:g}].",
    ),
]
BtvRadiusOpt = Annotated[
    int | None,
    typer.Option(
        "--btv-radius",
        help=f"Deblurring: BTV half-window P >= 1 (high-res px) "
        f"[default: {_D['deblur.radius_px']}].",
    ),
]
IterationsOpt = Annotated[
    int | None,
    typer.Option(
        "--iterations",
        help=f"Deblurring: number of steepest-descent steps >= 0 "
        f"[default: {_D['deblur.iterations']}].",
    ),
]
BlurOpt = Annotated[
    Blur | None,
    typer.Option(
        "--blur",
        case_sensitive=False,
        help=f"Deblurring: blur model B [default: {_D['deblur.blur']}].",
    ),
]
FlowOpt = Annotated[
    Flow | None,
    typer.Option(
        "--flow", case_sensitive=False, help=f"Optical-flow backend [default: {_D['flow']}]."
    ),
]
FlowPresetOpt = Annotated[
    FlowPreset | None,
    typer.Option(
        "--flow-preset",
        case_sensitive=False,
        help=f"DIS flow speed/accuracy preset [default: {_D['flow_preset']}].",
    ),
]
FlowScaleOpt = Annotated[
    int | None,
    typer.Option(
        "--flow-scale",
        min=1,
        help="Upsampling factor s <= r of the frames the flow is computed on [default: the "
        "smallest s >= 2 (--recursive: 1) with a flow grid >= 192 px wide]. Smaller: faster.",
    ),
]
RefinePresetOpt = Annotated[
    FlowPreset | None,
    typer.Option(
        "--refine-preset",
        case_sensitive=False,
        help="DIS preset of the eq. 19 residual flows [default: ultrafast on flow grids "
        ">= 192 px wide, else --flow-preset].",
    ),
]
SpecklePxOpt = Annotated[
    int | None,
    typer.Option(
        "--speckle-px",
        min=0,
        help="Isolated regions of at most this many output px with no neighbour within "
        "100 mm (noise outliers) become 0 = unknown [default: r*r; 0 keeps them].",
    ),
]
NoRefineOpt = Annotated[
    bool,
    typer.Option(
        "--no-refine",
        help="Skip the re-estimation of each motion against the "
        "registered neighbour (paper eq. 19): faster, less accurate.",
    ),
]
KeepAllMotionOpt = Annotated[
    bool,
    typer.Option(
        "--keep-all-motion",
        help="Keep the flow where zero motion explains the depth as well (no "
        "spurious-motion suppression): better for smooth bodies drifting sideways, worse "
        "on static backgrounds.",
    ),
]

RecursiveOpt = Annotated[
    bool,
    typer.Option(
        "--recursive",
        help="Recursive (causal) mode: each output from the current frame and a state "
        "carried from the previous output; latency 0 frames, one flow per frame, N caps "
        "the frames the state summarises (any video length).",
    ),
]


FillHolesOpt = Annotated[
    bool,
    typer.Option(
        "--fill-holes",
        help="fill pixels without depth from the farther (background) side, as depth SDKs "
        "do: invented depth",
    ),
]
TrustKOpt = Annotated[
    float | None,
    typer.Option(
        "--trust-k",
        metavar="K",
        help="Samples vote only within K*noise (+ relief) of the reference's anchor "
        f"[default: {_D['trust_k']:g}].",
    ),
]
EdgeMmOpt = Annotated[
    float | None,
    typer.Option(
        "--edge-mm",
        metavar="MM",
        help="Depth step between two surfaces, as given: no scaling by the scene's depth "
        f"[default: {_D['edge_mm']:g}, times the median depth / 1 m for a scene nearer than "
        "1 m; at least 4x the noise]; a ToF camera nearer than 1 m: a tenth of its depth.",
    ),
]
SmoothMmOpt = Annotated[
    float | None,
    typer.Option(
        "--smooth-mm",
        metavar="MM",
        min=0.0,
        help="Range std of the final smoothing of each surface along its plane [default: "
        f"{_D['deblur.smooth_sigma_mm']:g}, times the median depth / 1 m for a scene nearer "
        "than 1 m; at least the noise]; 0 turns it off (the blocks' own detail kept).",
    ),
]
ValidRangeOpt = Annotated[
    str | None,
    typer.Option(
        "--valid-range",
        metavar="MIN,MAX",
        help="Depths (mm) outside MIN..MAX are no measurement, as an SDK's threshold filter "
        "makes them (a sensor's stray values) [default: every depth > 0].",
    ),
]
NoTrustOpt = Annotated[
    bool,
    typer.Option("--no-trust", help="No trust test: the paper's plain median (eq. 28)."),
]
FusionEstimatorOpt = Annotated[
    FusionEstimator | None,
    typer.Option(
        "--fusion-estimator",
        case_sensitive=False,
        help="Fusion of the trusted samples: median, mean, or auto (median for "
        f"heavy-tailed noise, else mean) [default: {_D['fusion_estimator']}].",
    ),
]
NoiseModelOpt = Annotated[
    NoiseModel | None,
    typer.Option(
        "--noise-model",
        case_sensitive=False,
        help="Noise of the trust test and the deblurring's steps: auto (measured from the "
        "first frames; grows with depth where it does, as for structured-light and stereo "
        "cameras) or constant (one noise level per video) "
        f"[default: {_D['trust_noise_profile']}].",
    ),
]
MixedRemovalOpt = Annotated[
    bool | None,
    typer.Option(
        "--mixed-removal/--no-mixed-removal",
        help="Drop mixed (flying) input pixels of ToF sensors before the fusion (split between "
        "their neighbours where no frame fills them), or keep them [default: decided from "
        "the video: on when a third of its edges have a pixel between the two surfaces].",
        show_default=False,
    ),
]
NoCompandOpt = Annotated[
    bool,
    typer.Option(
        "--no-compand",
        help="Never compand the depth of a camera that quantises disparity (structured light, "
        "stereo) [default: beyond the depth where one level step reaches the edge step, "
        "measured on the first frame with depth].",
    ),
]
NoRegistrationCheckOpt = Annotated[
    bool,
    typer.Option(
        "--no-registration-check",
        help="Let the samples of frames the motion did not follow vote too (no check of each "
        "registered frame against the reference).",
    ),
]
NoRadialOpt = Annotated[
    bool,
    typer.Option(
        "--no-radial",
        help="No compensation of depth motion (toward/away from the camera) before fusion.",
    ),
]
NoSlopesOpt = Annotated[
    bool,
    typer.Option(
        "--no-slopes",
        help="Keep each output block's own trend: do not make blocks on one surface follow "
        "the slope measured between the reference's neighbouring pixels.",
    ),
]
NoEdgeVotesOpt = Annotated[
    bool,
    typer.Option(
        "--no-edge-votes",
        help="Place depth edges on the nearest sample of each frame (the r×r block grid) "
        "instead of the bilinear votes of the four samples around each position.",
    ),
]
NoThinPartsOpt = Annotated[
    bool,
    typer.Option(
        "--no-thin-parts",
        help="Where mixed pixels are removed, leave parts narrower than a pixel (legs, "
        "cables) and small clusters of like mixes (legs one to two pixels wide) as "
        "measured, a mix of the part and what lies behind, instead of splitting them "
        "(fewer flying pixels, some rmse where a part's place in its pixels is unsure).",
    ),
]


def config_from_options(
    scale: int,
    frames: int | None,
    *,
    lam: float | None = None,
    alpha: float | None = None,
    btv_radius: int | None = None,
    iterations: int | None = None,
    blur: Enum | None = None,
    flow: Enum | None = None,
    flow_preset: Enum | None = None,
    flow_scale: int | None = None,
    refine_preset: Enum | None = None,
    speckle_px: int | None = None,
    smooth_mm: float | None = None,
    no_deblur: bool = False,
    no_refine: bool = False,
    keep_all_motion: bool = False,
    recursive: bool = False,
    fill_holes: bool = False,
    trust_k: float | None = None,
    no_trust: bool = False,
    fusion_estimator: Enum | None = None,
    noise_model: Enum | None = None,
    mixed_removal: bool | None = None,
    no_compand: bool = False,
    no_registration_check: bool = False,
    no_radial: bool = False,
    no_slopes: bool = False,
    no_edge_votes: bool = False,
    no_thin_parts: bool = False,
    valid_range: str | None = None,
    edge_mm: float | None = None,
) -> UPSRConfig:
    """The :class:`UPSRConfig` of the method options shared by ``upsr run`` and ``upsr batch``
    (``None``: the default; ``frames=None``: N = 9)."""
    from upsr.errors import InputError
    from upsr.method.config import UPSRConfig

    # named as the user gave them (the config's own messages name its fields)
    if isinstance(scale, int) and scale < 1:
        raise InputError(f"--scale (-r) must be an integer >= 1, got {scale}")
    if isinstance(frames, int) and frames < 1:
        raise InputError(f"--frames (-n) must be an integer >= 1, got {frames}")
    options: dict[str, Any] = {}
    for name, value in (
        ("deblur_lam", lam),
        ("deblur_alpha", alpha),
        ("deblur_radius_px", btv_radius),
        ("deblur_iterations", iterations),
        ("flow_scale", flow_scale),
        ("speckle_px", speckle_px),
        ("trust_k", trust_k),
    ):
        if value is not None:
            options[name] = value
    for name, choice in (
        ("deblur_blur", blur),
        ("flow", flow),
        ("flow_preset", flow_preset),
        ("refine_preset", refine_preset),
        ("fusion_estimator", fusion_estimator),
        ("trust_noise_profile", noise_model),
    ):
        if choice is not None:
            options[name] = choice.value
    if no_deblur:
        options["deblur"] = False
    if no_refine:
        options["refine"] = False
    if keep_all_motion:
        options["zero_motion_tolerance"] = None
    if recursive:
        options["mode"] = "recursive"
    if no_trust:
        if trust_k is not None:
            raise InputError("give --trust-k or --no-trust, not both")
        options["trust_k"] = None
    if fill_holes:
        options["fill_holes"] = True
    if mixed_removal is not None:
        options["remove_mixed"] = mixed_removal
    if no_compand:
        options["compand_knee_mm"] = None
    for off, name in ((no_registration_check, "check_registration"), (no_slopes, "follow_slopes"),
                      (no_radial, "radial_compensation"), (no_edge_votes, "edge_votes"),
                      (no_thin_parts, "thin_parts")):  # fmt: skip
        if off:
            options[name] = False
    if smooth_mm is not None:  # (0: off; otherwise scaled and floored as the default is)
        if not math.isfinite(smooth_mm) or smooth_mm < 0:
            raise InputError(f"--smooth-mm must be a number >= 0 (mm), got {smooth_mm:g}")
        options["deblur_smooth_sigma_mm"] = smooth_mm if smooth_mm > 0 else None
    if valid_range is not None:
        options["valid_range_mm"] = parse_valid_range(valid_range)
    if edge_mm is not None:  # (the fusion's and the deblurring's: one step between surfaces)
        if not (math.isfinite(edge_mm) and edge_mm > 0):
            raise InputError(f"--edge-mm must be a number > 0 (mm), got {edge_mm:g}")
        options.update(edge_mm=edge_mm, deblur_edge_mm=edge_mm, near_depth_mm=None)
    return UPSRConfig.from_options(scale, DEFAULT_FRAMES if frames is None else frames, **options)


def parse_valid_range(text: str) -> tuple[float, float]:
    """``--valid-range MIN,MAX`` (mm) as two numbers (checked by :class:`UPSRConfig`)."""
    from upsr.errors import InputError

    try:
        lo, hi = (float(p) for p in str(text).split(","))
    except ValueError:
        raise InputError(
            f"--valid-range must be MIN,MAX in mm (e.g. 300,4000), got {text!r}"
        ) from None
    return lo, hi


def method_config(values: dict[str, Any]) -> UPSRConfig:
    """:func:`config_from_options` of the method options among a command's parameters
    (``values``: its ``locals()``, with ``scale`` and ``frames``; the options grafted by
    :func:`with_method_options` arrive in its ``method`` dict)."""
    import inspect

    values = {**values, **values.get("method", {})}
    names = set(inspect.signature(config_from_options).parameters) - {"scale", "frames"}
    options = {k: values[k] for k in names if k in values}
    return config_from_options(values["scale"], values["frames"], **options)


#: The method options of ``upsr run`` and ``upsr batch`` (name, annotation, default), in the
#: order of their --help; :func:`with_method_options` adds them to both commands.
METHOD_OPTIONS: tuple[tuple[str, Any, Any], ...] = (
    ("no_deblur", NoDeblurOpt, False),
    ("lam", LamOpt, None),
    ("alpha", AlphaOpt, None),
    ("btv_radius", BtvRadiusOpt, None),
    ("iterations", IterationsOpt, None),
    ("blur", BlurOpt, None),
    ("flow", FlowOpt, None),
    ("flow_preset", FlowPresetOpt, None),
    ("flow_scale", FlowScaleOpt, None),
    ("refine_preset", RefinePresetOpt, None),
    ("speckle_px", SpecklePxOpt, None),
    ("smooth_mm", SmoothMmOpt, None),
    ("no_refine", NoRefineOpt, False),
    ("keep_all_motion", KeepAllMotionOpt, False),
    ("fill_holes", FillHolesOpt, False),
    ("trust_k", TrustKOpt, None),
    ("no_trust", NoTrustOpt, False),
    ("fusion_estimator", FusionEstimatorOpt, None),
    ("noise_model", NoiseModelOpt, None),
    ("mixed_removal", MixedRemovalOpt, None),
    ("no_compand", NoCompandOpt, False),
    ("no_registration_check", NoRegistrationCheckOpt, False),
    ("no_radial", NoRadialOpt, False),
    ("no_slopes", NoSlopesOpt, False),
    ("no_edge_votes", NoEdgeVotesOpt, False),
    ("no_thin_parts", NoThinPartsOpt, False),
    ("valid_range", ValidRangeOpt, None),
    ("edge_mm", EdgeMmOpt, None),
)


def with_method_options(command: Any) -> Any:
    """Give a command (declared with ``**method``) the :data:`METHOD_OPTIONS` as parameters.

    typer reads the command's ``__signature__`` and annotations: the shared options are
    written once, here, and reach the command in its ``method`` dict.
    """
    import inspect
    import typing

    sig = inspect.signature(command)
    hints = typing.get_type_hints(command, include_extras=True)  # the Annotated objects
    own = [
        p.replace(annotation=hints.get(p.name, p.annotation))
        for p in sig.parameters.values()
        if p.kind is not p.VAR_KEYWORD
    ]
    added = [
        inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=ann)
        for name, ann, default in METHOD_OPTIONS
    ]
    command.__signature__ = sig.replace(parameters=[*own, *added])
    command.__annotations__ = {
        **{p.name: p.annotation for p in own},
        **{name: ann for name, ann, _ in METHOD_OPTIONS},
        "return": hints.get("return", sig.return_annotation),
    }
    return command
