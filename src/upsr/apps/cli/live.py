"""``upsr live``: super-resolve a RealSense camera (or an SDK recording) frame by frame.

The frames come from the RealSense SDK (``pyrealsense2``, the optional extra
``upsr[realsense]``; it needs the system's libusb): a connected camera, or a ``.bag`` / ``.db3``
recording played back through the SDK exactly as a camera, through a queue of one frame
(:class:`upsr.apps._realsense.FrameSource`: frames that arrive while one is processed are
dropped and counted, never queued without bound; ``--no-real-time`` plays a recording as fast
as the processing allows, every frame, the same frames as ``upsr run --recursive``). Before the
stream starts (the SDK resolves its profile without streaming), the engine loads its compiled
kernels for the stream's size (:func:`upsr.method.warmup.warm_up`): in a new process the first
frame would otherwise take several frames' time while the camera's next frames are dropped.

Each frame is super-resolved at once by the recursive engine
(:class:`upsr.method.recursive.RecursiveUPSR`, latency 0 frames: its state is updated on this
thread, then the frame is finished on a helper thread while the next one arrives,
:meth:`~upsr.method.pipeline.TwoStagePipeline.push_async`) and written, in order, with
:class:`upsr.io.video.VideoWriter` (any output format of ``upsr run``, with the SDK's
intrinsics scaled by r) on a writer thread of its own. A status line on stderr shows the frames
processed, the rate, the latency (time from the frame's arrival to its output) and the dropped
frames, the summary the median and largest latency; ``--preview`` rewrites a side-by-side PNG
(low-res | bicubic | UP-SR, :func:`upsr.viz.pictures.comparison_frame`) every
``--preview-every`` frames.
Ctrl-C ends the stream as the end of a recording does.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import math
import os
import queue
import signal
import statistics
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import typer

from upsr.apps._realsense import FrameSource, parse_stream
from upsr.apps.cli.options import (
    CameraMotion,
    CameraMotionOpt,
    EdgeMmOpt,
    FlowPresetOpt,
    IterationsOpt,
    MaxMemoryOpt,
    NoCompandOpt,
    OutFormat,
    ScaleOpt,
    ValidRangeOpt,
    config_from_options,
    fmt,
)
from upsr.errors import InputError

__all__ = ["FrameSource", "live", "register"]

_LIVE_EPILOG = """\b
Examples:
  upsr live -o live_x2.npy -r 2 --preview preview.png        # the first RealSense camera
  upsr live capture.bag -o out.npy -r 2 --no-real-time       # a recording, every frame
  upsr live -o drive.npy -r 2 --camera-motion depth           # a camera driving forward
  upsr live -o low.npy -r 4 --stream 256x144@90               # a low-res, fast stream
