"""``upsr live`` on a recording written by the RealSense SDK, played back as a camera."""

from __future__ import annotations

import ctypes.util
import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

import upsr
from tests.apps._util import assert_user_error, run_cli

DATA = Path(__file__).resolve().parents[1] / "data"
FIXTURE = DATA / "live_small.db3"


def _sdk_missing() -> str | None:
    if importlib.util.find_spec("pyrealsense2") is None:
        return "pyrealsense2 is not installed"
    if ctypes.util.find_library("usb-1.0") is None:
        return "libusb-1.0 is not installed"
    try:
        import pyrealsense2  # noqa: F401
    except ImportError as e:  # pragma: no cover
        return f"pyrealsense2 does not load: {e}"
    return None


needs_sdk = pytest.mark.skipif(_sdk_missing() is not None, reason=str(_sdk_missing()))


def _frames() -> np.ndarray:
    sys.path.insert(0, str(DATA))
    try:
        import make_live_small
    finally:
        sys.path.remove(str(DATA))
    return make_live_small.frames()


def test_fixture_is_small_and_made_by_its_script():
    assert FIXTURE.stat().st_size < 300_000
    assert (DATA / "make_live_small.py").is_file()


@needs_sdk
def test_live_on_a_recording_equals_run_recursive(tmp_path, capsys):
    out = tmp_path / "live.npy"
    preview = tmp_path / "preview.png"
    rc, stdout, err = run_cli(
        capsys, "live", FIXTURE, "--no-real-time", "-o", out, "-r", "2", "--preview", preview
    )
    assert rc == 0, err
    assert "12 frames 48x40 -> 96x80" in stdout and "0 dropped" in stdout
    assert "frames/s" in err and "latency" in err and "dropped" in err
    assert "upsr live: fused by the mean" in err  # the per-video choices, as run's
    assert preview.stat().st_size > 0
    frames = _frames()
    np.save(tmp_path / "in.npy", frames.astype(np.float32))
    ref = tmp_path / "run.npy"
    rc, stdout, err = run_cli(
        capsys, "run", tmp_path / "in.npy", "-o", ref, "-r", "2", "--recursive", "-q"
    )
    assert rc == 0, err
    assert "recursive" in stdout
    np.testing.assert_array_equal(np.load(out), np.load(ref))


@needs_sdk
def test_live_registers_by_the_cameras_motion_with_the_sdks_intrinsics(
    tmp_path, capsys, monkeypatch
):
    """--camera-motion depth takes the depth stream's intrinsics from the SDK (fx = fy = 40,
    the centre (23.5, 19.5) of the recording): the output equals ``upsr run --recursive
    --camera-motion depth`` given them (a still camera: the flow's registration)."""
    from upsr.method import recursive

    configs = []
    init = recursive.RecursiveUPSR.__init__

    def noting(self, *args, config=None, **kwargs):
        configs.append(config)
        init(self, *args, config=config, **kwargs)

    monkeypatch.setattr(recursive.RecursiveUPSR, "__init__", noting)
    out = tmp_path / "live.npy"
    rc, _, err = run_cli(
        capsys, "live", FIXTURE, "--no-real-time", "-o", out, "-r", "2", "-q",
        "--camera-motion", "depth",
    )  # fmt: skip
    assert rc == 0, err
    assert configs[0].camera_motion == "depth"
    assert configs[0].camera_intrinsics == pytest.approx((40.0, 40.0, 23.5, 19.5))
    np.save(tmp_path / "in.npy", _frames().astype(np.float32))
    ref = tmp_path / "run.npy"
    rc, _, err = run_cli(
        capsys, "run", tmp_path / "in.npy", "-o", ref, "-r", "2", "--recursive", "-q",
        "--camera-motion", "depth", "--intrinsics", "40,40,23.5,19.5",
    )  # fmt: skip
    assert rc == 0, err
    np.testing.assert_array_equal(np.load(out), np.load(ref))


