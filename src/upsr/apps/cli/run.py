"""``upsr run``: super-resolve one depth video file or frame folder."""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import typer

from upsr.apps.cli.options import (
    DEFAULT_FRAMES,
    AlphaOpt,
    BlurOpt,
    BtvRadiusOpt,
    FlowOpt,
    FlowPresetOpt,
    FlowScaleOpt,
    FramesOpt,
    InFormatOpt,
    IterationsOpt,
    KeepAllMotionOpt,
    KeyOpt,
    LamOpt,
    NoDeblurOpt,
    NoRefineOpt,
    OutDepthScaleOpt,
    OutFormat,
    OutIntrinsicsOpt,
    QuietOpt,
    RecursiveOpt,
    RefinePresetOpt,
    ScaleOpt,
    SpecklePxOpt,
    TopicOpt,
    config_from_options,
    fmt,
)
from upsr.errors import InputError

__all__ = ["register", "run"]

_RUN_EPILOG = """\b
Input formats (by name; --input-format to force):
  .npy / .npz   one (T, h, w) array of depth in mm (any integer or float dtype)
  FOLDER        16-bit single-channel PNG frames, natural name order
                (raw value / depth-scale = metres)
  .tif/.tiff    TIFF, one frame per page, or a folder of TIFFs (raw / depth-scale = m)
  .exr          OpenEXR (channel Z/depth/...), or a folder of EXRs
  .bag          ROS 1 / RealSense bag; a ROS 2 bag folder (metadata.yaml): --topic
  .pgm          NYU raw Kinect disparity (--input-format pgm: plain 16-bit depth)
  tum, sun      --input-format for TUM (raw/5000 m) and SUN RGB-D PNGs
The intrinsics (--intrinsics, or from the bag) scaled by r go to OUTPUT.intrinsics.json.

\b
Examples:
  upsr run video.npy -o video_x4.npy -r 4
  upsr run frames/ -o frames_x2/ -r 2 -n 5 --depth-scale 5000    # TUM PNGs
  upsr run capture.npz --key depth -o out.npz -r 2 --no-deblur --flow-preset fast
  upsr run capture.bag --topic /camera/depth/image_rect_raw -o out.npy -r 2
  upsr run video.npy -o video_x2.npy -r 2 --recursive           # causal, latency 0
"""


InputArg = Annotated[
    Path,
    typer.Argument(
        metavar="INPUT",
        show_default=False,
        help="Low-res depth video: a .npy/.npz (T, h, w) array in mm, or a folder "
        "of 16-bit PNG depth frames.",
    ),
]
OutputOpt = Annotated[
    Path,
    typer.Option(
        "--output",
        "-o",
        show_default=False,
        help="Where to write the high-res video: .npy or .npz (float32 mm, key "
        "'depth') or a folder name (16-bit PNG frames). Missing parent folders "
        "are created.",
    ),
]
FormatOpt = Annotated[
    OutFormat | None,
    typer.Option(
        "--format",
        "-f",
        case_sensitive=False,
        help="Output format [default: from the output name].",
    ),
]
WorkersOpt = Annotated[
    int | None,
    typer.Option(
        "--workers",
        min=0,
        help="Threads that finish windows side by side (same output) [default: 2 on a "
        "machine with 2 or more cores; 0: one window at a time].",
    ),
]
RunOverwriteOpt = Annotated[bool, typer.Option("--overwrite", help="Replace OUTPUT if it exists.")]


