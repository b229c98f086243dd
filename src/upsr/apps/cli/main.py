"""The ``upsr`` command line.

``upsr run`` super-resolves a depth video file or PNG folder; ``upsr demo`` runs the
self-contained demonstration. Errors in what the user gave (bad files, bad options) print one
line ``upsr: error: …`` on stderr and exit with status 2; anything else is an internal error
(status 1, ``--debug`` shows the traceback); Ctrl-C exits with 130. No partial output is ever
left behind.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import signal
import sys
import threading
import time
import traceback
import warnings
from collections.abc import Iterator
from enum import Enum
from pathlib import Path
from typing import Annotated, Any

import typer

from upsr import __version__
from upsr.apps.cli.experiment import app as experiment_app
from upsr.apps.cli.tools import Blur, Flow, FlowPreset, InFormat, config_from_options
from upsr.apps.cli.tools import register as _register_io_commands
from upsr.errors import InputError
from upsr.method.config import DeblurConfig, UPSRConfig

try:  # typer >= 0.24 vendors click
    from typer._click.exceptions import ClickException, UsageError
except ImportError:  # pragma: no cover
    from click.exceptions import ClickException, UsageError  # type: ignore[no-redef]
try:
    from typer._click.exceptions import NoArgsIsHelpError
except ImportError:  # pragma: no cover
    try:
        from click.exceptions import NoArgsIsHelpError  # type: ignore[no-redef]
    except ImportError:

        class NoArgsIsHelpError(UsageError):  # type: ignore[no-redef]
            """Never raised by this click version."""


__all__ = ["app", "main"]

_DEFAULT_CFG = UPSRConfig()
_DEFAULT_DEBLUR = DeblurConfig()


class _State:
    debug = False
    terminated = False


class OutFormat(str, Enum):
    npy = "npy"
    npz = "npz"
    png = "png"
    tiff = "tiff"
    exr = "exr"


app = typer.Typer(
    name="upsr",
    help="UP-SR: super-resolution of dynamic depth videos (Al Ismaeil et al.). "
    "Depth is in millimetres; 0 or NaN means 'no measurement'.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
    rich_markup_mode=None,
)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"upsr {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_version_callback,
            is_eager=True,
            help="Print the version and exit.",
        ),
    ] = False,
    debug: Annotated[
        bool,
        typer.Option("--debug", help="Debug logging, and full tracebacks on errors."),
    ] = False,
) -> None:
    """UP-SR: super-resolution of dynamic depth videos (Al Ismaeil et al.).

    Depth is in millimetres; 0 or NaN means 'no measurement'.
    """
    _State.debug = _State.debug or debug
    if debug:
        logging.basicConfig(level=logging.DEBUG, format="upsr: %(name)s: %(message)s")


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
"""