@needs_sdk
def test_a_recording_not_in_real_time_loses_no_frame_behind_a_slow_first_frame():
    """(The first frame waits for the kernels to compile in a fresh checkout: a pipeline,
    which starts the playback in real time, lost a frame in 3 of 10 such runs.)"""
    import time

    from upsr.apps.cli.live import FrameSource

    expected = _frames()
    for _ in range(6):  # (the old race lost a frame in a third of the runs)
        source = FrameSource(FIXTURE, real_time=False)
        try:
            time.sleep(0.1)
            got = [mm for mm, *_ in source]
        finally:
            source.close()
        assert len(got) == len(expected) == 12
        np.testing.assert_allclose(np.stack(got), expected, atol=1e-3)
    assert source.dropped == 0 and source.received == 12


@needs_sdk
def test_live_in_real_time_drops_frames_rather_than_queueing_them(tmp_path, capsys):
    out = tmp_path / "live.npz"
    rc, stdout, err = run_cli(capsys, "live", FIXTURE, "-o", out, "-r", "2", "-q")
    assert rc == 0, err
    done = int(stdout.split("live: ")[1].split(" frames")[0])
    dropped = int(stdout.split(" dropped")[0].rsplit(" ", 1)[1])
    assert done >= 1 and done + dropped == 12
    assert np.load(out)["depth"].shape == (done, 80, 96)


@needs_sdk
def test_frames_a_real_time_playback_skips_before_the_first_count_as_dropped(tmp_path, capsys):
    """A recording written without pacing plays in real time all at once: the frames the SDK
    never gives, before the first one read too, count as dropped (it said "0 dropped" with
    1 of 12 frames processed)."""
    from upsr.research.synth.recording import write_realsense_recording

    rec = write_realsense_recording(tmp_path / "burst.db3", np.round(_frames()))
    out = tmp_path / "live.npy"
    rc, stdout, err = run_cli(capsys, "live", rec, "-o", out, "-r", "2", "-q")
    assert rc == 0, err
    done = int(stdout.split("live: ")[1].split(" frames")[0])
    dropped = int(stdout.split(" dropped")[0].rsplit(" ", 1)[1])
    assert done + dropped == len(_frames()) and np.load(out).shape[0] == done


def test_frames_the_camera_dropped_while_recording_are_not_dropped_by_upsr(tmp_path, capsys):
    """A recording whose frame numbers have gaps (10, 11, 13, 14, 20, ...: the camera dropped
    frames while recording) said "13 dropped" of 8 frames processed, with advice to keep up."""
    from upsr.research.synth.recording import write_realsense_recording

    frames = np.round(_frames()[:8])
    numbers = [10, 11, 13, 14, 20, 21, 22, 30]
    rec = write_realsense_recording(
        tmp_path / "gaps.db3", frames, real_time=True, frame_numbers=numbers
    )
    rc, stdout, err = run_cli(capsys, "live", rec, "-o", tmp_path / "o.npy", "-r", "2", "-q")
    assert rc == 0, err
    done = int(stdout.split("live: ")[1].split(" frames")[0])
    dropped = int(stdout.split(" dropped")[0].rsplit(" ", 1)[1])
    assert done + dropped == len(frames)