"""

SourceArg = Annotated[
    Path | None,
    typer.Argument(
        metavar="[RECORDING]",
        show_default=False,
        help="A RealSense recording (.bag, or .db3 from SDK 2.56 on) played through the SDK as "
        "a camera [default: the first connected RealSense camera].",
    ),
]
LiveOutputOpt = Annotated[
    Path,
    typer.Option(
        "--output",
        "-o",
        show_default=False,
        help="Where to write the high-res video (any output format of 'upsr run').",
    ),
]
LiveFormatOpt = Annotated[
    OutFormat | None,
    typer.Option(
        "--format", "-f", case_sensitive=False, help="Output format [default: from the name]."
    ),
]
PreviewOpt = Annotated[
    Path | None,
    typer.Option(
        "--preview",
        metavar="PATH.png",
        help="Side-by-side PNG (low-res | bicubic | UP-SR, frames numbered from 0), rewritten "
        "while the video runs.",
    ),
]
PreviewEveryOpt = Annotated[
    int, typer.Option("--preview-every", min=1, help="Rewrite the preview every K frames.")
]
NoRealTimeOpt = Annotated[
    bool,
    typer.Option(
        "--no-real-time",
        help="Recording: play it as fast as the processing allows, every frame (no frame "
        "dropped; the output equals 'upsr run --recursive' on the same frames).",
    ),
]
StreamOpt = Annotated[
    str | None,
    typer.Option(
        "--stream",
        metavar="WxH[@FPS]",
        help="The depth stream to open, e.g. 424x240@90 (a low resolution at a high rate, "
        "which upsr then super-resolves) [default: the camera's default; a recording's "
        "depth stream].",
    ),
]
MaxFramesOpt = Annotated[
    int | None,
    typer.Option("--max-frames", min=1, help="Stop after this many processed frames."),
]


def _check_seconds(value: float | None) -> float | None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise typer.BadParameter(f"must be a finite number of seconds > 0, got {value}")
    return value


SecondsOpt = Annotated[
    float | None,
    typer.Option("--seconds", callback=_check_seconds, help="Stop after this many seconds."),
]
LiveOverwriteOpt = Annotated[bool, typer.Option("--overwrite", help="Replace OUTPUT if it exists.")]
#: (the camera's or recording's depth units come from the SDK: only the output's are chosen;
#: no ``--depth-scale``, which means the input's in ``upsr run``)
LiveDepthScaleOpt = Annotated[
    float,
    typer.Option(
        "--output-depth-scale",
        metavar="UNITS_PER_M",
        help="PNG/TIFF/EXR output: raw units per metre (1000 = mm, 1 = metres); .npy/.npz/"
        "bags: always mm/m. The camera's depth units are read from the SDK.",
    ),
]
LiveQuietOpt = Annotated[
    bool,
    typer.Option(
        "--quiet", "-q", help="No status line, notes or hints on stderr (the summary stays)."
    ),
]
#: (the recursive mode's N and flow grid, not the windowed mode's of ``upsr run``)
LiveFramesOpt = Annotated[
    int | None,
    typer.Option(
        "--frames",
        "-n",
        show_default=False,
        help="N: the most frames a pixel's state summarises (the recursive mode's memory; "
        "latency stays 0) [default: 9].",
    ),
]
LiveFlowScaleOpt = Annotated[
    int | None,
    typer.Option(
        "--flow-scale",
        min=1,
        help="Upsampling factor s <= r of the frames the flow is computed on [default: the "
        "smallest s >= 1 giving a flow grid >= 192 px wide]. Smaller: faster.",
    ),
]
LiveNoDeblurOpt = Annotated[
    bool,
    typer.Option("--no-deblur", help="Skip the deblurring step (output the fused state)."),
]


def live(
    output: LiveOutputOpt,
    scale: ScaleOpt,
    recording: SourceArg = None,
    frames: LiveFramesOpt = None,
    output_format: LiveFormatOpt = None,
    depth_scale: LiveDepthScaleOpt = 1000.0,
    no_deblur: LiveNoDeblurOpt = False,
    iterations: IterationsOpt = None,
    flow_preset: FlowPresetOpt = None,
    flow_scale: LiveFlowScaleOpt = None,
    preview: PreviewOpt = None,
    preview_every: PreviewEveryOpt = 10,
    no_real_time: NoRealTimeOpt = False,
    max_frames: MaxFramesOpt = None,
    seconds: SecondsOpt = None,
    camera_motion: CameraMotionOpt = CameraMotion.flow,
    stream: StreamOpt = None,
    valid_range: ValidRangeOpt = None,
    edge_mm: EdgeMmOpt = None,
    no_compand: NoCompandOpt = False,
    max_memory: MaxMemoryOpt = None,
    overwrite: LiveOverwriteOpt = False,
    quiet: LiveQuietOpt = False,
) -> None:
    """Super-resolve a RealSense camera or recording live (recursive mode, latency 0).

    Runs until the recording ends, --max-frames or --seconds, or Ctrl-C: the output then holds
    every frame processed so far (a second Ctrl-C while they finish writes nothing). Prints
    one summary line on stdout; the live status line goes to stderr.
    """
    from upsr.apps import _preflight as pre
    from upsr.apps._camera import camera_motion_config
    from upsr.geometry.camera import PinholeCamera
    from upsr.io import units
    from upsr.io import video as io
    from upsr.method.recursive import RecursiveUPSR
    from upsr.method.warmup import warm_up

    cfg = config_from_options(
        scale,
        frames,
        iterations=iterations,
        flow_preset=flow_preset,
        flow_scale=flow_scale,
        no_deblur=no_deblur,
        recursive=True,
        valid_range=valid_range,
        edge_mm=edge_mm,
        no_compand=no_compand,
    )
    out_fmt = fmt(output_format)
    io.check_output_path([] if recording is None else [recording], output, overwrite, fmt=out_fmt)
    resolved = io._output_format(output, out_fmt)
    units.check_output_capacity(output, 1, fmt=out_fmt, depth_scale=depth_scale)
    if resolved in ("exr", "png") and not io._folder_output(resolved, output) and max_frames != 1:
        # (before the stream: it would stop at its second frame, its work lost)
        raise InputError(
            f"{output.name}: a single .{resolved} file holds one frame: give --max-frames 1, "
            f"or write the stream to a folder (a name without suffix"
            f"{', --format exr' if resolved == 'exr' else ''})"
        )
    if preview is not None:
        _check_preview(preview, recording, output, overwrite)
    pre.check_sidecar(io.intrinsics_path(output), overwrite, [recording])
    mem = pre.memory_limit(max_memory)
    wanted = None if stream is None else parse_stream(stream)
    source = FrameSource(recording, real_time=not no_real_time, stream=wanted)
    stats: dict[str, Any] = {"done": 0, "latency_ms": [], "last_status": 0.0}
    start = time.perf_counter()
    try:
        if camera_motion is CameraMotion.depth:  # (the SDK's intrinsics of the depth stream)
            cfg = camera_motion_config(cfg, source.intrinsics)
        h, w = source.shape
        # (one frame's work: the stream's length is not known, its disk not checked)
        pre.check_run_resources(
            (1, h, w), cfg, workers=1, out_fmt=resolved, output=None, max_memory=mem
        )
        pre.kernel_note(quiet)
        if not quiet:
            sys.stderr.write(f"upsr live: loading the kernels for {w}x{h} frames ...")
            sys.stderr.flush()
        # before the stream starts: a new process's first frame would otherwise load them
        # while the camera's next frames are dropped (upsr.method.warmup)
        warm_up(cfg, source.shape)
        # each frame updates the state here, then is finished (deblurred) on a helper thread
        # while the next frame updates the state (RecursiveUPSR.push_async), and written
        # (and shown) on the writer's thread
        engine = RecursiveUPSR(config=cfg)
        r = cfg.scale
        camera = PinholeCamera(*source.intrinsics, width=w, height=h)
        source.start()
        start = time.perf_counter()
        _stream(source, engine, (output, out_fmt, depth_scale, overwrite, camera), stats, start,
                preview=preview, preview_every=preview_every, quiet=quiet,
                max_frames=max_frames, seconds=seconds)  # fmt: skip
    finally:
        source.close()
        if not quiet:
            sys.stderr.write("\n")
    end = time.perf_counter()
    # (the stream's rate up to its last output; closing the output, e.g. compressing a .npz,
    # is reported apart)
    elapsed = stats.get("last_output", end) - start
    closing = end - start - elapsed
    done = stats["done"]
    rate = done / elapsed if elapsed > 0 else float("inf")
    typer.echo(
        f"upsr live: {done} frames {w}x{h} -> {w * r}x{h * r} (r={r}, recursive) in "
        f"{elapsed:.1f} s ({rate:.1f} frames/s, {latency_text(stats['latency_ms'])}, "
        f"{source.dropped} dropped"
        + (f"; output closed in {closing:.1f} s more" if closing >= 0.5 else "")
        + f") -> {output}"
        + (" (stopped by Ctrl-C)" if stats.get("stopped") else "")
    )
    if not quiet:
        _advise(engine, done, source.dropped)


def _advise(engine: Any, done: int, dropped: int) -> None:
    """On stderr: the cheaper settings where frames were dropped (:func:`drop_hint`), and the
    per-video choices as ``upsr run --recursive`` says them."""
    hint = drop_hint(done, dropped, engine.config.flow_preset)
    if hint is not None:
        typer.echo(hint, err=True)
    if engine.statistics is not None:
        from upsr.apps.cli.run import choices_line

        typer.echo(f"upsr live: {choices_line(engine.statistics)}", err=True)


#: Share of the frames dropped from which :func:`drop_hint` names the cheaper settings.
DROP_HINT_SHARE = 0.05


def drop_hint(done: int, dropped: int, flow_preset: str) -> str | None:
    """A one-line note when more than :data:`DROP_HINT_SHARE` of the frames were dropped:
    what keeps up (``--flow-preset fast``: 90 of 90 frames at 320×240 → 640×480 where
    ``medium`` kept 84, README speed section; a smaller stream; a lower r); None otherwise."""
    total = done + dropped
    if total == 0 or dropped <= DROP_HINT_SHARE * total:
        return None
    faster = "" if flow_preset in ("fast", "ultrafast") else "--flow-preset fast, "
    return (
        f"upsr live: note: {dropped} of {total} frames dropped ({100 * dropped / total:.0f} %): "
        f"{faster}a smaller --stream or a lower --scale keeps up"
    )


def _stream(
    source: FrameSource,
    engine: Any,
    sink: tuple[Path, Any, float, bool, Any],
    stats: dict[str, Any],
    start: float,
    *,
    preview: Path | None,
    preview_every: int,
    quiet: bool,
    max_frames: int | None,
    seconds: float | None,
) -> None:
    """Super-resolve ``source``'s frames with ``engine`` into ``sink`` = (output, format,
    depth scale, overwrite, the input's camera: its scaled intrinsics go with the video and
    to ``OUTPUT.intrinsics.json`` as ``upsr run`` writes them) until it ends (or
    ``max_frames`` / ``seconds``); ``stats``: frames done, each one's latency (ms)."""
    from upsr.apps._camera import intrinsics_sidecar
    from upsr.io import video as io

    output, out_fmt, depth_scale, overwrite, camera = sink
    r = engine.config.scale

    @contextlib.contextmanager
    def opened() -> Iterator[Any]:
        with io.VideoWriter(
            output,
            fmt=out_fmt,
            depth_scale=depth_scale,
            overwrite=overwrite,
            camera=camera.scaled(r),
        ) as sink:
            yield sink
            # (at the end: with the SDK's times of the frames written, as `upsr run` gives)
            sidecar = intrinsics_sidecar(camera, r, writer.stamps)
            sink.add_sidecar(io.intrinsics_path(output), sidecar)

    def written(frame: Any, out: Any) -> None:  # (on the writer's thread)
        stats["done"] += 1
        done, now = stats["done"], time.perf_counter()
        stats["last_output"] = now
        if preview is not None and (done == 1 or done % preview_every == 0):
            _write_preview(preview, frame, out, r, done - 1)  # (frame numbers from 0)
        if not quiet and now - stats["last_status"] > 0.25:
            _status(done, now - start, stats["latency_ms"][done - 1], source.dropped)
            stats["last_status"] = now

    def emit(frame: Any, arrived: float, stamp: int, out: Any) -> None:  # (where it finished)
        stats["latency_ms"].append(1000.0 * (time.perf_counter() - arrived))
        writer.put((frame, out, stamp))

    writer = _Writer(opened, written)
    writer.start()
    submitted = 0
    complete = False
    futures: collections.deque[Any] = collections.deque()
    try:
        try:
            for frame, arrived, stamp in source:
                futures.append(
                    engine.push_async(frame, then=functools.partial(emit, frame, arrived, stamp))
                )
                while (
                    futures and futures[0].done()
                ):  # (a frame's error is in its future: raised here)
                    futures.popleft().result()
                submitted += 1
                if writer.error is not None or (
                    (max_frames is not None and submitted >= max_frames)
                    or (seconds is not None and time.perf_counter() - start >= seconds)
                ):
                    break
        except KeyboardInterrupt:
            # Ctrl-C ends a live stream, as the end of a recording does: the frames processed
            # so far are written; a second Ctrl-C, while they finish, discards the output (a
            # flag the writer reads between frames, not an exception inside the SDK's or the
            # writer's native code: the process aborted when it left them running)
            stats["stopped"] = True
            # (until the command returns: upsr.apps.cli.main restores SIGINT's handler)
            _second_interrupt_discards(writer.abort)
        finally:
            engine.wait()  # every frame handed to the writer before it closes
        for future in futures:
            future.result()
        complete = bool(stats["latency_ms"])
    finally:
        writer.finish(complete)
    if writer.abort.is_set() and not writer.completed:
        raise KeyboardInterrupt  # (the output was discarded: "interrupted, no output written")
    if not complete:
        raise InputError("no depth frame came from the RealSense source")


