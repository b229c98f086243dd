"""Recordings of real tools: librealsense .bag / .db3, image_transport compressed depth, and
the ROS 2 bags upsr writes (issue 15).

The RealSense files of ``data/realsense`` were written by librealsense itself (2.56: ROS 1
``.bag``; 2.59: ``.db3`` without metadata.yaml) through ``data/make_realsense_fixtures.py``,
which also stored what the SDK's own playback returns (``NAME.sdk.npz``). pyrealsense2 is not
needed to read them; when it is installed, a live playback is compared too.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import upsr.io as uio
from upsr.errors import InputError
from upsr.geometry.camera import PinholeCamera
from upsr.io._rosmsg import CompressedMsg, decode_compressed_depth, parse_image, rvl_decode

from .bagtools import encode_compressed_depth, rvl_encode

pytest.importorskip("rosbags")

DATA = Path(__file__).parent / "data" / "realsense"
RECORDINGS = ["rs256_1mm.bag", "rs256_100um.bag", "rs259_1mm.db3", "rs259_100um.db3"]


def _sdk(name: str) -> dict[str, np.ndarray]:
    with np.load(DATA / f"{name}.sdk.npz") as z:
        return {k: z[k] for k in z.files}


@pytest.mark.parametrize("name", RECORDINGS)
def test_realsense_recording_equals_sdk_playback(name: str) -> None:
    path = DATA / name
    assert path.stat().st_size < 200_000
    ref = _sdk(name)
    info = uio.probe(path)
    assert info.format == "rosbag" and info.shape == ref["depth_mm"].shape
    depth = uio.read_video(path)
    np.testing.assert_allclose(depth, ref["depth_mm"], rtol=0, atol=1e-3)
    cam = uio.read_intrinsics(path)
    fx, fy, cx, cy, w, h = ref["intrinsics"]
    assert (cam.width, cam.height) == (int(w), int(h))
    np.testing.assert_allclose([cam.fx, cam.fy, cam.cx, cam.cy], [fx, fy, cx, cy], atol=1e-6)
    stamps = uio.read_timestamps(path)
    np.testing.assert_allclose(stamps / 1e6, ref["timestamps_ms"], rtol=0, atol=1e-3)


def test_depth_units_are_applied() -> None:
    """100 µm units: the same scene in mm as at 1 mm (not 10x too large)."""
    for kind in ("rs256", "rs259"):
        a = uio.read_video(DATA / f"{kind}_1mm{'.bag' if kind == 'rs256' else '.db3'}")
        b = uio.read_video(DATA / f"{kind}_100um{'.bag' if kind == 'rs256' else '.db3'}")
        both = (a > 0) & (b > 0)
        assert np.abs(a[both] - b[both]).max() <= 0.5 + 1e-3


def test_realsense_units_as_the_camera_was_set() -> None:
    """The Depth Units a float32 holds (the SDK, a .bag) read as the decimal a .db3 stores."""
    from upsr.io.rosbag import realsense_units_mm

    for units_m, mm in ((1e-4, 0.1), (1e-3, 1.0), (1.25e-4, 0.125), (2.5e-4, 0.25)):
        assert realsense_units_mm(float(np.float32(units_m))) == mm
        assert realsense_units_mm(units_m) == mm
    for bad in (0.0, -1e-3, 1.5, float("nan"), float("inf")):
        with pytest.raises(InputError, match="not a valid unit"):
            realsense_units_mm(bad)


def test_librealsense_image_trailer() -> None:
    """librealsense's Image records end with float32 depth units after data."""
    from rosbags.rosbag1 import Reader

    with Reader(DATA / "rs256_100um.bag") as r:
        conn = next(c for c in r.connections if c.topic.endswith("Depth_0/image/data"))
        _, _, raw = next(iter(r.messages(connections=[conn])))
    msg = parse_image(raw, cdr=False)
    assert (msg.width, msg.height, msg.encoding) == (64, 48, "mono16")
    assert msg.depth_units_m == pytest.approx(1e-4)


@pytest.mark.skipif(importlib.util.find_spec("pyrealsense2") is None, reason="no pyrealsense2")
@pytest.mark.parametrize("name", RECORDINGS)
def test_realsense_live_sdk_playback(name: str) -> None:
    spec = importlib.util.spec_from_file_location(
        "make_realsense_fixtures", DATA.parent / "make_realsense_fixtures.py"
    )
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    ref = mod.playback(DATA / name)
    ours, stamps_ms = uio.read_video(DATA / name), uio.read_timestamps(DATA / name) / 1e6
    # the SDK's playback runs in real time until set_real_time(False) takes effect: on a busy
    # machine it may drop a frame there, so its frames are matched to ours by timestamp
    assert 1 <= len(ref["depth_mm"]) <= len(ours) and len(ours) == 3
    for depth, stamp in zip(ref["depth_mm"], ref["timestamps_ms"], strict=True):
        k = int(np.argmin(np.abs(stamps_ms - stamp)))
        assert stamps_ms[k] == pytest.approx(stamp, abs=1e-3)
        np.testing.assert_allclose(ours[k], depth, atol=1e-3)


