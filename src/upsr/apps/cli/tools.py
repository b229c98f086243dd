"""``upsr`` commands for pictures, point clouds and batches (registered by :mod:`upsr.apps.cli.main`).

``upsr compare``
    Side-by-side low-res / bicubic / UP-SR (/ truth / error) as PNG, animated GIF or MP4.
``upsr view``
    A rendered 3-D view of one frame (PNG).
``upsr export-ply``
    A coloured PLY point cloud per frame.
``upsr batch``
    Many recordings, on local processes or a Dask cluster, resumable.
"""

from __future__ import annotations

import contextlib
import math
import sys
import time
from enum import Enum
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from upsr.errors import InputError
from upsr.method.config import DeblurConfig, UPSRConfig

__all__ = ["InFormat", "register"]

_DEFAULT_CFG = UPSRConfig()
_DEFAULT_DEBLUR = DeblurConfig()
DEFAULT_FRAMES = 9


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
) -> UPSRConfig:
    """The :class:`UPSRConfig` of the method options shared by ``upsr run`` and ``upsr batch``
    (``None``: the default; ``frames=None``: N = 9)."""
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
    return UPSRConfig.from_options(scale, DEFAULT_FRAMES if frames is None else frames, **options)


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


class BatchFormat(str, Enum):
    """Output formats of ``upsr batch``."""

    npy = "npy"
    npz = "npz"
    tiff = "tiff"
    png = "png"
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


class Shading(str, Enum):
    gray = "gray"
    depth = "depth"


# ---------------------------------------------------------------------------------------------
# shared options
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
IntrinsicsOpt = Annotated[
    str | None,
    typer.Option(
        "--intrinsics",
        metavar="FX,FY,CX,CY",
        help="Camera intrinsics of the input (px) [default: from the file: ROS CameraInfo, "
        "RealSense, or INPUT.intrinsics.json].",
    ),
]
OverwriteOpt = Annotated[bool, typer.Option("--overwrite", help="Replace existing outputs.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar on stderr.")]


def _fmt(value: Enum | None) -> str | None:
    return None if value is None else str(value.value)


def _read_opts(
    key: str | None, topic: str | None, input_format: InFormat | None, depth_scale: float
) -> dict[str, Any]:
    return {"key": key, "topic": topic, "fmt": _fmt(input_format), "depth_scale": depth_scale}


def _camera_for(path: Path, info: Any, intrinsics: str | None, read: dict[str, Any]) -> Any:
    """The camera of a video: --intrinsics, else what the file (or its sidecar) carries."""
    from upsr.geometry.intrinsics import parse_intrinsics
    from upsr.io import _core as io

    if intrinsics is not None:
        return parse_intrinsics(intrinsics, info.width, info.height)
    cam = io.read_intrinsics(path, fmt=read["fmt"], topic=read["topic"])
    if cam is not None and cam.shape != (info.height, info.width):
        raise InputError(
            f"{path}: its intrinsics are for {cam.width}x{cam.height} images, the frames are "
            f"{info.width}x{info.height}"
        )
    return cam


