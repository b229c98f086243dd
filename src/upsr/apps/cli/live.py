"""``upsr live``: super-resolve a RealSense camera (or an SDK recording) frame by frame.

The frames come from the RealSense SDK (``pyrealsense2``, the optional extra
``upsr[realsense]``; it needs the system's libusb): a connected camera, or a ``.bag`` / ``.db3``
recording played back through the SDK exactly as a camera (``enable_device_from_file``). Before
the stream starts (the SDK resolves its profile without streaming), the engine loads its
compiled kernels for the stream's size (:func:`upsr.method.warmup.warm_up`): in a new process
the first frame would otherwise take several frames' time while the camera's next frames are
dropped. A reader thread takes each frame from the SDK and hands it over through a queue of ONE
frame: a frame that arrives while the previous one is still being processed replaces it, and the
one replaced is counted as dropped (never queued without bound); gaps in the SDK's frame numbers
count as dropped too. ``--no-real-time`` plays a recording as fast as the processing allows (no
frame dropped: deterministic, the same frames as ``upsr run --recursive``): the recording's
depth sensor is opened directly, not through a pipeline, in non-real-time playback from the
start, and its frame callback waits for the queue, so the playback waits for the processing (a
pipeline starts in real time and, with a slow first frame, lost one).

Each frame is super-resolved at once by the recursive engine
(:class:`upsr.method.recursive.RecursiveUPSR`, latency 0 frames: its state is updated on this
thread, then the frame is finished on a helper thread while the next one arrives,
:meth:`~upsr.method.pipeline.TwoStagePipeline.push_async`) and written, in order, with
:class:`upsr.io.video.VideoWriter` (any output format of ``upsr run``, with the SDK's
intrinsics scaled by r) on a writer thread of its own. A status line on stderr
shows the frames processed, the rate, the latency (time from the frame's arrival to its output)
and the dropped frames, the summary the median and largest latency; ``--preview`` rewrites a
side-by-side PNG (input | output, :func:`upsr.viz.pictures.comparison_frame`) every
``--preview-every`` frames.
"""

from __future__ import annotations

import contextlib
import functools
import queue
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import typer