# ---------------------------------------------------------------------------------------------
# image_transport compressedDepth / compressed
# ---------------------------------------------------------------------------------------------
def _scene(t: int) -> np.ndarray:
    y, x = np.mgrid[0:12, 0:16]
    d = (800 + 30 * x + 11 * y + 5 * t).astype(np.uint16)
    d[(x + y + t) % 7 == 0] = 0
    return d


def _compressed(ts, fmt: str, data: bytes, stamp_ns: int):
    hdr = ts.types["std_msgs/msg/Header"]
    time = ts.types["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    header = (
        hdr(seq=0, stamp=time, frame_id="cam")
        if "seq" in hdr.__dataclass_fields__
        else hdr(stamp=time, frame_id="cam")
    )
    return ts.types["sensor_msgs/msg/CompressedImage"](
        header=header, format=fmt, data=np.frombuffer(data, np.uint8)
    )


def _write_bag(path: Path, ros2: bool, topics: dict[str, list[tuple[str, bytes]]]) -> Path:
    from rosbags.typesys import Stores, get_typestore

    if ros2:
        from rosbags.rosbag2 import Writer

        ts = get_typestore(Stores.ROS2_HUMBLE)
        w = Writer(path, version=8)
        ser = ts.serialize_cdr
    else:
        from rosbags.rosbag1 import Writer

        ts = get_typestore(Stores.ROS1_NOETIC)
        w = Writer(path)
        ser = ts.serialize_ros1
    mt = "sensor_msgs/msg/CompressedImage"
    with w:
        for topic, msgs in topics.items():
            conn = w.add_connection(topic, mt, typestore=ts)
            for k, (fmt, data) in enumerate(msgs):
                stamp = 5 * 10**9 + k * 10**8
                w.write(conn, stamp, ser(_compressed(ts, fmt, data, stamp), mt))
    return path


def _jpeg() -> bytes:
    import cv2

    return cv2.imencode(".jpg", np.full((12, 16, 3), 128, np.uint8))[1].tobytes()


@pytest.mark.parametrize("ros2", [False, True])
@pytest.mark.parametrize("codec", ["png", "rvl"])
def test_compressed_depth_16uc1(tmp_path: Path, ros2: bool, codec: str) -> None:
    frames = [_scene(t) for t in range(3)]
    msgs = [encode_compressed_depth(f, "16UC1", codec) for f in frames]
    path = _write_bag(
        tmp_path / ("bag2" if ros2 else "a.bag"),
        ros2,
        {
            "/camera/depth/image_raw/compressedDepth": msgs,
            "/camera/color/image_raw/compressed": [("bgr8; jpeg compressed bgr8", _jpeg())] * 3,
        },
    )
    info = uio.probe(path)
    assert info.topic == "/camera/depth/image_raw/compressedDepth" and info.shape == (3, 12, 16)
    np.testing.assert_array_equal(uio.read_video(path), np.stack(frames).astype(np.float32))
    np.testing.assert_array_equal(uio.read_timestamps(path), 5 * 10**9 + np.arange(3) * 10**8)


def test_compressed_depth_32fc1_inverse_depth(tmp_path: Path) -> None:
    m = _scene(0).astype(np.float64) / 1000.0
    fmt, data = encode_compressed_depth(m, "32FC1", "png")
    path = _write_bag(tmp_path / "b2", True, {"/d/compressedDepth": [(fmt, data)]})
    got = uio.read_video(path)[0]
    assert ((got > 0) == (m > 0)).all()
    # quantised inverse depth: the error grows as depth²; at ~1.5 m it is well under 1 mm
    np.testing.assert_allclose(got[m > 0], 1000 * m[m > 0], atol=0.5)
    msg = CompressedMsg(0, fmt, data)
    import struct

    _, qa, qb = struct.unpack_from("<iff", data)
    raw = np.floor(qa / m[m > 0] + qb)
    np.testing.assert_allclose(
        decode_compressed_depth(msg)[m > 0], 1000 * qa / (raw - qb), rtol=1e-5
    )