@app.command(epilog=_RUN_EPILOG, no_args_is_help=True)
def run(
    input_path: Annotated[
        Path,
        typer.Argument(
            metavar="INPUT",
            show_default=False,
            help="Low-res depth video: a .npy/.npz (T, h, w) array in mm, or a folder "
            "of 16-bit PNG depth frames.",
        ),
    ],
    output: Annotated[
        Path,
        typer.Option(
            "--output",
            "-o",
            show_default=False,
            help="Where to write the high-res video: .npy or .npz (float32 mm, key "
            "'depth') or a folder name (16-bit PNG frames). Missing parent folders "
            "are created.",
        ),
    ],
    scale: Annotated[
        int,
        typer.Option(
            "--scale",
            "-r",
            show_default=False,
            help="Super-resolution factor r (integer >= 1): output frames are (r*h) x (r*w).",
        ),
    ],
    frames: Annotated[
        int | None,
        typer.Option(
            "--frames",
            "-n",
            help="Window length N: frames fused per output frame (1 <= N <= number of frames) "
            "[default: 9, or all the frames of a shorter video].",
            show_default=False,
        ),
    ] = None,
    key: Annotated[
        str | None,
        typer.Option("--key", help="Array to read from a .npz input [default: the first]."),
    ] = None,
    depth_scale: Annotated[
        float,
        typer.Option(
            "--depth-scale",
            help="PNG input and output: raw units per metre (1000 = mm, TUM: 5000). "
            ".npy/.npz always hold mm.",
        ),
    ] = 1000.0,
    output_format: Annotated[
        OutFormat | None,
        typer.Option(
            "--format",
            "-f",
            case_sensitive=False,
            help="Output format [default: from the output name].",
        ),
    ] = None,
    input_format: Annotated[
        InFormat | None,
        typer.Option(
            "--input-format",
            case_sensitive=False,
            help="Input format [default: from the input name].",
        ),
    ] = None,
    topic: Annotated[
        str | None,
        typer.Option("--topic", help="ROS bag: the depth image topic [default: the only one]."),
    ] = None,
    intrinsics: Annotated[
        str | None,
        typer.Option(
            "--intrinsics",
            metavar="FX,FY,CX,CY",
            help="Input camera intrinsics (px) [default: from the file, if it has them]; "
            "scaled by r and written to OUTPUT.intrinsics.json.",
        ),
    ] = None,
    no_deblur: Annotated[
        bool,
        typer.Option("--no-deblur", help="Skip the deblurring step (output the fused median)."),
    ] = False,
    lam: Annotated[
        float | None,
        typer.Option(
            "--lam", help=f"Deblurring: BTV weight lambda >= 0 [default: {_DEFAULT_DEBLUR.lam:g}]."
        ),
    ] = None,
    alpha: Annotated[
        float | None,
        typer.Option(
            "--alpha",
            help=f"Deblurring: BTV decay alpha in (0, 1] [default: {_DEFAULT_DEBLUR.alpha:g}].",
        ),
    ] = None,
    btv_radius: Annotated[
        int | None,
        typer.Option(
            "--btv-radius",
            help=f"Deblurring: BTV half-window P >= 1 (high-res px) "
            f"[default: {_DEFAULT_DEBLUR.radius_px}].",
        ),
    ] = None,
    iterations: Annotated[
        int | None,
        typer.Option(
            "--iterations",
            help=f"Deblurring: number of steepest-descent steps >= 0 "
            f"[default: {_DEFAULT_DEBLUR.iterations}].",
        ),
    ] = None,
    blur: Annotated[
        Blur | None,
        typer.Option(
            "--blur",
            case_sensitive=False,
            help=f"Deblurring: blur model B [default: {_DEFAULT_DEBLUR.blur}].",
        ),
    ] = None,
    flow: Annotated[
        Flow | None,
        typer.Option(
            "--flow",
            case_sensitive=False,
            help=f"Optical-flow backend [default: {_DEFAULT_CFG.flow}].",
        ),
    ] = None,
    flow_preset: Annotated[
        FlowPreset | None,
        typer.Option(
            "--flow-preset",
            case_sensitive=False,
            help=f"DIS flow speed/accuracy preset [default: {_DEFAULT_CFG.flow_preset}].",
        ),
    ] = None,
    flow_scale: Annotated[
        int | None,
        typer.Option(
            "--flow-scale",
            min=1,
            help="Upsampling factor s <= r of the frames the flow is computed on [default: the "
            "smallest s >= 2 giving a flow grid >= 192 px wide]. Smaller: faster.",
        ),
    ] = None,
    refine_preset: Annotated[
        FlowPreset | None,
        typer.Option(
            "--refine-preset",
            case_sensitive=False,
            help="DIS preset of the eq. 19 residual flows [default: ultrafast on flow grids "
            ">= 192 px wide, else --flow-preset].",
        ),
    ] = None,
    speckle_px: Annotated[
        int | None,
        typer.Option(
            "--speckle-px",
            min=0,
            help="Isolated regions of at most this many output px with no neighbour within "
            "100 mm (noise outliers) become 0 = unknown [default: r*r; 0 keeps them].",
        ),
    ] = None,
    no_refine: Annotated[
        bool,
        typer.Option(
            "--no-refine",
            help="Skip the re-estimation of each motion against the "
            "registered neighbour (paper eq. 19): faster, less accurate.",
        ),
    ] = False,
    keep_all_motion: Annotated[
        bool,
        typer.Option(
            "--keep-all-motion",
            help="Keep the flow where zero motion explains the depth as well (no "
            "spurious-motion suppression): better for smooth bodies drifting sideways, worse "
            "on static backgrounds.",
        ),
    ] = False,
    workers: Annotated[
        int | None,
        typer.Option(
            "--workers",
            min=0,
            help="Threads that finish windows side by side (same output) [default: 2 on a "
            "machine with 2 or more cores; 0: one window at a time].",
        ),
    ] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace OUTPUT if it exists.")
    ] = False,
    quiet: Annotated[
        bool, typer.Option("--quiet", "-q", help="No progress bar on stderr.")
    ] = False,
) -> None:
    """Super-resolve a depth video with UP-SR and write the result.

    Prints one summary line on stdout; the progress bar goes to stderr.
    """
    from tqdm import tqdm

    from upsr.io import _core as io
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
    )
    in_fmt = input_format.value if input_format is not None else None
    out_fmt = output_format.value if output_format is not None else None
    info = io.probe(input_path, key=key, fmt=in_fmt, topic=topic)
    camera = _input_camera(input_path, info, intrinsics, in_fmt, topic)
    shortened = frames is None and info.n_frames < cfg.n_frames
    if shortened:  # the default N, not the user's: a shorter video uses all its frames
        cfg = dataclasses.replace(cfg, n_frames=info.n_frames)
    if cfg.n_frames > info.n_frames:
        raise InputError(
            f"N={cfg.n_frames} > {info.n_frames} frames in {input_path}: use "
            f"--frames {info.n_frames} or less"
        )
    io.check_output_path([input_path], output, overwrite, fmt=out_fmt)
    if shortened:
        typer.echo(
            f"upsr: note: the video has {info.n_frames} frame(s): N = {cfg.n_frames}", err=True
        )
    source = io.iter_frames(input_path, key=key, depth_scale=depth_scale, fmt=in_fmt, topic=topic)
    engine = UPSR(cfg.scale, cfg.n_frames, config=cfg, workers=workers)

    start = time.perf_counter()
    with (
        io.VideoWriter(
            output,
            n_frames=info.n_frames,
            fmt=out_fmt,
            depth_scale=depth_scale,
            overwrite=overwrite,
        ) as writer,
        tqdm(
            total=info.n_frames,
            desc="upsr",
            unit="frame",
            file=sys.stderr,
            disable=quiet,
            leave=False,
            dynamic_ncols=True,
        ) as bar,
    ):
        for frame in engine.process(source):
            writer.write(frame)
            bar.update(1)
    elapsed = time.perf_counter() - start
    if camera is not None:
        from upsr.geometry.intrinsics import write_intrinsics

        write_intrinsics(
            io.intrinsics_path(output), camera.scaled(cfg.scale), source=camera, scale=cfg.scale
        )

    r = cfg.scale
    t_n, h, w = info.shape
    rate = t_n / elapsed if elapsed > 0 else float("inf")
    typer.echo(
        f"upsr: {t_n} frames {w}x{h} -> {w * r}x{h * r} (r={r}, N={cfg.n_frames}) in "
        f"{elapsed:.1f} s ({rate:.1f} frames/s) -> {output}"
    )


