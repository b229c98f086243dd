"""``upsr compare`` and ``upsr view``: pictures of depth videos.

``upsr compare``
    Side-by-side low-res / bicubic / UP-SR (/ truth / error) as PNG, animated GIF or MP4.
``upsr view``
    A rendered 3-D view of one frame (PNG).
"""

from __future__ import annotations

import contextlib
import math
import sys
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from upsr.apps._preflight import read_options
from upsr.apps.cli.options import (
    DepthScaleOpt,
    InFormatOpt,
    IntrinsicsOpt,
    KeyOpt,
    OverwriteOpt,
    QuietOpt,
    TopicOpt,
    fmt,
)
from upsr.errors import InputError

if TYPE_CHECKING:
    import numpy as np

__all__ = ["Shading", "compare", "register", "view"]


class Shading(str, Enum):
    gray = "gray"
    depth = "depth"


#: bounds of ``compare --fps`` (frames per second) and ``view --width`` (px)
FPS_RANGE = (0.1, 240.0)
MAX_VIEW_WIDTH = 8192


def frame_index(frame: int, n: int, path: Path) -> int:
    """``--frame`` (negative: from the end) as an index into the ``n`` frames of ``path``."""
    if not -n <= frame < n:
        raise InputError(f"--frame {frame}: {path} has frames 0..{n - 1}")
    return frame % n


def _nth(frames: Any, k: int) -> np.ndarray:
    with contextlib.closing(frames):
        for t, f in enumerate(frames):
            if t == k:
                return f  # type: ignore[no-any-return]
    raise InputError(f"frame {k} not found")  # pragma: no cover - probe counted the frames


def _parse_range(text: str | None, name: str) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"{name} must be MIN,MAX in mm, got {text!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise InputError(f"{name} must be MIN,MAX with MIN < MAX, got {text!r}")
    return lo, hi


# ---------------------------------------------------------------------------------------------
# compare
# ---------------------------------------------------------------------------------------------
_COMPARE_EPILOG = """\b
Examples:
  upsr compare lowres.npy upsr.npy --truth truth.npy -o cmp.png --frame 3
  upsr compare lowres.npy upsr.npy -o cmp.gif --fps 4
  upsr compare capture.bag out.npy -o cmp.mp4 --scale 2
"""


def _compare_scale(
    lowres: Path, upsr_path: Path, truth: Path | None, lo_info: Any, scale: int | None
) -> tuple[int, int]:
    """The SR factor r and the number of frames of a comparison, checked."""
    from upsr.io import video as io

    up_info = io.probe(upsr_path)
    tr_info = io.probe(truth) if truth is not None else None
    r = scale
    if r is None:
        r = up_info.height // lo_info.height
    if r < 1 or (up_info.height, up_info.width) != (lo_info.height * r, lo_info.width * r):
        raise InputError(
            f"{upsr_path}: frames {up_info.width}x{up_info.height} are not r={r} times the "
            f"low-res {lo_info.width}x{lo_info.height} frames"
        )
    n = min(lo_info.n_frames, up_info.n_frames)
    if lo_info.n_frames != up_info.n_frames:
        raise InputError(
            f"{lowres} has {lo_info.n_frames} frames, {upsr_path} has {up_info.n_frames}"
        )
    if tr_info is not None:
        if tr_info.shape != up_info.shape:
            raise InputError(
                f"--truth {truth}: shape {tr_info.shape} differs from {upsr_path}'s {up_info.shape}"
            )
    return r, n


def _colour_scales(
    lo_f: np.ndarray,
    up_f: np.ndarray,
    tr_f: np.ndarray | None,
    rng: tuple[float, float] | None,
    error_max: float | None,
) -> tuple[tuple[float, float], float | None]:
    """The depth colour scale (``--range``, else 1-99th percentile) and the error scale (mm)."""
    import numpy as np

    if rng is None:
        ref = tr_f if tr_f is not None else up_f
        vals = ref[ref > 0]
        if not vals.size:
            vals = lo_f[lo_f > 0]
        lo_p, hi_p = np.percentile(vals, [1, 99]) if vals.size else (0.0, 1000.0)
        rng = (float(lo_p), float(max(hi_p, lo_p + 1.0)))
    if error_max is None and tr_f is not None:
        both = (tr_f > 0) & (up_f > 0)
        errs = np.abs(up_f - tr_f)[both]
        error_max = max(float(np.percentile(errs, 99)), 1.0) if errs.size else 1.0
    return rng, error_max