@needs_sdk
def test_a_recording_of_two_depth_streams_needs_stream(tmp_path, capsys):
    """Two depth streams: real time said "the RealSense SDK cannot play it: Couldn't resolve
    requests", --no-real-time took the first silently: both name the streams and --stream."""
    import time

    import pyrealsense2 as rs

    dev, profiles = rs.software_device(), []
    for k, (w, h) in enumerate(((16, 12), (20, 15))):
        sensor = dev.add_sensor(f"Depth {k}")
        sensor.add_read_only_option(rs.option.depth_units, 0.001)
        intr = rs.intrinsics()
        intr.width, intr.height, intr.fx, intr.fy, intr.ppx, intr.ppy = w, h, w, w, w / 2, h / 2
        vs = rs.video_stream()
        vs.type, vs.index, vs.uid, vs.width, vs.height = rs.stream.depth, 0, k, w, h
        vs.fps, vs.bpp, vs.fmt, vs.intrinsics = 30, 2, rs.format.z16, intr
        profiles.append((sensor, sensor.add_video_stream(vs), w, h))
    path = tmp_path / "two.db3"
    recorder, queue = rs.recorder(str(path), dev), rs.frame_queue(16)
    for sensor, profile, *_ in profiles:
        sensor.open(profile)
        sensor.start(queue)
    for t in range(3):
        for sensor, profile, w, h in profiles:
            f = rs.software_video_frame()
            f.pixels = np.full((h, w), 1500, np.uint16)
            f.stride, f.bpp, f.timestamp, f.frame_number = 2 * w, 2, 1000.0 + 33.3 * t, t + 1
            f.domain, f.profile = rs.timestamp_domain.system_time, profile.as_video_stream_profile()
            sensor.on_video_frame(f)
            time.sleep(0.01)
    for sensor, *_ in profiles:
        sensor.stop()
        sensor.close()
    del recorder
    for extra in ([], ["--no-real-time"]):
        rc, _, err = run_cli(capsys, "live", path, "-o", tmp_path / "o.npy", "-r", "2", *extra)
        assert rc == 2 and "several depth streams (offered: 16x12@30, 20x15@30)" in err, err
        assert "--stream WxH@FPS" in err and not (tmp_path / "o.npy").exists()


def test_the_summary_gives_the_median_latency():
    from upsr.apps.cli.live import latency_text

    assert latency_text([116.0, 80.0]) == "latency 98 ms median, 116 ms max"  # (it said 116)
    assert latency_text([5.0, 1.0, 3.0]) == "latency 3 ms median, 5 ms max"
    assert latency_text([]) == "latency 0 ms median, 0 ms max"


def test_a_stream_that_drops_frames_is_told_what_keeps_up():
    from upsr.apps.cli.live import DROP_HINT_SHARE, drop_hint

    assert drop_hint(90, 0, "medium") is None
    assert drop_hint(95, int(DROP_HINT_SHARE * 100), "medium") is None  # 5 of 100: no note
    note = drop_hint(84, 6, "medium")
    assert "6 of 90 frames dropped (7 %)" in note and "--flow-preset fast" in note
    assert "--flow-preset" not in drop_hint(84, 6, "fast")
    assert drop_hint(0, 0, "medium") is None


@needs_sdk
def test_live_bad_recording(tmp_path, capsys):
    rc, out, err = run_cli(
        capsys, "live", tmp_path / "none.db3", "-o", tmp_path / "o.npy", "-r", "2"
    )
    assert_user_error(rc, out, err, "no such recording")
    assert not (tmp_path / "o.npy").exists()
    (tmp_path / "dir.db3").mkdir()
    for odd in (tmp_path / "dir.db3", Path("/dev/null")):
        rc, out, err = run_cli(capsys, "live", odd, "-o", tmp_path / "o.npy", "-r", "2")
        assert_user_error(rc, out, err, "not a regular file")
    # a file the SDK cannot open: its name and the SDK's reason, the reason's end on the line
    (tmp_path / "text.db3").write_text("not a recording\n" * 20)
    rc, out, err = run_cli(capsys, "live", tmp_path / "text.db3", "-o", tmp_path / "o.npy",
                           "-r", "2")  # fmt: skip
    assert_user_error(rc, out, err, "text.db3: the RealSense SDK cannot play it")
    assert err.strip().endswith("file is not a database"), err