@app.command(epilog="\b\nExample:\n  upsr demo --out results/demo --seed 1")
def demo(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Folder for the demo's videos, figures and metrics.")
    ] = Path("results/demo"),
    seed: Annotated[
        int, typer.Option("--seed", help="Random seed of the synthetic scene and noise.")
    ] = 0,
    quiet: Annotated[
        bool, typer.Option("--quiet", "-q", help="No progress bar on stderr.")
    ] = False,
) -> None:
    """Run the built-in demo: a synthetic moving scene, UP-SR vs baselines, metrics table."""
    from upsr.apps import demo as demo_module

    result = demo_module.run_demo(out, seed=seed, progress=not quiet)
    typer.echo(demo_module.format_metrics_table(result))
    files = result.get("files") if isinstance(result, dict) else None
    if isinstance(files, dict) and files:
        typer.echo(f"upsr: demo results written to {', '.join(map(str, files.values()))}")
    else:
        typer.echo(f"upsr: demo results written to {out}")


@app.command(epilog="\b\nExample:\n  upsr analyze --out results/analysis --sigma 20 --trials 50000")
def analyze(
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            "-o",
            help="Folder for analysis_vs_n.csv/.png and analysis_vs_sigma.csv/.png "
            "(created if needed; those files are replaced).",
        ),
    ] = Path("results/analysis"),
    sigma: Annotated[
        float, typer.Option("--sigma", help="Noise std (mm) of the sweep over N, > 0.")
    ] = 30.0,
    max_frames: Annotated[
        int, typer.Option("--max-frames", help="Largest number of frames N, 1..1000.")
    ] = 25,
    trials: Annotated[
        int, typer.Option("--trials", help="Monte-Carlo medians per point, 1..10^7.")
    ] = 20_000,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the Monte-Carlo draws, >= 0.")] = 0,
) -> None:
    """Statistical analysis (paper §6): variance of the median fusion, theory vs Monte-Carlo.

    Exact variance of the median of N Laplace samples, the Cramér–Rao bound and a
    Monte-Carlo estimate, vs N = 1..max-frames (at --sigma) and vs sigma = 0..100 mm (N = 9).
    """
    from upsr.research import analysis

    result = analysis.run_analysis(
        out, sigma=sigma, max_frames=max_frames, trials=trials, seed=seed
    )
    typer.echo(analysis.format_analysis_table(result))
    typer.echo(f"upsr: analysis written to {', '.join(result['files'].values())}")