def _frame_index(frame: int, n: int, path: Path) -> int:
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
            help="Depth colour scale in mm [default: 1-99th percentile of the first frame].",
        ),
    ] = None,
    error_max: Annotated[
        float | None,
        typer.Option("--error-max", help="Top of the error colour scale in mm [default: auto]."),
    ] = None,
    key: KeyOpt = None,
    topic: TopicOpt = None,
    input_format: InFormatOpt = None,
    depth_scale: DepthScaleOpt = 1000.0,
    overwrite: OverwriteOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Side-by-side pictures: low-res, bicubic, UP-SR (and truth, |UP-SR - truth|).

    One colour scale in mm for every depth panel, with a colour bar; pixels without depth are
    black. The read options apply to LOWRES; UPSR and --truth are read by their names.
    """
    from tqdm import tqdm

    from upsr.io import _core as io
    from upsr.viz.pictures import ComparisonWriter, comparison_frame, picture_kind

    kind = picture_kind(output)
    if output.exists() and not overwrite:
        raise InputError(f"output {output} already exists (use --overwrite to replace it)")
    if error_max is not None and not (math.isfinite(error_max) and error_max > 0):
        raise InputError(f"--error-max must be > 0, got {error_max}")
    rng = _parse_range(depth_range, "--range")
    read = _read_opts(key, topic, input_format, depth_scale)
    lo_info = io.probe(lowres, key=key, fmt=read["fmt"], topic=topic)
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
    lo_frames = io.iter_frames(lowres, **read)
    up_frames = io.iter_frames(upsr_path)
    tr_frames = io.iter_frames(truth) if truth is not None else None
    ks = [_frame_index(frame, n, lowres)] if kind == "png" else list(range(n))
    with (
        ComparisonWriter(output, fps=fps) as writer,
        tqdm(total=len(ks), desc="compare", file=sys.stderr, disable=quiet, leave=False) as bar,
    ):
        vmin = vmax = None
        for t in range(n):
            lo_f = next(lo_frames)
            up_f = next(up_frames)
            tr_f = next(tr_frames) if tr_frames is not None else None
            if t not in ks:
                if t > ks[-1]:
                    break
                continue
            if vmin is None:
                if rng is None:
                    ref = tr_f if tr_f is not None else up_f
                    vals = ref[ref > 0]
                    if not vals.size:
                        vals = lo_f[lo_f > 0]
                    lo_p, hi_p = np.percentile(vals, [1, 99]) if vals.size else (0.0, 1000.0)
                    rng = (float(lo_p), float(max(hi_p, lo_p + 1.0)))
                vmin, vmax = rng
                if error_max is None and tr_f is not None:
                    both = (tr_f > 0) & (up_f > 0)
                    errs = np.abs(up_f - tr_f)[both]
                    error_max = max(float(np.percentile(errs, 99)), 1.0) if errs.size else 1.0
            img = comparison_frame(
                lo_f,
                up_f,
                r,
                tr_f,
                vmin_mm=vmin,
                vmax_mm=vmax,  # type: ignore[arg-type]
                error_max_mm=error_max,
                caption=f"frame {t}/{n - 1}",
            )
            writer.write(img)
            bar.update(1)
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
    yaw: Annotated[float, typer.Option("--yaw", help="View rotation left/right (deg).")] = 35.0,
    pitch: Annotated[float, typer.Option("--pitch", help="View rotation up/down (deg).")] = 20.0,
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
    depth_scale: DepthScaleOpt = 1000.0,
    overwrite: OverwriteOpt = False,
) -> None:
    """Render one frame as a lit 3-D surface seen from a rotated viewpoint (paper Fig. 3).

    Without intrinsics (--intrinsics, or carried by the file) a 60-degree horizontal field of
    view is assumed (the shape is then only approximate).
    """
    from upsr.geometry.camera import PinholeCamera
    from upsr.io import _core as io
    from upsr.viz.colormaps import write_png
    from upsr.viz.pictures import render_view

    if output.suffix.lower() != ".png":
        raise InputError(f"{output}: the view is written as a .png file")
    if output.exists() and not overwrite:
        raise InputError(f"output {output} already exists (use --overwrite to replace it)")
    if width < 16:
        raise InputError(f"--width must be >= 16, got {width}")
    read = _read_opts(key, topic, input_format, depth_scale)
    info = io.probe(input_path, key=key, fmt=read["fmt"], topic=topic)
    k = _frame_index(frame, info.n_frames, input_path)
    cam = _camera_for(input_path, info, intrinsics, read)
    if cam is None:
        cam = PinholeCamera.from_fov(info.width, info.height, 60.0)
    depth = _nth(io.iter_frames(input_path, **read), k)
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


# ---------------------------------------------------------------------------------------------
# export-ply
# ---------------------------------------------------------------------------------------------
def _colour_source(color: Path | None, n: int) -> list[Path | None]:
    if color is None:
        return [None] * n
    from upsr.io._common import frame_files

    suffixes = (".png", ".jpg", ".jpeg", ".ppm", ".pgm", ".bmp", ".tif", ".tiff")
    if not color.exists():
        raise InputError(f"--color {color}: no such file or folder")
    files = frame_files(color, suffixes, "colour image")
    if len(files) == 1 and n > 1 and not color.is_dir():
        return [files[0]] * n
    if len(files) != n:
        raise InputError(f"--color {color}: {len(files)} colour images for {n} depth frames")
    return list(files)


def _read_colour(path: Path) -> np.ndarray:
    import cv2

    data = np.fromfile(path, np.uint8) if path.is_file() else None
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data is not None and data.size else None
    if img is None:
        raise InputError(f"{path}: cannot read the colour image")
    return img


def export_ply(
    input_path: Annotated[Path, typer.Argument(metavar="INPUT", help="Depth video.")],
    out: Annotated[
        Path, typer.Option("--out", "-o", show_default=False, help="Folder for the PLY files.")
    ],
    intrinsics: IntrinsicsOpt = None,
    color: Annotated[
        Path | None,
        typer.Option(
            "--color",
            help="Colour image (all frames) or folder of images (one per frame, name order), "
            "registered to the depth; resized to the depth's size [default: depth colours].",
        ),
    ] = None,
    key: KeyOpt = None,
    topic: TopicOpt = None,
    input_format: InFormatOpt = None,
    depth_scale: DepthScaleOpt = 1000.0,
    overwrite: OverwriteOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Write a coloured point cloud per frame: OUT/frame_000000.ply, ...

    Binary PLY, points in metres in the camera frame (x right, y down, z forward); pixels
    without depth are skipped.
    """
    from tqdm import tqdm

    from upsr.io import _core as io
    from upsr.io.pointcloud import color_for_depth, write_ply
    from upsr.io.registry import require

    require("plyfile", "writing PLY point clouds")
    read = _read_opts(key, topic, input_format, depth_scale)
    info = io.probe(input_path, key=key, fmt=read["fmt"], topic=topic)
    cam = _camera_for(input_path, info, intrinsics, read)
    if cam is None:
        raise InputError(
            f"{input_path}: no camera intrinsics in the file: give --intrinsics FX,FY,CX,CY"
        )
    colours = _colour_source(color, info.n_frames)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    names = [out / f"frame_{t:06d}.ply" for t in range(info.n_frames)]
    existing = [p for p in names if p.exists()]
    if existing and not overwrite:
        raise InputError(f"{existing[0]} already exists (use --overwrite to replace)")
    vmin = vmax = None
    points = 0
    with tqdm(total=info.n_frames, desc="export-ply", file=sys.stderr, disable=quiet) as bar:
        for t, depth in enumerate(io.iter_frames(input_path, **read)):
            src = colours[t]
            if src is None and vmin is None:
                vals = depth[depth > 0]
                lo, hi = np.percentile(vals, [1, 99]) if vals.size else (0.0, 1000.0)
                vmin, vmax = float(lo), float(max(hi, lo + 1.0))
            col = color_for_depth(
                depth, _read_colour(src) if src is not None else None, vmin_mm=vmin, vmax_mm=vmax
            )
            write_ply(names[t], depth, cam, col)
            points += int((depth > 0).sum())
            bar.update(1)
    typer.echo(f"upsr: export-ply: {info.n_frames} PLY file(s), {points} points -> {out}")