@needs_sdk
def test_live_at_close_range_equals_run_recursive(tmp_path, capsys):
    """A camera 40 cm away (the recording's scene at a fifth of its depth, written by the
    SDK): the depth thresholds are scaled to the scene in both commands alike."""
    from upsr.research.synth.recording import write_realsense_recording

    near = np.round(_frames() * 0.2)
    rec = write_realsense_recording(tmp_path / "near.db3", near, units_m=1e-4)
    out, ref = tmp_path / "live.npy", tmp_path / "run.npy"
    rc, _, err = run_cli(capsys, "live", rec, "--no-real-time", "-o", out, "-r", "2", "-q")
    assert rc == 0, err
    rc, _, err = run_cli(capsys, "run", rec, "-o", ref, "-r", "2", "--recursive", "-q")
    assert rc == 0, err
    np.testing.assert_array_equal(np.load(out), np.load(ref))
    assert not np.array_equal(  # (the scaled thresholds made a difference)
        np.load(out), upsr.super_resolve(near.astype(np.float32), 2, 9, mode="recursive",
                                         near_depth_mm=None)
    )  # fmt: skip


@needs_sdk
def test_live_in_tenths_of_a_mm_gives_the_frames_and_output_of_run(tmp_path, capsys):
    """A recording in 100 µm units (written by librealsense 2.59): the SDK's float32 unit
    (9.99999974738e-05 m) and the recording's text ("0.000100") give the same frames, so
    `upsr live` equals `upsr run --recursive` on the same file (the method's thresholds
    decided differently on 600.0 and 599.99994 mm: up to 836 mm apart on edge pixels of a
    256×192 recording)."""
    from upsr.apps.cli.live import FrameSource
    from upsr.io import read_video

    rec = Path(__file__).resolve().parents[2] / "io" / "data" / "realsense" / "rs259_100um.db3"
    source = FrameSource(rec, real_time=False)
    try:
        got = np.stack([mm for mm, *_ in source])
    finally:
        source.close()
    np.testing.assert_array_equal(got, read_video(rec))
    out, ref = tmp_path / "live.npy", tmp_path / "run.npy"
    rc, stdout, err = run_cli(capsys, "live", rec, "--no-real-time", "-o", out, "-r", "2", "-q")
    assert rc == 0, err
    assert "ms median" in stdout and "ms max" in stdout and "0 dropped" in stdout
    rc, _, err = run_cli(capsys, "run", rec, "-o", ref, "-r", "2", "--recursive", "-q")
    assert rc == 0, err
    np.testing.assert_array_equal(np.load(out), np.load(ref))


@needs_sdk
def test_live_loads_the_kernels_before_the_stream_starts(tmp_path, capsys, monkeypatch):
    """`upsr live` warms the engine up for the stream's shape (known from the SDK before it
    streams) and only then starts the source: a camera's first frames are not dropped while
    a new process loads its compiled kernels."""
    from upsr.apps.cli import live as live_cli
    from upsr.method import warmup

    events = []
    monkeypatch.setattr(
        warmup, "warm_up", lambda cfg, shape: events.append(("warm up", cfg.mode, shape))
    )
    start = live_cli.FrameSource.start

    def started(self):
        events.append(("start", self.received))
        return start(self)

    monkeypatch.setattr(live_cli.FrameSource, "start", started)
    rc, _, err = run_cli(
        capsys, "live", FIXTURE, "--no-real-time", "-o", tmp_path / "o.npy", "-r", "2", "-q"
    )
    assert rc == 0, err
    assert events[:2] == [("warm up", "recursive", (40, 48)), ("start", 0)]


