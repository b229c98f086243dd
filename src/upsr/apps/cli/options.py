"""The options the ``upsr`` commands share, each defined once (typer ``Annotated`` aliases).

* method options (``upsr run`` and ``upsr batch``): ``--scale``, ``--frames`` and the 13 options
  of :class:`upsr.method.config.UPSRConfig`, turned into a config by :func:`config_from_options`;
* read options (every command that reads a video): ``--key``, ``--topic``, ``--input-format``,
  ``--depth-scale``, ``--intrinsics``;
* ``--format`` choices (:class:`OutFormat`), ``--overwrite``, ``--quiet``.

Importing this module does not import NumPy or the method (``upsr --version`` stays fast): the
defaults shown in the help texts are written here and checked against
:class:`~upsr.method.config.UPSRConfig` by the tests.
"""

from __future__ import annotations

from enum import Enum
from typing import TYPE_CHECKING, Annotated, Any

import typer

if TYPE_CHECKING:
    from upsr.method.config import UPSRConfig

__all__ = [
    "DEFAULT_FRAMES",
    "HELP_DEFAULTS",
    "Blur",
    "Flow",
    "FlowPreset",
    "InFormat",
    "OutFormat",
    "config_from_options",
    "fmt",
    "read_options",
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
}
_D = HELP_DEFAULTS


# ---------------------------------------------------------------------------------------------
# choices
# ---------------------------------------------------------------------------------------------
class InFormat(str, Enum):
    """Input formats of :mod:`upsr.io` (``--input-format``)."""

    npy = "npy"
    npz = "npz"
    png = "png"
    tiff = "tiff"
    exr = "exr"
    rosbag = "rosbag"
    nyu = "nyu"
    pgm = "pgm"
    tum = "tum"
    sun = "sun"


class OutFormat(str, Enum):
    """Output formats (``upsr run --format``, ``upsr batch --format``)."""

    npy = "npy"
    npz = "npz"
    png = "png"
    tiff = "tiff"
    exr = "exr"


class Blur(str, Enum):
    none = "none"
    box = "box"
    gaussian = "gaussian"


class Flow(str, Enum):
    dis = "dis"
    farneback = "farneback"


class FlowPreset(str, Enum):
    ultrafast = "ultrafast"
    fast = "fast"
    medium = "medium"


def fmt(value: Enum | None) -> str | None:
    """The string of a choice, None for none."""
    return None if value is None else str(value.value)


def read_options(
    key: str | None, topic: str | None, input_format: InFormat | None, depth_scale: float
) -> dict[str, Any]:
    """The keyword arguments of :func:`upsr.io.iter_frames` for the read options."""
    return {"key": key, "topic": topic, "fmt": fmt(input_format), "depth_scale": depth_scale}


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
    float,
    typer.Option(
        "--depth-scale",
        help="PNG/TIFF/EXR/PGM: raw units per metre (1000 = mm, TUM: 5000, metres: 1).",
    ),
]
#: ``--depth-scale`` of the commands that also write PNG (``run``, ``batch``).
OutDepthScaleOpt = Annotated[
    float,
    typer.Option(
        "--depth-scale",
        help="PNG/TIFF/EXR/PGM input and PNG output: raw units per metre (1000 = mm, "
        "TUM: 5000, metres: 1). .npy/.npz always hold mm.",
    ),
]
IntrinsicsOpt = Annotated[
    str | None,
    typer.Option(
        "--intrinsics",
        metavar="FX,FY,CX,CY",
        help="Camera intrinsics of the input (px) [default: from the file: ROS CameraInfo, "
        "RealSense, or INPUT.intrinsics.json].",
    ),
]
#: ``--intrinsics`` of the commands that write OUTPUT.intrinsics.json (``run``, ``batch``).
OutIntrinsicsOpt = Annotated[
    str | None,
    typer.Option(
        "--intrinsics",
        metavar="FX,FY,CX,CY",
        help="Camera intrinsics of the input (px) [default: from the file: ROS CameraInfo, "
        "RealSense, or INPUT.intrinsics.json]; scaled by r and written to "
        "OUTPUT.intrinsics.json.",
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
        help="Super-resolution factor r (integer >= 1): output frames are (r*h) x (r*w).",
    ),
]
FramesOpt = Annotated[
    int | None,
    typer.Option(
        "--frames",
        "-n",
        show_default=False,
        help="Window length N: frames fused per output frame (1 <= N <= number of frames) "
        "[default: 9, or all the frames of a shorter video].",
    ),
]
NoDeblurOpt = Annotated[
    bool,
    typer.Option("--no-deblur", help="Skip the deblurring step (output the fused median)."),
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
        "smallest s >= 2 giving a flow grid >= 192 px wide]. Smaller: faster.",
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
    no_deblur: bool = False,
    no_refine: bool = False,
    keep_all_motion: bool = False,
    recursive: bool = False,
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
    ):
        if value is not None:
            options[name] = value
    for name, choice in (
        ("deblur_blur", blur),
        ("flow", flow),
        ("flow_preset", flow_preset),
        ("refine_preset", refine_preset),
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
    return UPSRConfig.from_options(scale, DEFAULT_FRAMES if frames is None else frames, **options)
