"""``upsr batch``: many recordings, on local processes or a Dask cluster, resumable.

The command line only; the engine is :func:`upsr.apps.batch.run_batch`.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Annotated, Any

import typer

from upsr.apps.cli import options as opt
from upsr.errors import one_line

__all__ = ["batch", "register"]

_BATCH_EPILOG = """\b
Examples:
  upsr batch rec1.npy rec2.bag frames/ --out results/x2 -r 2
  upsr batch data/*.npy --out out -r 4 --workers 2 --chunk-frames 50
  upsr batch data/*.bag --out out -r 2 --scheduler tcp://10.0.0.5:8786
"""


@opt.with_method_options
def batch(
    inputs: Annotated[
        list[Path], typer.Argument(metavar="INPUTS...", help="Recordings (any input format).")
    ],
    out: Annotated[
        Path,
        typer.Option("--out", "-o", show_default=False, help="Output folder (one file each)."),
    ],
    scale: opt.ScaleOpt,
    frames: opt.WindowedFramesOpt = None,
    output_format: Annotated[
        opt.OutFormat,
        typer.Option("--format", "-f", case_sensitive=False, help="Output format."),
    ] = opt.OutFormat.npy,
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
    intrinsics: opt.OutIntrinsicsOpt = None,
    camera_motion: opt.CameraMotionOpt = opt.CameraMotion.flow,
    key: opt.KeyOpt = None,
    topic: opt.TopicOpt = None,
    input_format: opt.InFormatOpt = None,
    input_depth_scale: opt.InputDepthScaleOpt = None,
    depth_scale: opt.DepthScaleAliasOpt = None,
    output_depth_scale: opt.OutputDepthScaleOpt = None,
    keep_names: opt.KeepNamesOpt = True,
    sensor: opt.SensorOpt = opt.Sensor.default,
    strict_units: opt.StrictUnitsOpt = False,
    max_memory: opt.MaxMemoryOpt = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Recompute outputs that exist [default: skip].")
    ] = False,
    quiet: opt.QuietOpt = False,
    **method: Any,
) -> int:
    """Super-resolve many recordings (the windowed options of 'upsr run'), resumably.

    Outputs OUT/<name>.npy (or --format) and OUT/<name>.npy.intrinsics.json when the
    intrinsics are known. Existing outputs are skipped (rerun after an interruption to
    resume). Long recordings are split into chunks overlapping by N-1 frames, processed in
    parallel with results identical to a single run. A failing recording is reported and the
    others go on; exit status 2 (bad input) or 1 (internal error) if any failed.
    """
    cfg = opt.method_config(locals())  # first: locals() are the options
    from upsr.apps._preflight import kernel_note, memory_limit
    from upsr.apps.batch import run_batch
    from upsr.io.units import resolve_depth_scales

    mem = memory_limit(max_memory)
    s_in, s_out = resolve_depth_scales(depth_scale, input_depth_scale, output_depth_scale)
    scale_given = depth_scale is not None or input_depth_scale is not None
    kernel_note(quiet)
    start = time.perf_counter()
    result = run_batch(
        inputs,
        out,
        cfg,
        key=key,
        topic=topic,
        input_format=opt.fmt(input_format),
        depth_scale=s_in,
        output_depth_scale=s_out,
        max_memory=mem,
        keep_names=keep_names,
        sensor=sensor.value,
        strict_units=strict_units,
        scale_given=scale_given,
        output_format=output_format.value,
        intrinsics=intrinsics,
        camera_motion=camera_motion.value,
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
    here = os.getcwd().rstrip(os.sep) + os.sep
    for rec in failed:
        msg = " ".join(rec.error.split())
        if str(rec.input) not in msg:
            msg = f"{rec.input}: {msg}"
        # (paths under the current folder as relative ones: the line keeps its advice, which
        # the 200-character limit cut out of its middle after two absolute paths)
        print(one_line(f"upsr: error: {msg.replace(here, '')}"), file=sys.stderr)
    return result.exit_code


def register(app: typer.Typer) -> None:
    """Add ``batch`` to the ``upsr`` app."""
    app.command("batch", epilog=_BATCH_EPILOG, no_args_is_help=True)(batch)