@needs_sdk
def test_ctrl_c_ends_the_stream_and_keeps_what_was_processed(tmp_path, capsys, monkeypatch):
    """A camera has no end: Ctrl-C stops it, and the output holds the frames processed so far
    (the first five here), as `upsr run --recursive` gives them; exit status 0."""
    from upsr.apps.cli import live as live_cli

    frames = live_cli.FrameSource.__iter__

    def interrupted(self):
        for k, item in enumerate(frames(self)):
            if k == 5:
                raise KeyboardInterrupt
            yield item

    monkeypatch.setattr(live_cli.FrameSource, "__iter__", interrupted)
    out = tmp_path / "live.npy"
    rc, stdout, err = run_cli(capsys, "live", FIXTURE, "--no-real-time", "-o", out, "-r", "2", "-q")
    assert rc == 0, err
    assert "5 frames 48x40" in stdout and "stopped by Ctrl-C" in stdout
    np.save(tmp_path / "in.npy", _frames()[:5].astype(np.float32))
    ref = tmp_path / "run.npy"
    rc, _, err = run_cli(capsys, "run", tmp_path / "in.npy", "-o", ref, "-r", "2", "--recursive")
    assert rc == 0, err
    np.testing.assert_array_equal(np.load(out), np.load(ref))


@needs_sdk
def test_a_second_ctrl_c_while_the_frames_finish_discards_the_output(tmp_path, capsys, monkeypatch):
    """After the first Ctrl-C the processed frames are being written; a second one (a real
    SIGINT, delivered while the writer thread writes) discards them: exit 130, "no output
    written" and nothing on disk (it was an exception in native code that aborted the
    process and left the output behind)."""
    import os
    import signal

    from upsr.apps.cli import live as live_cli
    from upsr.io import video as io

    frames = live_cli.FrameSource.__iter__
    flags = []

    def interrupted(self):
        for k, item in enumerate(frames(self)):
            if k == 6:
                raise KeyboardInterrupt
            yield item

    def discards(abort):
        flags.append(abort)
        install(abort)

    def write(self, *args, **kwargs):
        written(self, *args, **kwargs)
        if flags and not flags[0].is_set():
            os.kill(os.getpid(), signal.SIGINT)  # (handled on the main thread)
            assert flags[0].wait(10)

    install, written = live_cli._second_interrupt_discards, io.VideoWriter.write
    monkeypatch.setattr(live_cli.FrameSource, "__iter__", interrupted)
    monkeypatch.setattr(live_cli, "_second_interrupt_discards", discards)
    monkeypatch.setattr(io.VideoWriter, "write", write)
    handler = signal.getsignal(signal.SIGINT)
    rc, _, err = run_cli(capsys, "live", FIXTURE, "--no-real-time", "-o", tmp_path / "o.npy",
                              "-r", "2", "-q")  # fmt: skip
    assert rc == 130 and "interrupted, no output written" in err, err
    assert flags and flags[0].is_set()
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGINT) is handler  # (restored)


@needs_sdk
@pytest.mark.parametrize("suffix", ["png", "exr"])
def test_a_single_file_output_is_refused_before_the_stream_unless_one_frame(
    tmp_path, capsys, suffix
):
    """A single .png or .exr file holds one frame: refused before the stream starts (it
    stopped at the second frame with its work lost, naming a temporary file), unless
    --max-frames 1."""
    if suffix == "exr":
        pytest.importorskip("OpenEXR")
    out = tmp_path / f"one.{suffix}"
    rc, stdout, err = run_cli(capsys, "live", FIXTURE, "--no-real-time", "-o", out, "-r", "2")
    assert_user_error(rc, stdout, err, f"one.{suffix}: a single .{suffix} file holds one frame")
    assert "--max-frames 1" in err
    assert not out.exists()
    rc, stdout, err = run_cli(capsys, "live", FIXTURE, "--no-real-time", "-o", out, "-r", "2",
                              "--max-frames", "1", "-q")  # fmt: skip
    assert rc == 0 and "1 frames" in stdout, err
    assert upsr.io.read_video(out).shape == (1, 80, 96)