def run(
    input_path: InputArg,
    output: OutputOpt,
    scale: ScaleOpt,
    frames: FramesOpt = None,
    key: KeyOpt = None,
    depth_scale: OutDepthScaleOpt = 1000.0,
    output_format: FormatOpt = None,
    input_format: InFormatOpt = None,
    topic: TopicOpt = None,
    intrinsics: OutIntrinsicsOpt = None,
    no_deblur: NoDeblurOpt = False,
    lam: LamOpt = None,
    alpha: AlphaOpt = None,
    btv_radius: BtvRadiusOpt = None,
    iterations: IterationsOpt = None,
    blur: BlurOpt = None,
    flow: FlowOpt = None,
    flow_preset: FlowPresetOpt = None,
    flow_scale: FlowScaleOpt = None,
    refine_preset: RefinePresetOpt = None,
    speckle_px: SpecklePxOpt = None,
    no_refine: NoRefineOpt = False,
    keep_all_motion: KeepAllMotionOpt = False,
    recursive: RecursiveOpt = False,
    workers: WorkersOpt = None,
    overwrite: RunOverwriteOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Super-resolve a depth video with UP-SR and write the result.

    Prints one summary line on stdout; the progress bar goes to stderr.
    """
    from upsr.apps._camera import input_camera
    from upsr.io import video as io
    from upsr.method.windowed import UPSR

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
        recursive=recursive,
    )
    most = max(64, 2 * (os.cpu_count() or 1))  # each holds 2 windows in flight
    if workers is not None and workers > most:
        raise InputError(f"--workers must be 0..{most}, got {workers}")
    in_fmt, out_fmt = fmt(input_format), fmt(output_format)
    info = io.probe(input_path, key=key, fmt=in_fmt, topic=topic)
    camera = input_camera(input_path, info, intrinsics, fmt=in_fmt, topic=topic)
    if not recursive:  # (the recursive state takes any video length)
        cfg = _fit_window(cfg, info.n_frames, input_path, explicit=frames is not None)
    io.check_output_path([input_path], output, overwrite, fmt=out_fmt)
    if frames is None and cfg.n_frames < DEFAULT_FRAMES and not recursive:
        typer.echo(
            f"upsr: note: the video has {info.n_frames} frame(s): N = {cfg.n_frames}", err=True
        )
    source = io.iter_frames(input_path, key=key, depth_scale=depth_scale, fmt=in_fmt, topic=topic)
    engine = UPSR(cfg.scale, cfg.n_frames, config=cfg, workers=workers)
    start = time.perf_counter()
    _write_video(
        engine.process(source),
        output,
        n_frames=info.n_frames,
        out_fmt=out_fmt,
        depth_scale=depth_scale,
        overwrite=overwrite,
        quiet=quiet,
    )
    elapsed = time.perf_counter() - start
    if camera is not None:
        from upsr.geometry.intrinsics import write_intrinsics

        write_intrinsics(
            io.intrinsics_path(output), camera.scaled(cfg.scale), source=camera, scale=cfg.scale
        )

    r = cfg.scale
    t_n, h, w = info.shape
    rate = t_n / elapsed if elapsed > 0 else float("inf")
    mode = ", recursive" if recursive else ""
    typer.echo(
        f"upsr: {t_n} frames {w}x{h} -> {w * r}x{h * r} (r={r}, N={cfg.n_frames}{mode}) in "
        f"{elapsed:.1f} s ({rate:.1f} frames/s) -> {output}"
    )


def _fit_window(cfg: Any, n_total: int, path: Path, *, explicit: bool) -> Any:
    """The config with N fitted to a video of ``n_total`` frames.

    The default N (not the user's ``--frames``) shrinks to a shorter video's length; an N
    larger than the video is an error.
    """
    if not explicit and n_total < cfg.n_frames:
        cfg = dataclasses.replace(cfg, n_frames=n_total)
    if cfg.n_frames > n_total:
        raise InputError(
            f"N={cfg.n_frames} > {n_total} frames in {path}: use --frames {n_total} or less"
        )
    return cfg


def _write_video(
    frames: Iterator[Any],
    output: Path,
    *,
    n_frames: int,
    out_fmt: str | None,
    depth_scale: float,
    overwrite: bool,
    quiet: bool,
) -> None:
    """Write the high-res ``frames`` to ``output`` (atomically), with a progress bar."""
    from tqdm import tqdm

    from upsr.io import video as io

    with (
        io.VideoWriter(
            output,
            n_frames=n_frames,
            fmt=out_fmt,
            depth_scale=depth_scale,
            overwrite=overwrite,
        ) as writer,
        tqdm(
            total=n_frames,
            desc="upsr",
            unit="frame",
            file=sys.stderr,
            disable=quiet,
            leave=False,
            dynamic_ncols=True,
        ) as bar,
    ):
        for frame in frames:
            writer.write(frame)
            bar.update(1)


def register(app: typer.Typer) -> None:
    """Add ``run`` to the ``upsr`` app."""
    app.command("run", epilog=_RUN_EPILOG, no_args_is_help=True)(run)