from upsr.apps.cli.options import (
    CameraMotion,
    CameraMotionOpt,
    FlowPresetOpt,
    FlowScaleOpt,
    FramesOpt,
    IterationsOpt,
    MaxMemoryOpt,
    NoDeblurOpt,
    OutDepthScaleOpt,
    OutFormat,
    QuietOpt,
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
        help="Side-by-side PNG (input | output), rewritten while the video runs.",
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
SecondsOpt = Annotated[
    float | None,
    typer.Option("--seconds", min=0.0, help="Stop after this many seconds."),
]
LiveOverwriteOpt = Annotated[bool, typer.Option("--overwrite", help="Replace OUTPUT if it exists.")]

_END = object()


class FrameSource:
    """Depth frames (mm, float32 (h, w)) from the RealSense SDK, through a queue of one.

    Made, it knows the depth stream's ``shape`` (h, w) and ``intrinsics`` (fx, fy, cx, cy)
    without streaming yet (the SDK resolves the profile); :meth:`start` starts it.

    Parameters
    ----------
    recording : path, optional
        A ``.bag`` / ``.db3`` file played back as a camera (no repeat); None: the first camera.
    real_time : bool
        Recording: play at the recorded rate (frames may be dropped) or, False, as fast as
        they are taken (none dropped).
    stream : (width, height, fps), optional
        The depth stream to open (fps 0: any rate); None: the camera's default, or the
        recording's depth stream.
    """

    def __init__(
        self,
        recording: Path | None,
        *,
        real_time: bool = True,
        stream: tuple[int, int, int] | None = None,
    ) -> None:
        try:
            import pyrealsense2 as rs
        except ImportError as e:  # pragma: no cover - depends on the machine
            raise InputError(
                "upsr live needs the RealSense SDK: pip install 'upsr[realsense]' "
                f"(and the system's libusb) ({e})"
            ) from e
        from upsr.io.rosbag import realsense_units_mm

        self._rs = rs
        self._units_mm = realsense_units_mm
        self.recording = recording
        self.real_time = real_time if recording is not None else True
        self.dropped = 0
        self.received = 0
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=1)
        self._stop = threading.Event()
        self._error: BaseException | None = None
        if recording is not None and not Path(recording).is_file():
            what = "not a regular file" if Path(recording).exists() else "no such recording"
            raise InputError(f"{recording}: {what}")
        self._pipe: Any = None
        self._cfg: Any = None
        self._sensor: Any = None
        self._profile: Any = None  # the sensor's depth profile (not in real time)
        self._playback: Any = None
        self._thread: threading.Thread | None = None
        self._busy = threading.Lock()  # held while the sensor's callback hands a frame over
        self._stream = stream
        try:
            if recording is not None and not self.real_time:
                profile = self._find_sensor(recording)
            else:
                profile = self._resolve_pipeline(recording)
        except RuntimeError as e:
            offered = self._offered(recording)
            if not offered:  # (no stream asked for, or no device: the SDK's own words)
                raise InputError(f"RealSense: {e}") from e
            where = recording if recording is not None else "RealSense camera"
            text = _stream_text(self._stream)  # type: ignore[arg-type]
            raise InputError(f"{where}: no depth stream {text}{offered}") from e
        self.shape = (profile.height(), profile.width())
        intr = profile.get_intrinsics()
        self.intrinsics = (intr.fx, intr.fy, intr.ppx, intr.ppy)

    def start(self) -> FrameSource:
        """Start the stream (a recording starts playing, a camera streaming) and its reader;
        returns ``self``. The shape and the intrinsics are known before (the engine can load
        its kernels for them first, :func:`upsr.method.warmup.warm_up`)."""
        if self._thread is not None:
            return self
        try:
            if self._sensor is not None:
                self._sensor.open(self._profile)
                self._sensor.start(self._on_frame)
                target = self._wait_for_end
            else:
                stream = self._start_pipeline()
                if (stream.height(), stream.width()) != self.shape:  # pragma: no cover
                    raise InputError(
                        f"RealSense: the depth stream started at {stream.width()}x"
                        f"{stream.height()}, not the resolved {self.shape[1]}x{self.shape[0]}"
                    )
                target = self._read
        except RuntimeError as e:
            raise InputError(f"RealSense: {e}") from e
        self._thread = threading.Thread(target=target, name="upsr-live-reader", daemon=True)
        self._thread.start()
        return self

    def _resolve_pipeline(self, recording: Path | None) -> Any:
        """A camera, or a recording in real time: the depth profile a pipeline will stream
        (resolved, not started: nothing plays yet)."""
        rs = self._rs
        cfg = rs.config()
        if recording is not None:
            cfg.enable_device_from_file(str(recording), repeat_playback=False)
        if self._stream is None:
            cfg.enable_stream(rs.stream.depth)
        else:
            w, h, fps = self._stream
            cfg.enable_stream(rs.stream.depth, w, h, rs.format.z16, fps)
        self._cfg = cfg
        self._pipe = rs.pipeline()
        profile = cfg.resolve(rs.pipeline_wrapper(self._pipe))
        return profile.get_stream(rs.stream.depth).as_video_stream_profile()

    def _start_pipeline(self) -> Any:
        """Start the resolved pipeline (read by :meth:`_read`); its depth profile."""
        profile = self._pipe.start(self._cfg)
        if self.recording is not None:
            self._playback = profile.get_device().as_playback()
            self._playback.set_real_time(self.real_time)
        return profile.get_stream(self._rs.stream.depth).as_video_stream_profile()

    def _find_sensor(self, recording: Path) -> Any:
        """A recording as fast as it is read: its depth sensor (opened by :meth:`start`),
        whose callback blocks."""
        rs = self._rs
        device = rs.context().load_device(str(recording))
        self._playback = device.as_playback()
        self._playback.set_real_time(False)  # before anything plays
        for sensor in device.query_sensors():
            for prof in sensor.get_stream_profiles():
                if prof.stream_type() == rs.stream.depth and self._wanted(prof):
                    self._sensor, self._profile = sensor, prof
                    return prof.as_video_stream_profile()
        what = "" if self._stream is None else " " + _stream_text(self._stream)
        raise InputError(f"{recording}: no depth stream{what}{self._offered(recording)}")

    def _wanted(self, profile: Any) -> bool:
        """Whether a depth profile is the ``stream`` asked for (any without one)."""
        if self._stream is None:
            return True
        w, h, fps = self._stream
        video = profile.as_video_stream_profile()
        return (video.width(), video.height()) == (w, h) and fps in (0, profile.fps())

    def _offered(self, recording: Path | None) -> str:
        """``" (offered: WxH@FPS, …)"``: the depth streams of the recording or of the first
        camera, where a ``stream`` was asked for ("" otherwise, or where none can be read)."""
        if self._stream is None:
            return ""
        rs = self._rs
        try:
            ctx = rs.context()
            device = ctx.load_device(str(recording)) if recording is not None else ctx.devices[0]
            offered = sorted(
                {
                    _stream_text((v.width(), v.height(), v.fps()))
                    for sensor in device.query_sensors()
                    for p in sensor.get_stream_profiles()
                    if p.stream_type() == rs.stream.depth
                    for v in [p.as_video_stream_profile()]
                }
            )
        except (RuntimeError, IndexError):
            return ""
        return f" (offered: {', '.join(offered)})" if offered else ""

    def _item(self, depth: Any) -> tuple[Any, float]:
        """(depth in mm, arrival time) of an SDK depth frame, counted as received."""
        import numpy as np

        mm = np.asanyarray(depth.get_data()).astype(np.float32)
        # (the unit as a recording read by `upsr run` gives it: the same frames)
        mm *= np.float32(self._units_mm(depth.get_units()))
        self.received += 1
        return mm, time.perf_counter()

    def _on_frame(self, frame: Any) -> None:
        """The sensor's callback (the playback's thread): hand the frame over, waiting for
        room in the queue (the playback waits with it)."""
        with self._busy:
            if self._stop.is_set():
                return
            item = self._item(frame.as_depth_frame())
            while not self._stop.is_set():
                try:
                    self._queue.put(item, timeout=0.2)
                    return
                except queue.Full:
                    continue

    def _wait_for_end(self) -> None:
        """Put the end marker once the playback has stopped and its last frame is handed
        over."""
        try:
            while not self._stop.is_set() and not self._finished():
                time.sleep(0.02)
            seen = -1
            while not self._stop.is_set():  # (no frame handed over for 0.1 s)
                with self._busy:
                    if self.received == seen:
                        break
                    seen = self.received
                time.sleep(0.1)
        finally:
            self._put_end()

    def _finished(self) -> bool:
        pb = self._playback
        return pb is not None and pb.current_status() == self._rs.playback_status.stopped

    def _read(self) -> None:
        """The pipeline's frames (a camera, or a recording in real time) through the queue of
        one: a newer frame replaces the waiting one, which counts as dropped."""
        last = None
        try:
            while not self._stop.is_set():
                ok, frames = self._pipe.try_wait_for_frames(200)
                if not ok:
                    if self._finished():
                        break
                    continue
                depth = frames.get_depth_frame()
                if not depth:
                    continue
                number = depth.get_frame_number()
                if last is not None and number > last + 1:
                    self.dropped += number - last - 1  # the SDK dropped these
                last = number
                item = self._item(depth)
                try:
                    self._queue.put_nowait(item)
                except queue.Full:
                    try:  # the waiting frame is stale: the newest replaces it
                        self._queue.get_nowait()
                        self.dropped += 1
                    except queue.Empty:
                        pass
                    self._queue.put_nowait(item)
        except BaseException as e:  # pragma: no cover - SDK errors
            self._error = e
        finally:
            self._put_end()

    def _put_end(self) -> None:
        while True:
            try:
                self._queue.put(_END, timeout=0.2)
                return
            except queue.Full:
                if self._stop.is_set():
                    return

    def __iter__(self) -> Iterator[tuple[Any, float]]:
        """(frame mm, arrival time) in order, until the recording ends or :meth:`close`
        (started first where :meth:`start` was not called)."""
        self.start()
        while True:
            item = self._queue.get()
            if item is _END:
                if self._error is not None:
                    raise InputError(f"RealSense: {self._error}")
                return
            yield item

    def close(self) -> None:
        """Stop reading and stop the SDK pipeline."""
        self._stop.set()
        while True:  # let the reader put its end marker
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break
        if self._thread is None:
            return  # (never started: nothing streams)
        self._thread.join(timeout=5.0)
        try:
            if self._pipe is not None:
                self._pipe.stop()
            if self._sensor is not None:
                self._sensor.stop()
                self._sensor.close()
        except RuntimeError:  # pragma: no cover
            pass