def _second_interrupt_discards(abort: threading.Event) -> None:
    """From now on SIGINT sets ``abort`` instead of raising (on the main thread only, where
    signals are handled)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, lambda signum, frame: abort.set())


class _Writer(threading.Thread):
    """The output opened, written and closed on a thread of its own: a ROS 2 bag's SQLite
    connection belongs to the thread that opened it, and neither the caller (which updates the
    state) nor the engine's helper (which finishes the frames) waits for the disk. At most
    :data:`WRITE_QUEUE` outputs wait: beyond, the helper waits, and the camera's frames are
    dropped at the source (never queued without bound)."""

    def __init__(self, opened: Any, written: Any) -> None:
        super().__init__(name="upsr-live-writer", daemon=True)
        self._opened, self._written = opened, written
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=WRITE_QUEUE)
        self.error: BaseException | None = None
        #: Set to discard the output (checked before each frame and before the output is
        #: closed); ``completed``: the output was closed, complete, before that.
        self.abort = threading.Event()
        self.completed = False
        #: The time (ns) of each frame written.
        self.stamps: list[int] = []

    def run(self) -> None:
        try:
            with self._opened() as writer:
                while (item := self._queue.get()) is not _CLOSE:
                    if item is _ABORT or self.abort.is_set():
                        raise _Aborted  # (the writer discards what it wrote)
                    frame, out, stamp = item
                    # the SDK's time of the frame, as recorded (a camera's clock may step
                    # back: as upsr run keeps it)
                    writer.write(out, timestamp_ns=stamp)
                    self.stamps.append(stamp)
                    self._written(frame, out)
                if self.abort.is_set():
                    raise _Aborted
            self.completed = True
        except _Aborted:
            pass
        except BaseException as e:  # (raised on the caller's thread by finish)
            self.error = e

    def put(self, item: Any) -> None:
        """Queue an output (or the end), waiting while the queue is full."""
        while self.is_alive():
            try:
                self._queue.put(item, timeout=0.2)
                return
            except queue.Full:
                continue

    def finish(self, complete: bool) -> None:
        """Close the output (``complete``) or discard it; raise the writer's error."""
        self.put(_CLOSE if complete else _ABORT)
        self.join()
        if self.error is not None:
            raise self.error


