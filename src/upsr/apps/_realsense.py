"""Depth frames from the RealSense SDK for ``upsr live``: a camera, or a recording played back
through the SDK exactly as a camera.

:class:`FrameSource` resolves the depth stream's profile (its size, rate and intrinsics) without
streaming, so that the engine can be made and warmed up first (:mod:`upsr.method.warmup`), then
:meth:`FrameSource.start` starts it. A reader thread takes each frame from the SDK and hands it
over through a queue of ONE frame: a frame that arrives while the previous one is still being
processed replaces it, and the one replaced is counted as dropped (never queued without
bound); gaps in a camera's frame numbers count as dropped too (a recording's dropped frames are
those it holds that the SDK did not give: gaps in its frame numbers are frames the camera
dropped while recording). A recording not in real time is
played as fast as it is taken, every frame: its depth sensor is opened directly, in
non-real-time playback from the start, and its frame callback waits for the queue (a pipeline
starts in real time and, with a slow first frame, lost one). Needs the optional extra
``upsr[realsense]`` and the system's libusb.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from upsr.errors import InputError

__all__ = ["FrameSource", "parse_stream"]

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
        self.received = 0
        self._replaced = 0  # received, then replaced in the queue by a newer frame
        self._unseen = 0  # frames the SDK skipped (gaps in its frame numbers; a recording's
        # frames it never gave)
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
            self._several(recording)
            offered = self._offered(recording)
            if not offered and recording is not None:  # (the SDK's reason, without its request)
                reason = str(e).rsplit("Reason: ", 1)[-1]
                raise InputError(f"{recording}: the RealSense SDK cannot play it: {reason}") from e
            if not offered:  # (no stream asked for, or no device: the SDK's own words)
                raise InputError(f"RealSense: {e}") from e
            where = recording if recording is not None else "RealSense camera"
            text = _stream_text(self._stream)  # type: ignore[arg-type]
            raise InputError(f"{where}: no depth stream {text}{offered}") from e
        self.shape = (profile.height(), profile.width())
        # a recording's depth frames: those it holds and the source did not give count as
        # dropped (real-time playback skips frames before the first one read, too)
        self._in_recording = _depth_frames(recording, self.shape) if recording else None
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
        found = [
            (sensor, prof)
            for sensor in device.query_sensors()
            for prof in sensor.get_stream_profiles()
            if prof.stream_type() == rs.stream.depth and self._wanted(prof)
        ]
        if len(found) > 1:  # (as in real time, and upsr run)
            self._several(recording)
        if found:
            self._sensor, self._profile = found[0]
            return found[0][1].as_video_stream_profile()
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
        offered = self._depth_streams(recording) if self._stream is not None else []
        return f" (offered: {', '.join(offered)})" if offered else ""

    def _depth_streams(self, recording: Path | None) -> list[str]:
        """``WxH@FPS`` of each depth stream of the recording or of the first camera ([] where
        none can be read)."""
        rs = self._rs
        try:
            ctx = rs.context()
            device = ctx.load_device(str(recording)) if recording is not None else ctx.devices[0]
            return sorted(
                {
                    _stream_text((v.width(), v.height(), v.fps()))
                    for sensor in device.query_sensors()
                    for p in sensor.get_stream_profiles()
                    if p.stream_type() == rs.stream.depth
                    for v in [p.as_video_stream_profile()]
                }
            )
        except (RuntimeError, IndexError):
            return []

    def _several(self, recording: Path | None) -> None:
        """Refuse a source of several depth streams where none was asked for (``--stream``)."""
        streams = self._depth_streams(recording) if self._stream is None else []
        if len(streams) > 1:
            raise InputError(
                f"{recording or 'RealSense camera'}: several depth streams (offered: "
                f"{', '.join(streams)}): choose one with --stream WxH@FPS"
            )

    @property
    def dropped(self) -> int:
        """Frames not handed over: replaced in the queue by a newer one, skipped by the SDK
        (gaps in its frame numbers) and, once a recording has ended, those of its depth
        frames the SDK never gave (real-time playback skips frames before the first read)."""
        return self._replaced + self._unseen

    def _item(self, depth: Any) -> tuple[Any, float, int]:
        """(depth in mm, arrival time, the SDK's timestamp in ns) of an SDK depth frame,
        counted as received."""
        import numpy as np

        mm = np.asanyarray(depth.get_data()).astype(np.float32)
        # (the unit as a recording read by `upsr run` gives it: the same frames)
        mm *= np.float32(self._units_mm(depth.get_units()))
        self.received += 1
        return mm, time.perf_counter(), round(depth.get_timestamp() * 1e6)

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
                if last is not None and number > last + 1 and self._in_recording is None:
                    # the SDK dropped these (a recording's are counted at its end: gaps in
                    # its frame numbers are frames the camera dropped while recording)
                    self._unseen += number - last - 1
                last = number
                item = self._item(depth)
                try:
                    self._queue.put_nowait(item)
                except queue.Full:
                    try:  # the waiting frame is stale: the newest replaces it
                        self._queue.get_nowait()
                        self._replaced += 1
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

    def __iter__(self) -> Iterator[tuple[Any, float, int]]:
        """(frame mm, arrival time (``time.perf_counter``), the SDK's timestamp (ns)) in order,
        until the recording ends or :meth:`close` (started first where :meth:`start` was not
        called)."""
        self.start()
        while True:
            item = self._queue.get()
            if item is _END:
                if self._error is not None:
                    raise InputError(f"RealSense: {self._error}")
                if self._in_recording is not None and not self._stop.is_set():
                    self._unseen = max(0, self._in_recording - self.received)
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


def _depth_frames(recording: Path, shape: tuple[int, int]) -> int | None:
    """The number of depth frames of ``shape`` (h, w) in a recording (upsr's own reader of
    its depth topic), or None where it cannot tell."""
    from upsr import io

    try:
        info = io.probe(recording)
    except Exception:  # (the SDK plays what upsr may not read: no count)
        return None
    return info.n_frames if (info.height, info.width) == shape else None


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