def _stream_text(stream: tuple[int, int, int]) -> str:
    w, h, fps = stream
    return f"{w}x{h}" + (f"@{fps}" if fps else "")


def parse_stream(text: str) -> tuple[int, int, int]:
    """``--stream WxH[@FPS]`` as (width, height, fps); fps 0: any rate."""
    size, _, rate = str(text).strip().lower().partition("@")
    try:
        w, h = (int(v) for v in size.split("x"))
        fps = int(rate) if rate else 0
    except ValueError:
        raise InputError(
            f"--stream must be WxH or WxH@FPS (e.g. 424x240@90), got {text!r}"
        ) from None
    if w < 1 or h < 1 or fps < 0:
        raise InputError(f"--stream needs a positive size and rate, got {text!r}")
    return w, h, fps


def live(
    output: LiveOutputOpt,
    scale: ScaleOpt,
    recording: SourceArg = None,
    frames: FramesOpt = None,
    output_format: LiveFormatOpt = None,
    depth_scale: OutDepthScaleOpt = 1000.0,
    no_deblur: NoDeblurOpt = False,
    iterations: IterationsOpt = None,
    flow_preset: FlowPresetOpt = None,
    flow_scale: FlowScaleOpt = None,
    preview: PreviewOpt = None,
    preview_every: PreviewEveryOpt = 10,
    no_real_time: NoRealTimeOpt = False,
    max_frames: MaxFramesOpt = None,
    seconds: SecondsOpt = None,
    camera_motion: CameraMotionOpt = CameraMotion.flow,
    stream: StreamOpt = None,
    valid_range: ValidRangeOpt = None,
    max_memory: MaxMemoryOpt = None,
    overwrite: LiveOverwriteOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Super-resolve a RealSense camera or recording live (recursive mode, latency 0).

    Runs until the recording ends, --max-frames or --seconds, or Ctrl-C: the output then holds
    every frame processed so far (a second Ctrl-C while they finish writes nothing). Prints
    one summary line on stdout; the live status line goes to stderr.
    """
    from upsr.apps import _preflight as pre
    from upsr.apps._camera import camera_motion_config
    from upsr.geometry.camera import PinholeCamera
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
    )
    out_fmt = fmt(output_format)
    io.check_output_path([] if recording is None else [recording], output, overwrite, fmt=out_fmt)
    if preview is not None:
        _check_preview(preview, recording, output)
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
        resolved = io._output_format(output, out_fmt)
        pre.check_run_resources(
            (1, h, w), cfg, workers=1, out_fmt=resolved, output=None, max_memory=mem
        )
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
    elapsed = time.perf_counter() - start
    done = stats["done"]
    rate = done / elapsed if elapsed > 0 else float("inf")
    lat = sorted(stats["latency_ms"])
    typer.echo(
        f"upsr live: {done} frames {w}x{h} -> {w * r}x{h * r} (r={r}, recursive) in "
        f"{elapsed:.1f} s ({rate:.1f} frames/s, latency {lat[len(lat) // 2]:.0f} ms median, "
        f"{lat[-1]:.0f} ms max, {source.dropped} dropped) -> {output}"
        + (" (stopped by Ctrl-C)" if stats.get("stopped") else "")
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
        ) as writer:
            writer.add_sidecar(io.intrinsics_path(output), intrinsics_sidecar(camera, r))
            yield writer

    def written(frame: Any, out: Any) -> None:  # (on the writer's thread)
        stats["done"] += 1
        done, now = stats["done"], time.perf_counter()
        if preview is not None and (done == 1 or done % preview_every == 0):
            _write_preview(preview, frame, out, r, done)
        if not quiet and now - stats["last_status"] > 0.25:
            _status(done, now - start, stats["latency_ms"][done - 1], source.dropped)
            stats["last_status"] = now

    def emit(frame: Any, arrived: float, out: Any) -> None:  # (where the frame finished)
        stats["latency_ms"].append(1000.0 * (time.perf_counter() - arrived))
        writer.put((frame, out))

    writer = _Writer(opened, written)
    writer.start()
    submitted = 0
    complete = False
    try:
        try:
            for frame, arrived in source:
                engine.push_async(frame, then=functools.partial(emit, frame, arrived))
                submitted += 1
                if writer.error is not None or (
                    (max_frames is not None and submitted >= max_frames)
                    or (seconds is not None and time.perf_counter() - start >= seconds)
                ):
                    break
        except KeyboardInterrupt:
            # Ctrl-C ends a live stream, as the end of a recording does: the frames processed
            # so far are written (a second Ctrl-C, while they finish, leaves no output)
            stats["stopped"] = True
        finally:
            engine.wait()  # every frame handed to the writer before it closes
        complete = bool(stats["latency_ms"])
    finally:
        writer.finish(complete)
    if not complete:
        raise InputError("no depth frame came from the RealSense source")


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

    def run(self) -> None:
        try:
            with self._opened() as writer:
                while (item := self._queue.get()) is not _END:
                    if item is _ABORT:
                        raise _Aborted  # (the writer discards what it wrote)
                    writer.write(item[1])
                    self._written(*item)
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
        self.put(_END if complete else _ABORT)
        self.join()
        if self.error is not None:
            raise self.error


class _Aborted(Exception):
    pass


_ABORT = object()
#: Outputs that may wait for the writer (beyond: the engine's helper waits).
WRITE_QUEUE = 4


def _check_preview(preview: Path, recording: Path | None, output: Path) -> None:
    """The preview is a ``.png`` file apart from the recording and the output (a preview
    named as the recording replaced it with a picture)."""
    if Path(preview).suffix.lower() != ".png" or Path(preview).is_dir():
        raise InputError(f"--preview must name a .png file, got {preview}")
    where = Path(preview).resolve()
    for other, what in ((recording, "the recording"), (output, "the output")):
        if other is not None and (
            where == Path(other).resolve() or Path(other).resolve() in where.parents
        ):
            raise InputError(f"--preview {preview} would write into {what} {other}")


def _status(done: int, elapsed: float, latency_ms: float, dropped: int) -> None:
    rate = done / elapsed if elapsed > 0 else 0.0
    sys.stderr.write(
        f"\rupsr live: {done} frames, {rate:5.1f} frames/s, latency {latency_ms:5.0f} ms, "
        f"{dropped} dropped "
    )
    sys.stderr.flush()


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