@needs_sdk
def test_live_valid_range_as_run(tmp_path, capsys):
    """--valid-range 1500,5000 drops the recording's box (1.3 m) as `upsr run` does."""
    out, ref = tmp_path / "live.npy", tmp_path / "run.npy"
    common = ["-r", "2", "-q", "--valid-range", "1500,5000"]
    rc, _, err = run_cli(capsys, "live", FIXTURE, "--no-real-time", "-o", out, *common)
    assert rc == 0, err
    np.save(tmp_path / "in.npy", _frames().astype(np.float32))
    rc, _, err = run_cli(capsys, "run", tmp_path / "in.npy", "-o", ref, "--recursive", *common)
    assert rc == 0, err
    live = np.load(out)
    np.testing.assert_array_equal(live, np.load(ref))
    assert live.max() < 2500 and (live[:, 24:52, 12:32] == 0).any()  # (where the box was)


@needs_sdk
def test_live_output_depth_scale_sets_the_png_units_of_the_output(tmp_path, capsys):
    """--output-depth-scale is the output's: PNG frames in 0.2 mm with 5000, the same depths
    as mm PNGs (the recording's own units come from the SDK); no --depth-scale, which means
    the input's in `upsr run`."""
    import upsr.io as uio

    args = ["live", FIXTURE, "--no-real-time", "-r", "2", "-q"]
    rc, _, err = run_cli(capsys, *args, "-o", tmp_path / "mm")
    assert rc == 0, err
    out = tmp_path / "fine"
    rc, _, err = run_cli(capsys, *args, "-o", out, "--output-depth-scale", "5000")
    assert rc == 0, err
    fine = uio.read_video(out, depth_scale=5000.0)
    np.testing.assert_allclose(fine, uio.read_video(tmp_path / "mm"), atol=0.5)
    np.testing.assert_allclose(uio.read_video(out), 5.0 * fine, atol=0.01)  # read as mm
    rc, _, err = run_cli(capsys, *args, "-o", tmp_path / "old", "--depth-scale", "5000")
    assert rc == 2 and not (tmp_path / "old").exists()


@needs_sdk
def test_live_writes_a_ros2_bag_with_the_scaled_intrinsics_as_run_does(tmp_path, capsys):
    """A ROS 2 bag output (whose SQLite connection belongs to the thread that opened it: the
    frames finished on the engine's helper thread are written on the caller's) carries the
    SDK's intrinsics scaled by r, and so does OUTPUT.intrinsics.json, as `upsr run` writes
    them for the same recording."""
    from upsr.io import read_intrinsics, read_video

    bag, npy, ref = tmp_path / "bag", tmp_path / "live.npy", tmp_path / "run.npy"
    common = ["-r", "2", "-q"]
    live = ["live", FIXTURE, "--no-real-time", *common]
    rc, _, err = run_cli(capsys, *live, "-o", bag, "--format", "rosbag")
    assert rc == 0, err
    rc, _, err = run_cli(capsys, *live, "-o", npy)
    assert rc == 0, err
    rc, _, err = run_cli(capsys, "run", FIXTURE, "-o", ref, "--recursive", *common)
    assert rc == 0, err
    # (a ROS 2 depth image holds float32 metres: within 1e-3 mm)
    np.testing.assert_allclose(read_video(bag), np.load(ref), rtol=0, atol=1e-3)
    np.testing.assert_array_equal(np.load(npy), np.load(ref))
    want = read_intrinsics(ref)
    assert (want.fx, want.cx, want.width) == (80.0, 47.5, 96)
    assert read_intrinsics(bag) == want and read_intrinsics(npy) == want


@needs_sdk
def test_a_write_error_ends_live_with_one_line_and_no_output(tmp_path, capsys, monkeypatch):
    """The writer's thread fails on the third frame (a full disk, say): the stream stops,
    the error is one line, exit status 2, nothing is left behind."""
    from upsr.errors import InputError
    from upsr.io import video

    write = video.VideoWriter.write
    count = []

    def failing(self, frame, timestamp_ns=None):
        count.append(1)
        if len(count) == 3:
            raise InputError("disk full")
        return write(self, frame, timestamp_ns)

    monkeypatch.setattr(video.VideoWriter, "write", failing)
    out = tmp_path / "o.npy"
    rc, stdout, err = run_cli(capsys, "live", FIXTURE, "--no-real-time", "-o", out, "-r", "2", "-q")
    assert_user_error(rc, stdout, err, "disk full")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@needs_sdk