app.add_typer(experiment_app, name="experiment")
_register_io_commands(app)


def _input_camera(
    path: Path, info: Any, intrinsics: str | None, fmt: str | None, topic: str | None
) -> Any:
    """--intrinsics, else the intrinsics the input carries (None if unknown)."""
    from upsr.geometry.intrinsics import parse_intrinsics
    from upsr.io import _core as io

    if intrinsics is not None:
        return parse_intrinsics(intrinsics, info.width, info.height)
    cam = io.read_intrinsics(path, fmt=fmt, topic=topic)
    return cam if cam is not None and cam.shape == (info.height, info.width) else None


# -------------------------------------------------------------------------------------------------
# entry point
# -------------------------------------------------------------------------------------------------
_USER_ERRORS = (
    InputError,
    FileNotFoundError,
    PermissionError,
    IsADirectoryError,
    NotADirectoryError,
    FileExistsError,
)


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def _print_error(message: str) -> None:
    print(f"upsr: error: {_one_line(message)}", file=sys.stderr, flush=True)


@contextlib.contextmanager
def _cli_environment() -> Iterator[None]:
    """Warnings as one ``upsr: warning:`` line; SIGTERM unwinds like Ctrl-C (cleanup runs)."""

    def show(
        message: Any, category: Any, filename: Any, lineno: Any, file: Any = None, line: Any = None
    ) -> None:
        print(f"upsr: warning: {_one_line(message)}", file=sys.stderr, flush=True)

    def on_sigterm(signum: int, frame: Any) -> None:
        _State.terminated = True
        raise KeyboardInterrupt

    old_term = None
    main_thread = threading.current_thread() is threading.main_thread()
    with warnings.catch_warnings():
        warnings.showwarning = show
        if main_thread:
            old_term = signal.signal(signal.SIGTERM, on_sigterm)
        try:
            yield
        finally:
            if main_thread:
                signal.signal(signal.SIGTERM, old_term)


def main(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); return the exit status."""
    args = list(sys.argv[1:] if argv is None else argv)
    _State.debug = "--debug" in args
    _State.terminated = False
    command = typer.main.get_command(app)
    try:
        with _cli_environment():
            rv = command.main(args=args, prog_name="upsr", standalone_mode=False)
    except NoArgsIsHelpError as e:
        typer.echo(e.ctx.get_help() if e.ctx is not None else str(e))
        return 0
    except UsageError as e:
        hint = f" (see '{e.ctx.command_path} --help')" if e.ctx is not None else ""
        _print_error(e.format_message() + hint)
        return 2
    except ClickException as e:
        _print_error(e.format_message())
        return 2
    except (typer.Abort, KeyboardInterrupt):
        return _interrupted()
    except _USER_ERRORS as e:
        if _State.debug:
            traceback.print_exc()
        if isinstance(e, OSError) and e.strerror and e.filename:
            _print_error(f"{e.filename}: {e.strerror}")
        else:
            _print_error(str(e))
        return 2
    except Exception as e:
        if _State.debug:
            traceback.print_exc()
        print(
            f"upsr: internal error: {type(e).__name__}: {_one_line(e)} "
            f"(rerun with --debug for a traceback)",
            file=sys.stderr,
            flush=True,
        )
        return 1
    if rv == 130:  # click turned a KeyboardInterrupt into Exit(130); the output was cleaned up
        return _interrupted()
    return rv if isinstance(rv, int) else 0


def _interrupted() -> int:
    if _State.terminated:
        print("upsr: terminated (SIGTERM), no output written", file=sys.stderr)
        return 143
    print("upsr: interrupted, no output written", file=sys.stderr)
    return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