class _Aborted(Exception):
    pass


_ABORT = object()
_CLOSE = object()
#: Outputs that may wait for the writer (beyond: the engine's helper waits).
WRITE_QUEUE = 4


def _check_preview(preview: Path, recording: Path | None, output: Path, overwrite: bool) -> None:
    """The preview is a ``.png`` file apart from the recording and the output (a preview
    named as the recording replaced it with a picture), new unless ``--overwrite``."""
    from upsr.io.paths import check_apart_from_inputs

    if Path(preview).suffix.lower() != ".png" or Path(preview).is_dir():
        raise InputError(f"--preview must name a .png file, got {preview}")
    if recording is not None:
        check_apart_from_inputs(recording, preview, "--preview")
    out, where = Path(output).resolve(), Path(preview).resolve()
    if where == out or out in where.parents:  # (a picture among the output's frames)
        raise InputError(f"--preview {preview} would write into the output {output}")
    if os.path.lexists(preview) and not overwrite:
        raise InputError(f"--preview {preview} already exists (use --overwrite to replace it)")


def _status(done: int, elapsed: float, latency_ms: float, dropped: int) -> None:
    rate = done / elapsed if elapsed > 0 else 0.0
    sys.stderr.write(
        f"\rupsr live: {done} frames, {rate:5.1f} frames/s, latency {latency_ms:5.0f} ms, "
        f"{dropped} dropped "
    )
    sys.stderr.flush()


def latency_text(latencies_ms: list[float]) -> str:
    """``latency M ms median, X ms max`` of the frames' latencies (the median of an even
    count the mean of the middle two: of two frames it was the larger)."""
    lat = latencies_ms or [0.0]
    return f"latency {statistics.median(lat):.0f} ms median, {max(lat):.0f} ms max"


def _write_preview(path: Path, frame: Any, out: Any, scale: int, k: int) -> None:
    import numpy as np

    from upsr.viz.colormaps import write_png
    from upsr.viz.pictures import comparison_frame

    valid = frame[frame > 0]
    if valid.size == 0:
        return
    lo, hi = np.percentile(valid, [1, 99])
    picture = comparison_frame(
        frame, out, scale, vmin_mm=float(lo), vmax_mm=float(max(hi, lo + 1)), caption=f"frame {k}"
    )
    write_png(path, picture)


def register(app: typer.Typer) -> None:
    """Add ``live`` to the ``upsr`` app."""
    app.command("live", epilog=_LIVE_EPILOG)(live)