def test_live_refuses_work_that_would_not_fit_in_memory(tmp_path, capsys):
    """As `upsr run` does, before anything streams: one line, exit 2, nothing written."""
    out = tmp_path / "o.npy"
    rc, stdout, err = run_cli(
        capsys, "live", FIXTURE, "--no-real-time", "-o", out, "-r", "16", "--max-memory", "1M"
    )
    assert_user_error(rc, stdout, err, "needs ~")
    assert "of memory" in err and "--max-memory to override" in err
    assert not out.exists()


@needs_sdk
@pytest.mark.parametrize("real_time", [True, False])
def test_live_stream_option(tmp_path, capsys, real_time):
    """--stream WxH[@FPS] opens that depth stream (a camera's low-res, fast mode); a stream the
    recording does not have is one line naming the ones it has; a bad spelling too."""
    from upsr.apps.cli.live import parse_stream

    assert parse_stream("424x240@90") == (424, 240, 90) and parse_stream("48X40") == (48, 40, 0)
    timing = [] if real_time else ["--no-real-time"]
    out = tmp_path / "o.npy"
    for stream in ("48x40@30", "48x40"):
        rc, stdout, err = run_cli(capsys, "live", FIXTURE, *timing, "-o", out, "-r", "2", "-q",
                                  "--stream", stream, "--overwrite")  # fmt: skip
        assert rc == 0, err
        assert "48x40 -> 96x80" in stdout
    for stream, message in (
        ("64x48@30", "no depth stream 64x48@30 (offered: 48x40@30)"),
        ("48x40@60", "no depth stream 48x40@60 (offered: 48x40@30)"),
        ("abc", "--stream must be WxH or WxH@FPS"),
        ("0x5", "positive size"),
    ):
        bad = tmp_path / "bad.npy"
        rc, stdout, err = run_cli(capsys, "live", FIXTURE, *timing, "-o", bad, "-r", "2", "-q",
                                  "--stream", stream)  # fmt: skip
        assert_user_error(rc, stdout, err, message)
        assert not bad.exists()


@needs_sdk
def test_the_preview_never_writes_over_the_recording_or_into_the_output(tmp_path, capsys):
    """(A preview named as the recording replaced it with a picture.)"""
    import shutil

    rec = tmp_path / "rec.db3"
    shutil.copy(FIXTURE, rec)
    before = rec.read_bytes()
    for out, preview, message in (
        ("o.npy", "rec.db3", "must name a .png file"),
        ("o.npy", "o.npy", "must name a .png file"),
        ("frames", "frames/p.png", "would write into the output"),
    ):
        args = ["-o", tmp_path / out, "--preview", tmp_path / preview]
        rc, stdout, err = run_cli(capsys, "live", rec, "--no-real-time", "-r", "2", "-q", *args)
        assert_user_error(rc, stdout, err, message)
    assert rec.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.db3"]


@needs_sdk
def test_an_existing_preview_or_intrinsics_file_needs_overwrite(tmp_path, capsys):
    (tmp_path / "mine.png").write_text("my picture")
    out = tmp_path / "o.npy"
    rc, _, err = run_cli(capsys, "live", FIXTURE, "-o", out, "-r", "2", "--no-real-time",
                         "--preview", tmp_path / "mine.png", "-q")  # fmt: skip
    assert (
        rc == 2 and "already exists" in err and (tmp_path / "mine.png").read_text() == "my picture"
    )
    (tmp_path / "o.npy.intrinsics.json").write_text("notes")
    rc, _, err = run_cli(capsys, "live", FIXTURE, "-o", out, "-r", "2", "--no-real-time", "-q")
    assert rc == 2 and "o.npy.intrinsics.json already exists" in err and not out.exists()