def compare(
    lowres: Annotated[Path, typer.Argument(metavar="LOWRES", help="Low-res input video.")],
    upsr_path: Annotated[Path, typer.Argument(metavar="UPSR", help="UP-SR output video.")],
    output: Annotated[
        Path,
        typer.Option(
            "--output", "-o", show_default=False, help="Picture: .png (one frame), .gif or .mp4."
        ),
    ],
    truth: Annotated[
        Path | None,
        typer.Option("--truth", help="Ground-truth high-res video: adds truth and error panels."),
    ] = None,
    scale: Annotated[
        int | None,
        typer.Option("--scale", "-r", help="SR factor r [default: from the frame sizes]."),
    ] = None,
    frame: Annotated[
        int, typer.Option("--frame", "-k", help="PNG: the frame shown (negative: from the end).")
    ] = 0,
    fps: Annotated[float, typer.Option("--fps", help="GIF/MP4 frame rate.")] = 5.0,
    depth_range: Annotated[
        str | None,
        typer.Option(
            "--range",
            metavar="MIN,MAX",
            help="Depth colour scale in mm [default: 1-99th percentile of the first frame shown "
            "(PNG: the --frame one; GIF/MP4: frame 0), of --truth if given, else of UP-SR].",
        ),
    ] = None,
    error_max: Annotated[
        float | None,
        typer.Option("--error-max", help="Top of the error colour scale in mm [default: auto]."),
    ] = None,
    key: KeyOpt = None,
    topic: TopicOpt = None,
    input_format: InFormatOpt = None,
    depth_scale: DepthScaleOpt = None,
    overwrite: OverwriteOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Side-by-side pictures: low-res, bicubic, UP-SR (and truth, |UP-SR - truth|).

    One colour scale in mm for every depth panel, with a colour bar; pixels without depth are
    black. The read options apply to LOWRES; UPSR and --truth are read by their names.
    """
    from tqdm import tqdm

    from upsr.io import video as io
    from upsr.io.paths import check_apart_from_inputs
    from upsr.viz.pictures import ComparisonWriter, comparison_frame, picture_kind

    kind = picture_kind(output)
    check_apart_from_inputs([p for p in (lowres, upsr_path, truth) if p is not None], output)
    if output.exists() and not overwrite:
        raise InputError(f"output {output} already exists (use --overwrite to replace it)")
    if error_max is not None and not (math.isfinite(error_max) and error_max > 0):
        raise InputError(f"--error-max must be > 0, got {error_max}")
    if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:  # also NaN; a GIF's frame time is 1/fps
        raise InputError(f"--fps must be {FPS_RANGE[0]:g}..{FPS_RANGE[1]:g}, got {fps:g}")
    rng = _parse_range(depth_range, "--range")
    given = [p for p in (lowres, upsr_path, truth) if p is not None]
    read = read_options(key, topic, fmt(input_format), depth_scale, given)
    lo_info = io.probe(lowres, key=key, fmt=read["fmt"], topic=topic)
    r, n = _compare_scale(lowres, upsr_path, truth, lo_info, scale)
    lo_frames = io.iter_frames(lowres, **read)
    up_frames = io.iter_frames(upsr_path)
    tr_frames = io.iter_frames(truth) if truth is not None else None
    ks = [frame_index(frame, n, lowres)] if kind == "png" else list(range(n))
    with (
        ComparisonWriter(output, fps=fps) as writer,
        tqdm(total=len(ks), desc="compare", file=sys.stderr, disable=quiet, leave=False) as bar,
    ):
        scales: tuple[tuple[float, float], float | None] | None = None
        depth_shown = False
        for t in range(n):
            lo_f = next(lo_frames)
            up_f = next(up_frames)
            tr_f = next(tr_frames) if tr_frames is not None else None
            if t not in ks:
                if t > ks[-1]:
                    break
                continue
            depth_shown = depth_shown or bool((lo_f > 0).any() or (up_f > 0).any())
            if scales is None:  # fixed on the first frame shown
                scales = _colour_scales(lo_f, up_f, tr_f, rng, error_max)
            (vmin, vmax), err_max = scales
            img = comparison_frame(
                lo_f,
                up_f,
                r,
                tr_f,
                vmin_mm=vmin,
                vmax_mm=vmax,
                error_max_mm=err_max,
                caption=f"frame {t}/{n - 1}",
            )
            writer.write(img)
            bar.update(1)
        if not depth_shown:  # (a black picture; run, view and export-ply refuse such input)
            raise InputError(
                f"{lowres}, {upsr_path}: no valid depth in the frame(s) compared (all 0 or NaN)"
            )
    typer.echo(f"upsr: compare: {len(ks)} frame(s) -> {output}")


# ---------------------------------------------------------------------------------------------
# view
# ---------------------------------------------------------------------------------------------
def view(
    input_path: Annotated[Path, typer.Argument(metavar="INPUT", help="Depth video.")],
    output: Annotated[
        Path, typer.Option("--output", "-o", show_default=False, help="Picture (.png).")
    ],
    frame: Annotated[
        int, typer.Option("--frame", "-k", help="Frame to show (negative: from the end).")
    ] = 0,
    intrinsics: IntrinsicsOpt = None,
    yaw: Annotated[
        float,
        typer.Option("--yaw", help="Viewpoint turned about the scene (deg; > 0: from the left)."),
    ] = 35.0,
    pitch: Annotated[
        float,
        typer.Option("--pitch", help="Viewpoint turned about the scene (deg; > 0: from below)."),
    ] = 20.0,
    shading: Annotated[
        Shading, typer.Option("--shading", case_sensitive=False, help="Grey or depth colours.")
    ] = Shading.gray,
    edge_mm: Annotated[
        float, typer.Option("--edge-mm", help="No surface across depth jumps larger than this.")
    ] = 100.0,
    width: Annotated[int, typer.Option("--width", help="Minimum picture width (px).")] = 640,
    key: KeyOpt = None,
    topic: TopicOpt = None,
    input_format: InFormatOpt = None,
    depth_scale: DepthScaleOpt = None,
    overwrite: OverwriteOpt = False,
) -> None:
    """Render one frame as a lit 3-D surface seen from a rotated viewpoint (paper Fig. 3).

    Without intrinsics (--intrinsics, or carried by the file) a 60-degree horizontal field of
    view is assumed (the shape is then only approximate). The viewpoint turns about the
    median 3-D point with the camera's own field of view: parts of the frame far from it may
    fall outside the picture (--yaw 0 --pitch 0 shows the whole frame).
    """
    from upsr.apps._camera import input_camera
    from upsr.geometry.camera import PinholeCamera
    from upsr.io import units
    from upsr.io import video as io
    from upsr.io.paths import check_apart_from_inputs
    from upsr.viz.colormaps import write_png
    from upsr.viz.pictures import render_view

    if output.suffix.lower() != ".png":
        raise InputError(f"{output}: the view is written as a .png file")
    check_apart_from_inputs(input_path, output)
    if output.exists() and not overwrite:
        raise InputError(f"output {output} already exists (use --overwrite to replace it)")
    if not 16 <= width <= MAX_VIEW_WIDTH:  # the picture is width x about width px
        raise InputError(f"--width must be 16..{MAX_VIEW_WIDTH}, got {width}")
    for name, value in (("--yaw", yaw), ("--pitch", pitch), ("--edge-mm", edge_mm)):
        if not math.isfinite(value):
            raise InputError(f"{name} must be a finite number, got {value}")
    read = read_options(key, topic, fmt(input_format), depth_scale, [input_path])
    info = io.probe(input_path, key=key, fmt=read["fmt"], topic=topic)
    k = frame_index(frame, info.n_frames, input_path)
    cam = input_camera(input_path, info, intrinsics, fmt=read["fmt"], topic=topic)
    if cam is None:
        cam = PinholeCamera.from_fov(info.width, info.height, 60.0)
    depth = _nth(io.iter_frames(input_path, **read), k)
    # (a metres file read as mm renders a scene 1000 times too small)
    units.check_depth_range(depth, depth_scale=read["depth_scale"], name=str(input_path),
                            option="--depth-scale")  # fmt: skip
    img = render_view(
        depth,
        cam,
        yaw_deg=yaw,
        pitch_deg=pitch,
        min_width_px=width,
        edge_mm=edge_mm,
        shading=shading.value,
    )
    write_png(output, img)
    typer.echo(f"upsr: view of frame {k} -> {output}")


def register(app: typer.Typer) -> None:
    """Add ``compare`` and ``view`` to the ``upsr`` app."""
    app.command("compare", epilog=_COMPARE_EPILOG, no_args_is_help=True)(compare)
    app.command(
        "view",
        epilog="\b\nExample:\n  upsr view out.npy --frame 4 -o view.png",
        no_args_is_help=True,
    )(view)