def test_compressed_png_16bit(tmp_path: Path) -> None:
    import cv2

    frames = [_scene(t) for t in range(2)]
    msgs = [("16UC1; png compressed", cv2.imencode(".png", f)[1].tobytes()) for f in frames]
    path = _write_bag(tmp_path / "c.bag", False, {"/camera/depth/image_raw/compressed": msgs})
    np.testing.assert_array_equal(uio.read_video(path), np.stack(frames).astype(np.float32))


def test_compressed_colour_only_is_refused(tmp_path: Path) -> None:
    path = _write_bag(tmp_path / "d.bag", False, {"/rgb/compressed": [("bgr8; jpeg", _jpeg())]})
    with pytest.raises(InputError, match=r"no topic is a depth image.*rgb/compressed"):
        uio.probe(path)


def test_rvl_round_trip() -> None:
    rng = np.random.default_rng(3)
    v = rng.integers(0, 65535, 500).astype(np.uint16)
    v[rng.random(500) < 0.3] = 0
    v[100:180] = 0
    assert (rvl_decode(rvl_encode(v), v.size) == v).all()
    with pytest.raises(InputError):
        rvl_decode(rvl_encode(v)[:8], v.size)


# ---------------------------------------------------------------------------------------------
# writing ROS 2 bags
# ---------------------------------------------------------------------------------------------
def test_rosbag_output_reads_back(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader

    rng = np.random.default_rng(1)
    video = (rng.uniform(400, 5000, (3, 10, 14))).astype(np.float32)
    video[:, 2, 3] = 0
    stamps = np.array([1_000_000_000, 1_033_300_000, 1_066_600_000])
    cam = PinholeCamera(50.5, 51.25, 31.7, 23.2, 64, 48).scaled(2)
    cam = PinholeCamera(cam.fx, cam.fy, cam.cx, cam.cy, 14, 10)
    out = uio.write_video(tmp_path / "sr", video, fmt="rosbag", timestamps_ns=stamps, camera=cam)
    assert (out / "metadata.yaml").is_file()
    np.testing.assert_allclose(uio.read_video(out), video, rtol=1e-6)
    np.testing.assert_array_equal(uio.read_timestamps(out), stamps)
    assert uio.read_intrinsics(out) == cam
    with AnyReader([out]) as r:
        topics = {c.topic: c for c in r.connections}
        assert topics["/camera/depth/image_raw"].msgcount == 3
        assert topics["/camera/depth/camera_info"].msgcount == 3
        infos = list(r.messages(connections=[topics["/camera/depth/camera_info"]]))
        for (c, t, raw), s in zip(infos, stamps, strict=True):
            info = r.deserialize(raw, c.msgtype)
            assert t == s and info.header.stamp.sec * 10**9 + info.header.stamp.nanosec == s
            np.testing.assert_allclose(info.k.reshape(3, 3), cam.K)
            assert (info.width, info.height) == (14, 10)
        c, _, raw = next(iter(r.messages(connections=[topics["/camera/depth/image_raw"]])))
        img = r.deserialize(raw, c.msgtype)
        assert img.encoding == "32FC1"
        assert np.isnan(np.frombuffer(img.data.tobytes(), "<f4").reshape(10, 14)[2, 3])


def test_rosbag_output_default_stamps_and_no_camera(tmp_path: Path) -> None:
    out = uio.write_video(tmp_path / "sr", np.full((2, 4, 5), 1000.0, np.float32), fmt="rosbag")
    np.testing.assert_array_equal(uio.read_timestamps(out), [0, 33_333_333])
    assert uio.read_intrinsics(out) is None


def test_lone_db3_and_mcap(tmp_path: Path) -> None:
    lone = tmp_path / "x.mcap"
    lone.write_bytes(b"\x89MCAP0\r\n")
    with pytest.raises(InputError):
        uio.probe(lone, fmt="rosbag")
    bad = tmp_path / "x.db3"
    bad.write_bytes(b"not sqlite at all" * 10)
    with pytest.raises(InputError, match=r"x\.db3"):
        uio.probe(bad)


def test_realsense_frames_take_their_own_units_and_times_from_their_metadata(tmp_path) -> None:
    """librealsense writes each frame's depth units and time into its metadata: upsr run read
    the Depth_Units option only (a D405 recording with no or another option: 10 times too
    deep) and, with one metadata message missing, took every time from the header stamps
    (another clock: the time since the recording began)."""
    from .bagtools import realsense_ros2_bag

    raw = [15000, 15000, 15000, 1500, 1500]  # 1500 mm at 0.1 mm, then at 1 mm
    units = ["0.000100"] * 3 + ["0.001000", None]
    header = [33.3 * k for k in range(5)]
    meta = [
        None if u is None else f"Frame number={k};timestamp={1000 + h:.6f};depth_units={u};"
        for k, (u, h) in enumerate(zip(units, header, strict=True))
    ]
    bag = realsense_ros2_bag(
        tmp_path / "rs",
        [np.full((6, 8), v, np.uint16) for v in raw],
        option_units="0.001000",
        metadata=meta,
        header_ms=header,
    )
    np.testing.assert_array_equal(uio.read_video(bag), np.full((5, 6, 8), 1500.0, np.float32))
    np.testing.assert_allclose(
        uio.read_timestamps(bag) / 1e6, [1000.0, 1033.3, 1066.6, 1099.9, 1133.2], atol=1e-3
    )


def test_only_the_depth_cameras_own_camera_info_gives_intrinsics(tmp_path) -> None:
    """A bag with the colour camera's CameraInfo only: its intrinsics were written as the
    depth's (or, of another size, the recording was refused)."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from .bagtools import K_DEFAULT, camera_info, image

    ts = get_typestore(Stores.ROS2_HUMBLE)
    info_t, img_t = "sensor_msgs/msg/CameraInfo", "sensor_msgs/msg/Image"
    depth = np.full((6, 8), 1500, np.uint16)
    for name, infos in (("sibling", ["color"]), ("own", ["color", "depth"])):
        with Writer(tmp_path / name, version=9) as w:
            for cam in infos:
                c = w.add_connection(f"/camera/camera/{cam}/camera_info", info_t, typestore=ts)
                k = (70.0, 0, 32.0, 0, 70.0, 24.0, 0, 0, 1) if cam == "color" else K_DEFAULT
                size = (16, 12) if cam == "color" else (8, 6)
                w.write(c, 1, ts.serialize_cdr(camera_info(ts, *size, k), info_t))
            c = w.add_connection("/camera/camera/depth/image_rect_raw", img_t, typestore=ts)
            w.write(c, 2, ts.serialize_cdr(image(ts, depth, "16UC1"), img_t))
    assert uio.read_intrinsics(tmp_path / "sibling") is None
    cam = uio.read_intrinsics(tmp_path / "own")
    assert (cam.fx, cam.cx, cam.cy) == (K_DEFAULT[0], K_DEFAULT[2], K_DEFAULT[5])


def test_a_lens_distortion_that_is_dropped_is_said(tmp_path) -> None:
    """Non-zero distortion coefficients were dropped without a word (the intrinsics sidecar
    says pinhole): a warning; none for zero coefficients (the other tests' bags)."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from .bagtools import K_DEFAULT, camera_info, image

    ts = get_typestore(Stores.ROS2_HUMBLE)
    info_t, img_t = "sensor_msgs/msg/CameraInfo", "sensor_msgs/msg/Image"
    with Writer(tmp_path / "bag", version=9) as w:
        c = w.add_connection("/cam/depth/camera_info", info_t, typestore=ts)
        msg = camera_info(ts, 8, 6, K_DEFAULT, d=(0.12, -0.25, 0.0, 0.0, 0.01))
        w.write(c, 1, ts.serialize_cdr(msg, info_t))
        c = w.add_connection("/cam/depth/image_raw", img_t, typestore=ts)
        w.write(c, 2, ts.serialize_cdr(image(ts, np.full((6, 8), 1500, np.uint16), "16UC1"), img_t))
    with pytest.warns(UserWarning, match="lens distortion .plumb_bob, 5 coefficients"):
        cam = uio.read_intrinsics(tmp_path / "bag")
    assert cam.fx == K_DEFAULT[0]


def test_a_cut_a_renamed_and_an_active_recording_are_named_for_what_they_are(tmp_path) -> None:
    """A RealSense .db3 named .bag was 'corrupt (UnicodeDecodeError)'; a ROS 1 bag cut short
    'corrupt (Bag index looks damaged)'; a .bag.active 'unknown input format'."""
    db3 = DATA / "rs259_1mm.db3"
    renamed = tmp_path / "rec.bag"
    renamed.write_bytes(db3.read_bytes())
    np.testing.assert_array_equal(uio.read_video(renamed), uio.read_video(db3))
    whole = (DATA / "rs256_1mm.bag").read_bytes()
    (tmp_path / "cut.bag").write_bytes(whole[: len(whole) // 2])
    with pytest.raises(InputError, match=r"index is damaged .* `rosbag reindex` repairs it"):
        uio.read_video(tmp_path / "cut.bag")
    (tmp_path / "live.bag.active").write_bytes(whole)
    with pytest.raises(InputError, match="still being recorded, or cut short: `rosbag reindex`"):
        uio.read_video(tmp_path / "live.bag.active")