@needs_sdk
def test_live_stamps_its_output_with_the_sdks_times_as_run_does(tmp_path, capsys):
    """Each output frame carries its SDK frame's time (a .npz's `timestamps`, a ROS 2 bag's
    stamps): the recording's times, as `upsr run` reads and writes them."""
    from upsr.io import read_timestamps

    want = read_timestamps(FIXTURE)
    assert want[1] == 33_333_333  # (the fixture's 30 frames/s)
    for name, fmt in (("live.npz", []), ("bag", ["--format", "rosbag"])):
        out = tmp_path / name
        rc, _, err = run_cli(capsys, "live", FIXTURE, "--no-real-time", "-o", out, "-r", "2",
                             "-q", *fmt)  # fmt: skip
        assert rc == 0, err
        np.testing.assert_array_equal(read_timestamps(out), want)
    ref = tmp_path / "run.npz"
    rc, _, err = run_cli(capsys, "run", FIXTURE, "-o", ref, "-r", "2", "--recursive", "-q")
    assert rc == 0, err
    np.testing.assert_array_equal(read_timestamps(ref), want)
    # a PNG folder holds no times: OUTPUT.intrinsics.json has them, as `upsr run` writes it
    sidecars = []
    for command in (["live", FIXTURE, "--no-real-time"], ["run", FIXTURE, "--recursive"]):
        out = tmp_path / f"{command[0]}_png"
        rc, _, err = run_cli(capsys, *command, "-o", out, "-r", "2", "-q")
        assert rc == 0, err
        sidecars.append(json.loads(upsr.io.intrinsics_path(out).read_text()))
    assert sidecars[0]["timestamps_ns"] == list(want) == sidecars[1]["timestamps_ns"]


@needs_sdk
def test_a_camera_clock_stepping_back_does_not_end_the_stream(tmp_path, capsys, monkeypatch):
    """The stream goes on, its output's times as the SDK gave them (upsr run keeps them so)."""
    from upsr.apps.cli import live as live_cli

    frames = live_cli.FrameSource.__iter__

    def stepping_back(self):
        for k, (mm, arrived, stamp) in enumerate(frames(self)):
            yield mm, arrived, stamp - (200_000_000 if k == 4 else 0)

    monkeypatch.setattr(live_cli.FrameSource, "__iter__", stepping_back)
    out = tmp_path / "o.npz"
    rc, _, err = run_cli(capsys, "live", FIXTURE, "--no-real-time", "-o", out, "-r", "2", "-q")
    assert rc == 0, err
    stamps = np.load(out)["timestamps"]
    assert len(stamps) == 12 and stamps[4] == stamps[3] - 200_000_000 + 33_333_333


@needs_sdk
def test_live_compands_a_far_kinect_recording_as_run_does(tmp_path, capsys):
    """A wall at 7 m through the Kinect model, written by the SDK: live says the knee and
    equals `upsr run --recursive`; --no-compand turns it off in both alike."""
    from upsr.research.synth.degradation import kinect
    from upsr.research.synth.recording import write_realsense_recording

    wall = np.round(kinect(np.full((6, 20, 24), 7000.0), np.random.default_rng(1)))
    rec = write_realsense_recording(tmp_path / "far.db3", wall, units_m=1e-3)
    outs = {}
    for extra in ((), ("--no-compand",)):
        out, ref = tmp_path / f"live{len(extra)}.npy", tmp_path / f"run{len(extra)}.npy"
        rc, _, err = run_cli(capsys, "live", rec, "--no-real-time", "-o", out, "-r", 2, *extra)
        assert rc == 0, err
        assert ("companded beyond 5.7" in err) == (not extra)
        rc, _, err = run_cli(capsys, "run", rec, "-o", ref, "-r", 2, "--recursive", "-q", *extra)
        assert rc == 0, err
        np.testing.assert_array_equal(np.load(out), np.load(ref))
        outs[extra] = np.load(out)
    assert not np.array_equal(outs[()], outs[("--no-compand",)])