# ---------------------------------------------------------------------------------------------
# batch
# ---------------------------------------------------------------------------------------------
_BATCH_EPILOG = """\b
Examples:
  upsr batch rec1.npy rec2.bag frames/ --out results/x2 -r 2
  upsr batch data/*.npy --out out -r 4 --workers 2 --chunk-frames 50
  upsr batch data/*.bag --out out -r 2 --scheduler tcp://10.0.0.5:8786
"""


def batch(
    inputs: Annotated[
        list[Path], typer.Argument(metavar="INPUTS...", help="Recordings (any input format).")
    ],
    out: Annotated[
        Path,
        typer.Option("--out", "-o", show_default=False, help="Output folder (one file each)."),
    ],
    scale: Annotated[int, typer.Option("--scale", "-r", show_default=False, help="SR factor r.")],
    frames: Annotated[
        int | None,
        typer.Option(
            "--frames",
            "-n",
            show_default=False,
            help="Window length N [default: 9, or all the frames of a shorter recording].",
        ),
    ] = None,
    output_format: Annotated[
        BatchFormat,
        typer.Option("--format", "-f", case_sensitive=False, help="Output format."),
    ] = BatchFormat.npy,
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler",
            metavar="tcp://HOST:PORT",
            help="Run on this Dask distributed scheduler [default: local processes].",
        ),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option("--workers", "-w", help="Local worker processes [default: CPU cores]."),
    ] = None,
    chunk_frames: Annotated[
        int,
        typer.Option(
            "--chunk-frames",
            help="Output frames per chunk of a recording; 0: about T/workers (>= 4N).",
        ),
    ] = 0,
    intrinsics: IntrinsicsOpt = None,
    key: KeyOpt = None,
    topic: TopicOpt = None,
    input_format: InFormatOpt = None,
    depth_scale: DepthScaleOpt = 1000.0,
    no_deblur: Annotated[
        bool, typer.Option("--no-deblur", help="Skip deblurring (output the fused median).")
    ] = False,
    lam: Annotated[
        float | None,
        typer.Option("--lam", help=f"BTV weight lambda [default: {_DEFAULT_DEBLUR.lam:g}]."),
    ] = None,
    alpha: Annotated[
        float | None,
        typer.Option("--alpha", help=f"BTV decay alpha [default: {_DEFAULT_DEBLUR.alpha:g}]."),
    ] = None,
    btv_radius: Annotated[
        int | None,
        typer.Option(
            "--btv-radius", help=f"BTV half-window P [default: {_DEFAULT_DEBLUR.radius_px}]."
        ),
    ] = None,
    iterations: Annotated[
        int | None,
        typer.Option(
            "--iterations", help=f"Deblurring steps [default: {_DEFAULT_DEBLUR.iterations}]."
        ),
    ] = None,
    blur: Annotated[
        Blur | None, typer.Option("--blur", case_sensitive=False, help="Blur model B.")
    ] = None,
    flow: Annotated[
        Flow | None, typer.Option("--flow", case_sensitive=False, help="Optical-flow backend.")
    ] = None,
    flow_preset: Annotated[
        FlowPreset | None,
        typer.Option("--flow-preset", case_sensitive=False, help="DIS preset."),
    ] = None,
    flow_scale: Annotated[
        int | None,
        typer.Option("--flow-scale", min=1, help="Upsampling factor of the flow grid (≤ r)."),
    ] = None,
    refine_preset: Annotated[
        FlowPreset | None,
        typer.Option("--refine-preset", case_sensitive=False, help="DIS preset of eq. 19."),
    ] = None,
    speckle_px: Annotated[
        int | None,
        typer.Option("--speckle-px", min=0, help="Largest isolated outlier removed (px)."),
    ] = None,
    no_refine: Annotated[
        bool, typer.Option("--no-refine", help="Skip the eq. 19 re-estimation.")
    ] = False,
    keep_all_motion: Annotated[
        bool,
        typer.Option("--keep-all-motion", help="No spurious-motion suppression (see 'upsr run')."),
    ] = False,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Recompute outputs that exist [default: skip].")
    ] = False,
    quiet: QuietOpt = False,
) -> int:
    """Super-resolve many recordings (same options as 'upsr run'), resumably.

    Outputs OUT/<name>.npy (or --format) and OUT/<name>.npy.intrinsics.json when the
    intrinsics are known. Existing outputs are skipped (rerun after an interruption to
    resume). Long recordings are split into chunks overlapping by N-1 frames, processed in
    parallel with results identical to a single run. A failing recording is reported and the
    others go on; exit status 2 (bad input) or 1 (internal error) if any failed.
    """
    from upsr.apps.batch import run_batch

    cfg = config_from_options(
        scale,
        frames,
        lam=lam,
        alpha=alpha,
        btv_radius=btv_radius,
        iterations=iterations,
        blur=blur,
        flow=flow,
        flow_preset=flow_preset,
        flow_scale=flow_scale,
        refine_preset=refine_preset,
        speckle_px=speckle_px,
        no_deblur=no_deblur,
        no_refine=no_refine,
        keep_all_motion=keep_all_motion,
    )
    start = time.perf_counter()
    result = run_batch(
        inputs,
        out,
        cfg,
        key=key,
        topic=topic,
        input_format=_fmt(input_format),
        depth_scale=depth_scale,
        output_format=output_format.value,
        intrinsics=intrinsics,
        scheduler=scheduler,
        workers=workers,
        chunk_frames=chunk_frames,
        overwrite=overwrite,
        progress=not quiet,
        shrink_frames=frames is None,
    )
    counts = {s: sum(r.status == s for r in result.recordings) for s in ("done", "skipped")}
    failed = result.failed
    typer.echo(
        f"upsr batch: {counts['done']} done, {counts['skipped']} skipped (output exists), "
        f"{len(failed)} failed in {time.perf_counter() - start:.1f} s -> {out}"
    )
    for rec in failed:
        msg = " ".join(rec.error.split())
        if str(rec.input) not in msg:
            msg = f"{rec.input}: {msg}"
        print(f"upsr: error: {msg}", file=sys.stderr)
    return result.exit_code


def register(app: typer.Typer) -> None:
    """Add ``compare``, ``view``, ``export-ply`` and ``batch`` to the ``upsr`` app."""
    app.command("compare", epilog=_COMPARE_EPILOG, no_args_is_help=True)(compare)
    app.command(
        "view",
        epilog="\b\nExample:\n  upsr view out.npy --frame 4 -o view.png",
        no_args_is_help=True,
    )(view)
    app.command(
        "export-ply",
        epilog="\b\nExample:\n  upsr export-ply out.npy -o ply/ --intrinsics 1050,1050,639.5,479.5",
        no_args_is_help=True,
    )(export_ply)
    app.command("batch", epilog=_BATCH_EPILOG, no_args_is_help=True)(batch)
