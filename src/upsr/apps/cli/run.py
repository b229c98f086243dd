"""``upsr run``: super-resolve one depth video file or frame folder."""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import math
import sys
import time
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import typer

from upsr.apps.cli.options import (
    DEFAULT_FRAMES,
    CameraMotion,
    CameraMotionOpt,
    DepthScaleAliasOpt,
    FramesOpt,
    InFormatOpt,
    InputDepthScaleOpt,
    KeepNamesOpt,
    KeyOpt,
    MaxMemoryOpt,
    OutFormat,
    OutIntrinsicsOpt,
    OutputDepthScaleOpt,
    QuietOpt,
    RecursiveOpt,
    ScaleOpt,
    Sensor,
    SensorOpt,
    StrictUnitsOpt,
    TopicOpt,
    fmt,
    method_config,
    with_method_options,
)
from upsr.errors import InputError

__all__ = ["choices_line", "register", "run"]

_RUN_EPILOG = """\b
Input formats (by name; --input-format to force):
  .npy / .npz   one (T, h, w) array of depth (any integer or float dtype)
  FOLDER        16-bit single-channel PNG frames, natural name order
  .tif/.tiff    TIFF, one frame per page, or a folder of TIFFs
  .exr          OpenEXR (channel Z/depth/...), or a folder of EXRs
  .bag          ROS 1 / RealSense bag; a ROS 2 bag folder (metadata.yaml): --topic
  .pgm          NYU raw Kinect disparity (--input-format pgm: plain 16-bit depth)
  tum, sun      --input-format for TUM (raw/5000 m) and SUN RGB-D PNGs
Units: raw value / --input-depth-scale = metres (default 1000: mm; 1: metres) for
.npy/.npz, PNG, TIFF, EXR and PGM; bags, nyu, tum and sun carry their own units.
The intrinsics (--intrinsics, or from the bag) scaled by r go to OUTPUT.intrinsics.json
(with the frame names and timestamps); --color writes the colour on the output grid to
OUTPUT.color/. Output formats: .npy, .npz, .tif, .exr or .png (one frame), a folder of
PNGs (or EXRs: --format exr), a ROS 2 bag folder (--format rosbag).

\b
Examples:
  upsr run video.npy -o video_x4.npy -r 4
  upsr run frames/ -o frames_x2/ -r 2 -n 5 --input-depth-scale 5000   # TUM PNGs
  upsr run frames/ -o x2.tif -r 2 --input-depth-scale 1 --output-depth-scale 1  # metres
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
        "machine with 2 or more cores; 0: one window at a time]. With --recursive, 1 or "
        "more: each frame is finished on a helper thread while the next one updates the "
        "state (same output).",
    ),
]
RunOverwriteOpt = Annotated[bool, typer.Option("--overwrite", help="Replace OUTPUT if it exists.")]
ColorOpt = Annotated[
    Path | None,
    typer.Option(
        "--color",
        metavar="PATH",
        help="Colour image, or folder of one image per frame, registered to the depth: "
        "resampled to the output grid and written to OUTPUT.color/ (PNG), for RGB-D tools "
        "such as Open3D.",
    ),
]


@with_method_options
def run(
    input_path: InputArg,
    output: OutputOpt,
    scale: ScaleOpt,
    frames: FramesOpt = None,
    key: KeyOpt = None,
    input_depth_scale: InputDepthScaleOpt = None,
    depth_scale: DepthScaleAliasOpt = None,
    output_depth_scale: OutputDepthScaleOpt = None,
    sensor: SensorOpt = Sensor.default,
    strict_units: StrictUnitsOpt = False,
    output_format: FormatOpt = None,
    input_format: InFormatOpt = None,
    topic: TopicOpt = None,
    intrinsics: OutIntrinsicsOpt = None,
    recursive: RecursiveOpt = False,
    camera_motion: CameraMotionOpt = CameraMotion.flow,
    keep_names: KeepNamesOpt = True,
    color: ColorOpt = None,
    workers: WorkersOpt = None,
    max_memory: MaxMemoryOpt = None,
    overwrite: RunOverwriteOpt = False,
    quiet: QuietOpt = False,
    **method: Any,
) -> None:
    """Super-resolve a depth video with UP-SR and write the result.

    Prints one summary line on stdout; the progress bar goes to stderr.
    """
    cfg = method_config(locals())  # first: locals() are the options
    from upsr.apps import _preflight as pre
    from upsr.apps._camera import camera_motion_config, input_camera, intrinsics_sidecar
    from upsr.io import identity, units
    from upsr.io import video as io
    from upsr.method.windowed import UPSR

    if workers is not None and workers > pre.max_workers():
        raise InputError(f"--workers must be 0..{pre.max_workers()}, got {workers}")
    mem = pre.memory_limit(max_memory)
    s_in, s_out = units.resolve_depth_scales(depth_scale, input_depth_scale, output_depth_scale)
    in_fmt, out_fmt = fmt(input_format), fmt(output_format)
    scale_given = depth_scale is not None or input_depth_scale is not None
    pre.check_scale_applies([input_path], in_fmt, scale_given, topic, s_in)
    info = io.probe(input_path, key=key, fmt=in_fmt, topic=topic)
    camera = input_camera(input_path, info, intrinsics, fmt=in_fmt, topic=topic)
    if camera_motion is CameraMotion.depth:
        cfg = camera_motion_config(cfg, camera)
    if not recursive:  # (the recursive state takes any video length)
        cfg = _fit_window(cfg, info.n_frames, input_path, explicit=frames is not None)
    io.check_output_path([input_path], output, overwrite, fmt=out_fmt)
    resolved_out = io._output_format(output, out_fmt)
    color_dest = _check_color(color, input_path, output, info.n_frames, overwrite)
    workers_now = pre.engine_workers(workers)
    pre.check_run_resources(info.shape, cfg, workers=workers_now, out_fmt=resolved_out,
                            output=output, max_memory=mem)  # fmt: skip
    if frames is None and cfg.n_frames < DEFAULT_FRAMES and not recursive and not quiet:
        typer.echo(f"upsr: note: the video has {info.n_frames} frame(s): N = {cfg.n_frames}",
                   err=True)  # fmt: skip
    names = identity.read_frame_names(input_path, fmt=in_fmt)
    stamps = identity.read_timestamps(input_path, fmt=in_fmt, topic=topic, key=key)
    back = identity.first_step_back(stamps)
    if back is not None:
        warnings.warn(f"{input_path.name}: the timestamps go back in time at frame {back} (a "
                      "camera clock reset?): kept as recorded", stacklevel=1)  # fmt: skip
    source = io.iter_frames(input_path, key=key, depth_scale=s_in, fmt=in_fmt, topic=topic)
    with contextlib.closing(source):
        read = pre.frames_until_depth(source)
        pre.check_first_frame(
            input_path,
            read[-1],
            output,
            info.n_frames,
            in_fmt=io._input_format(input_path, in_fmt),
            out_fmt=resolved_out,
            units_options=(sensor.value, strict_units),
            scale_given=scale_given,
            scales=(s_in, s_out),
        )
        engine = UPSR(cfg.scale, cfg.n_frames, config=cfg, workers=workers)
        pre.kernel_note(quiet)
        out_cam = None if camera is None else camera.scaled(cfg.scale)
        sidecar = intrinsics_sidecar(camera, cfg.scale, stamps, names)
        if sidecar is not None:
            pre.check_sidecar(io.intrinsics_path(output), overwrite, [input_path, intrinsics])
        start = time.perf_counter()
        _write_video(
            engine.process(itertools.chain(read, source)),
            output,
            n_frames=info.n_frames,
            out_fmt=out_fmt,
            depth_scale=s_out,
            overwrite=overwrite,
            quiet=quiet,
            meta={
                "frame_names": names if keep_names else None,
                "timestamps_ns": stamps,
                "camera": out_cam,
            },
            sidecar=sidecar,
            color=None
            if color_dest is None
            else (color, color_dest, names if keep_names else None),
        )
    _summary(info.shape, cfg, time.perf_counter() - start, output)
    stats = engine.statistics  # (of this video)
    if stats is not None and not quiet:
        typer.echo(f"upsr: {choices_line(stats)}", err=True)


def _summary(shape: tuple[int, int, int], cfg: Any, elapsed: float, output: Path) -> None:
    """The one summary line on stdout."""
    r = cfg.scale
    t_n, h, w = shape
    rate = t_n / elapsed if elapsed > 0 else float("inf")
    mode = ", recursive" if cfg.mode == "recursive" else ""
    typer.echo(
        f"upsr: {t_n} frames {w}x{h} -> {w * r}x{h * r} (r={r}, N={cfg.n_frames}{mode}) in "
        f"{elapsed:.1f} s ({rate:.1f} frames/s) -> {output}"
    )


def choices_line(stats: Any) -> str:
    """The per-video choices of ``fusion_estimator``, the trust, the mixed-pixel test and the
    scale of the depth thresholds, in one line (``upsr.method.statistics.VideoStatistics``)."""
    profile = stats.trust_noise_profile
    if profile is not None:
        noise = f"noise σ(z) = {profile[0]:.1f} mm·(z/1 m)^{profile[1]:.2f}"
    else:
        noise = f"trust noise {stats.trust_noise_mm:.1f} mm"
        if stats.reach_noise_mm < stats.trust_noise_mm:  # (the reach, the radial offsets)
            noise += f", sample noise {stats.reach_noise_mm:.1f} mm"
    mixed = "mixed pixels removed" if stats.remove_mixed else "no mixed pixels"
    line = f"fused by the {stats.estimator}, {noise}, {mixed}"
    if stats.depth_scale < 1:
        line += f", depth thresholds x{stats.depth_scale:.2f} (a near scene)"
    if math.isfinite(stats.knee_mm):
        line += f", disparity levels: depth companded beyond {stats.knee_mm / 1000:.2f} m"
    return line


def _check_color(
    color: Path | None, input_path: Path, output: Path, n_frames: int, overwrite: bool
) -> Path | None:
    """Where ``--color`` goes (``OUTPUT.color``), checked before any processing; None: none."""
    if color is None:
        return None
    from upsr.io import video as io
    from upsr.io.color import color_files

    files = color_files(color)
    if color.is_dir() and len(files) != n_frames:
        raise InputError(
            f"--color {color}: {len(files)} colour image(s) for {n_frames} depth frame(s): "
            f"give one image per frame (or one image file)"
        )
    dest = output.with_name(output.name.rstrip("/") + ".color")
    io.check_output_path([input_path, color], dest, overwrite, fmt="png")
    return dest


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
    meta: dict[str, Any] | None = None,
    sidecar: str | None = None,
    color: tuple[Path, Path, list[str] | None] | None = None,
) -> None:
    """Write the high-res ``frames`` to ``output`` (atomically), with a progress bar.

    ``meta``: frame names, timestamps, camera (:class:`~upsr.io.VideoWriter`); ``sidecar``:
    the text of ``OUTPUT.intrinsics.json``, published with the video; ``color``: (source,
    destination, frame names) of ``--color``, written once every frame is, before the video is
    published (and removed again if that fails).
    """
    from tqdm import tqdm

    from upsr.io import video as io

    color_written: Path | None = None
    try:
        with (
            io.VideoWriter(
                output,
                n_frames=n_frames,
                fmt=out_fmt,
                depth_scale=depth_scale,
                overwrite=overwrite,
                **(meta or {}),
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
            if sidecar is not None:
                writer.add_sidecar(io.intrinsics_path(output), sidecar)
            shape = None
            for frame in frames:
                writer.write(frame)
                shape = frame.shape
                bar.update(1)
            if color is not None and shape is not None:
                color_written = _write_color(color, shape, n_frames, overwrite)
    except BaseException:
        if color_written is not None:
            from upsr._atomic import remove

            remove(color_written)
        raise


def _write_color(
    color: tuple[Path, Path, list[str] | None],
    shape: tuple[int, int],
    n_frames: int,
    overwrite: bool,
) -> Path:
    """``--color`` resampled to ``shape``, named like the depth frames (one image per frame)."""
    from upsr.io.color import color_files, write_color

    src, dest, names = color
    per_frame = len(color_files(src)) == n_frames
    if per_frame and names is None:
        names = [f"{t:06d}" for t in range(n_frames)]
    return write_color(
        src,
        dest,
        shape,
        n_frames=n_frames if src.is_dir() else None,
        frame_names=names if per_frame else None,
        overwrite=overwrite,
    )


def register(app: typer.Typer) -> None:
    """Add ``run`` to the ``upsr`` app."""
    app.command("run", epilog=_RUN_EPILOG, no_args_is_help=True)(run)
