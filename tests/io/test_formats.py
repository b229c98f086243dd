"""Readers and writers of upsr.io.registry behind upsr.io: TIFF, EXR, ROS bags, dataset formats."""

from __future__ import annotations

import shutil
import tempfile
from datetime import timedelta
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from upsr.errors import InputError
from upsr.io import video as io

DATA = Path(__file__).parent / "data" / "formats"


def video(t: int = 3, h: int = 6, w: int = 8, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = rng.integers(400, 5000, size=(t, h, w)).astype(np.float32)
    v[:, 0, 0] = 0
    return v


def listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


# ---------------------------------------------------------------------------------------------
# dataset formats: real crops of the shared samples
# ---------------------------------------------------------------------------------------------
def test_nyu_raw_kinect_pgm() -> None:
    path = DATA / "nyu_depth_crop.pgm"
    info = io.probe(path)
    assert (info.format, info.shape) == ("nyu", (1, 48, 64))
    depth = io.read_video(path)[0]
    raw = np.frombuffer(path.read_bytes()[15:], "<u2").reshape(48, 64).astype(np.float64)
    expect = np.where(raw == 2047, 0.0, 351.3 / (1092.5 - raw) * 1000.0)
    np.testing.assert_allclose(depth, expect, rtol=1e-6)
    assert (depth == 0).any() and 2000 < np.median(depth[depth > 0]) < 5000


def test_nyu_byte_order_and_invalid_values(tmp_path: Path) -> None:
    raw = np.array([[900, 2047, 1050, 1092]], np.uint16)
    standard = tmp_path / "be.pgm"  # a standard (big-endian) PGM of raw disparity works too
    standard.write_bytes(b"P5\n# comment\n4 1\n65535\n" + raw.astype(">u2").tobytes())
    d = io.read_video(standard)[0, 0]
    assert d[0] == pytest.approx(351.3 / 192.5 * 1000, rel=1e-6)
    assert d[1] == 0 and d[3] == 0  # 2047 = none; 702 m (beyond 10 m) = none
    assert d[2] == pytest.approx(351.3 / 42.5 * 1000, rel=1e-6)
    big = tmp_path / "depth.pgm"
    big.write_bytes(b"P5 2 1 65535\n" + np.array([[3000, 2500]], ">u2").tobytes())
    with pytest.raises(InputError, match="not raw Kinect disparity"):
        io.read_video(big)
    plain = io.read_video(big, fmt="pgm")[0, 0]  # a plain 16-bit PGM of mm
    np.testing.assert_array_equal(plain, [3000, 2500])
    assert io.read_video(big, fmt="pgm", depth_scale=5000)[0, 0, 0] == pytest.approx(600)


@pytest.mark.parametrize(
    ("header", "body", "match"),
    [
        (b"P5 4 1 255\n", b"\x01\x02\x03\x04", "8-bit"),
        (b"P5 4 1 65535\n", b"\x01\x02\x03", "truncated"),
        (b"P2 4 1 65535\n", b"1 2 3 4", "ASCII"),
        (b"P5 4", b"", "corrupt or truncated PGM header"),
        (b"P5 0 1 65535\n", b"", "empty"),
        (b"P6 4 1 65535\n", b"\0" * 24, "not a binary PGM"),
    ],
)
def test_bad_pgm(tmp_path: Path, header: bytes, body: bytes, match: str) -> None:
    p = tmp_path / "x.pgm"
    p.write_bytes(header + body)
    with pytest.raises(InputError, match=match):
        io.read_video(p)


def test_sun_rgbd_png() -> None:
    path = DATA / "sun_depth_crop.png"
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED).astype(np.uint32)
    depth = io.read_video(path, fmt="sun")[0]
    expect = ((raw >> 3) | (raw << 13)) & 0xFFFF
    np.testing.assert_array_equal(depth, expect)
    assert 500 < np.median(depth[depth > 0]) < 10000  # plausible mm
    assert io.probe(path, fmt="sun").format == "sun"


def test_tum_png() -> None:
    path = DATA / "tum_depth_crop.png"
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED).astype(np.float64)
    np.testing.assert_allclose(io.read_video(path, fmt="tum")[0], raw / 5.0, rtol=1e-6)
    np.testing.assert_allclose(io.read_video(path, depth_scale=5000)[0], raw / 5.0, rtol=1e-6)


def test_dataset_folder(tmp_path: Path) -> None:
    folder = tmp_path / "nyu"
    folder.mkdir()
    for i in range(3):
        shutil.copy(DATA / "nyu_depth_crop.pgm", folder / f"f{i}.pgm")
    assert io.probe(folder).shape == (3, 48, 64)
    (folder / "f1.pgm").write_bytes(b"P5 3 2 65535\n" + b"\0" * 12)
    with pytest.raises(InputError, match=r"f1\.pgm: frame size 3x2 differs"):
        io.probe(folder)


# ---------------------------------------------------------------------------------------------
# TIFF
# ---------------------------------------------------------------------------------------------
@pytest.fixture
def tifffile():  # type: ignore[no-untyped-def]
    return pytest.importorskip("tifffile")


@pytest.mark.parametrize("name", ["v.tif", "v.tiff", "sub/v.tif"])
def test_tiff_round_trip(tmp_path: Path, name: str, tifffile) -> None:
    v = video()
    out = io.write_video(tmp_path / name, v)
    info = io.probe(out)
    assert (info.format, info.shape) == ("tiff", v.shape)
    np.testing.assert_array_equal(io.read_video(out), v)
    with tifffile.TiffFile(out) as tif:
        assert len(tif.pages) == 3 and tif.pages[0].dtype == np.float32
    # metres in the file
    io.write_video(tmp_path / "m.tif", v, depth_scale=1.0)
    np.testing.assert_allclose(tifffile.imread(tmp_path / "m.tif"), v / 1000.0, rtol=1e-6)
    np.testing.assert_allclose(io.read_video(tmp_path / "m.tif", depth_scale=1.0), v, rtol=1e-6)


def test_tiff_inputs(tmp_path: Path, tifffile) -> None:
    v = video()
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, f in enumerate(v):
        tifffile.imwrite(folder / f"{i:02d}.tiff", f.astype(np.uint16))
    assert io.probe(folder).format == "tiff"
    np.testing.assert_array_equal(io.read_video(folder), v)
    nan = v.copy()
    nan[0, 1, 1] = np.nan
    tifffile.imwrite(tmp_path / "nan.tif", nan.astype(np.float64), photometric="minisblack")
    got = io.read_video(tmp_path / "nan.tif")
    assert got[0, 1, 1] == 0 and got.dtype == np.float32
    # OpenCV's TIFFs are LZW-compressed: read through imagecodecs (they were "corrupt")
    cv2.imwritemulti(str(tmp_path / "cv.tif"), list(v.astype(np.uint16)))
    assert tifffile.TiffFile(tmp_path / "cv.tif").pages[0].compression == 5  # LZW
    np.testing.assert_array_equal(io.read_video(tmp_path / "cv.tif"), v)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda tf, p: tf.imwrite(p, np.ones((4, 5), np.uint8)), "8-bit"),
        (lambda tf, p: tf.imwrite(p, np.ones((4, 5, 3), np.uint16)), "single-channel"),
        (
            lambda tf, p: tf.imwrite(p, -np.ones((2, 4, 5), np.float32), photometric="minisblack"),
            "negative",
        ),
        (lambda tf, p: tf.imwrite(p, np.full((4, 5), np.inf, np.float32)), "inf"),
        (lambda tf, p: p.write_bytes(b"II*\0garbage"), "x.tif"),
        (lambda tf, p: p.write_bytes(b""), "x.tif"),
    ],
)
def test_bad_tiff(tmp_path: Path, make, match: str, tifffile) -> None:
    p = tmp_path / "x.tif"
    make(tifffile, p)
    with pytest.raises(InputError, match=match):
        io.read_video(p)


def test_truncated_and_mixed_tiff(tmp_path: Path, tifffile) -> None:
    p = io.write_video(tmp_path / "v.tif", video(t=3, h=20, w=30))
    data = p.read_bytes()
    cut = tmp_path / "cut.tif"
    for n in (len(data) - 50, len(data) // 2, 16):
        cut.write_bytes(data[:n])
        with pytest.raises(InputError, match=r"cut\.tif"):
            io.read_video(cut)
    with tifffile.TiffWriter(tmp_path / "mixed.tif") as tw:
        tw.write(np.ones((4, 5), np.float32))
        tw.write(np.ones((5, 5), np.float32))
    with pytest.raises(InputError, match="differs"):
        io.probe(tmp_path / "mixed.tif")


# ---------------------------------------------------------------------------------------------
# OpenEXR
# ---------------------------------------------------------------------------------------------
def _exr(path: Path, channels: dict[str, np.ndarray]) -> Path:
    exr = pytest.importorskip("OpenEXR")
    header = {"compression": exr.ZIP_COMPRESSION, "type": exr.scanlineimage}
    exr.File(header, channels).write(str(path))
    return path


def test_exr_round_trip(tmp_path: Path) -> None:
    pytest.importorskip("OpenEXR")
    v = video()
    one = io.write_video(tmp_path / "one.exr", v[:1])
    np.testing.assert_array_equal(io.read_video(one), v[:1])
    folder = io.write_video(tmp_path / "frames", v, fmt="exr")
    assert sorted(p.name for p in folder.iterdir()) == ["000000.exr", "000001.exr", "000002.exr"]
    info = io.probe(folder)
    assert (info.format, info.shape) == ("exr", v.shape)
    np.testing.assert_array_equal(io.read_video(folder), v)
    with pytest.raises(InputError, match="holds one frame"):
        io.write_video(tmp_path / "many.exr", v)
    assert not (tmp_path / "many.exr").exists()
    # a stream of unknown length finds out at its second frame: the message names the output
    with pytest.raises(InputError, match=r"holds one frame.*not streamed\.exr$"):
        with io.VideoWriter(tmp_path / "streamed.exr") as writer:
            writer.write(v[0])
            writer.write(v[1])
    assert not (tmp_path / "streamed.exr").exists()
    assert [n for n in listing(tmp_path) if n.startswith(".")] == []


def test_a_single_png_file_holds_one_frame(tmp_path: Path) -> None:
    v = video()
    one = io.write_video(tmp_path / "one.png", v[:1])
    assert one.is_file() and io.probe(one).shape == v[:1].shape
    np.testing.assert_allclose(io.read_video(one), v[:1], atol=0.5)  # whole mm
    with pytest.raises(InputError, match="holds one frame"):
        io.write_video(tmp_path / "many.png", v)
    assert not (tmp_path / "many.png").exists()
    assert [n for n in listing(tmp_path) if n.startswith(".")] == []


def test_exr_channels(tmp_path: Path) -> None:
    z = (video(t=1)[0] / 1000.0).astype(np.float32)  # metres, as renderers write
    rgb = np.zeros_like(z)
    p = _exr(tmp_path / "render.exr", {"R": rgb, "G": rgb, "B": rgb, "ViewLayer.Depth.Z": z})
    np.testing.assert_allclose(io.read_video(p, depth_scale=1.0)[0], z * 1000, rtol=1e-6)
    with pytest.raises(InputError, match="no valid depth"):  # G is all 0 here
        io.read_video(p, key="G", depth_scale=1)
    with pytest.raises(InputError, match="no channel 'Q'"):
        io.probe(p, key="Q")
    half = _exr(tmp_path / "half.exr", {"depth": z.astype(np.float16)})
    np.testing.assert_allclose(io.read_video(half, depth_scale=1)[0], z * 1000, rtol=2e-3)
    two = _exr(tmp_path / "two.exr", {"A": z, "B": z})
    with pytest.raises(InputError, match="which channel"):
        io.probe(two)


def test_bad_exr(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("OpenEXR")
    good = io.write_video(tmp_path / "g.exr", video(t=1, h=30, w=40))
    data = good.read_bytes()
    bad = tmp_path / "bad.exr"
    for blob in (data[: len(data) - 40], data[:60], b"v/1\x01" + b"\0" * 30, b"not an exr"):
        bad.write_bytes(blob)
        with pytest.raises(InputError, match=r"bad\.exr"):
            io.read_video(bad)
    out, err = capfd.readouterr()
    assert out == "" and err == ""  # OpenEXR's own complaints are part of the error, not noise


def test_folder_mixing_formats(tmp_path: Path, tifffile) -> None:
    folder = tmp_path / "mix"
    folder.mkdir()
    tifffile.imwrite(folder / "a.tif", np.ones((4, 5), np.uint16))
    shutil.copy(DATA / "nyu_depth_crop.pgm", folder / "b.pgm")
    with pytest.raises(InputError, match="mixes frames of several formats"):
        io.probe(folder)


# ---------------------------------------------------------------------------------------------
# ROS bags
# ---------------------------------------------------------------------------------------------
def _bags():  # type: ignore[no-untyped-def]
    pytest.importorskip("rosbags")
    from tests.io import bagtools

    return bagtools


@pytest.mark.parametrize(("big", "pad"), [(False, 0), (True, 3), (False, 5)])
def test_ros1_bag_16uc1(tmp_path: Path, big: bool, pad: int) -> None:
    bt = _bags()
    v = video(t=4)
    bag = bt.ros1_bag(tmp_path / "rec.bag", v, big=big, pad=pad, k=bt.K_DEFAULT)
    info = io.probe(bag)
    assert (info.format, info.shape, info.topic) == ("rosbag", v.shape, "/camera/depth/image_raw")
    np.testing.assert_array_equal(io.read_video(bag), v)
    cam = io.read_intrinsics(bag)
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (500, 501, 3.5, 2.5, 8, 6)


def test_ros2_bag_32fc1(tmp_path: Path) -> None:
    bt = _bags()
    v = video(t=3) / 1000.0
    v[1, 2, 2] = np.nan
    v[1, 2, 3] = np.inf  # REP 117: too far
    v[1, 2, 4] = -np.inf  # too close
    bag = bt.ros2_bag(tmp_path / "rec2", v.astype(np.float32), k=bt.K_DEFAULT)
    assert io.probe(bag).format == "rosbag"
    got = io.read_video(bag)
    assert (got[1, 2, 2:5] == 0).all()
    ok = np.isfinite(v)
    np.testing.assert_allclose(got[ok], (v * 1000)[ok], rtol=1e-6)
    storage = next(bag.glob("*.db3"))
    np.testing.assert_array_equal(io.read_video(storage), got)  # the .db3 file means its bag
    assert io.read_intrinsics(bag).fx == 500


def test_realsense_bag(tmp_path: Path) -> None:
    bt = _bags()
    v = video(t=3)
    bag = bt.realsense_bag(tmp_path / "d435.bag", v.astype(np.uint16), units_m=0.0001)
    np.testing.assert_allclose(io.read_video(bag), v * 0.1, rtol=1e-6)  # 0.1 mm units
    assert io.read_intrinsics(bag).cy == 2.5


def test_bag_topics(tmp_path: Path) -> None:
    bt = _bags()
    v = video(t=2)
    rgb = np.zeros((6, 8, 3), np.uint8)
    bag = bt.ros1_bag(
        tmp_path / "rgb.bag", [rgb, rgb], topic="/camera/color/image_raw", encoding="rgb8"
    )
    with pytest.raises(InputError, match=r"no topic is a depth image.*color/image_raw \(rgb8\)"):
        io.probe(bag)
    assert not list(tmp_path.glob(".*"))
    two = bt.ros1_bag(
        tmp_path / "two.bag",
        v,
        topic="/a/depth",
        extra=[("/b/depth", "sensor_msgs/msg/Image", lambda ts: bt.image(ts, v[0], "16UC1"))],
    )
    with pytest.raises(
        InputError, match=r"several depth topics, choose one with --topic: /a/depth, /b/depth"
    ):
        io.probe(two)
    assert io.probe(two, topic="/b/depth").n_frames == 1
    np.testing.assert_array_equal(io.read_video(two, topic="/a/depth"), v)
    with pytest.raises(InputError, match="no topic '/c'"):
        io.probe(two, topic="/c")
    with pytest.raises(InputError, match="only applies to ROS bags"):
        io.probe(DATA / "nyu_depth_crop.pgm", topic="/a/depth")


def test_bad_bags(tmp_path: Path) -> None:
    bt = _bags()
    v = video(t=3, h=12, w=16)
    bag = bt.ros1_bag(tmp_path / "ok.bag", v)
    data = bag.read_bytes()
    bad = tmp_path / "bad.bag"
    for blob in (data[: len(data) // 2], data[:20], b"#ROSBAG V2.0\n" + b"\xff" * 100, b""):
        bad.write_bytes(blob)
        with pytest.raises(InputError, match=r"bad\.bag"):
            io.read_video(bad)
    mixed = bt.ros1_bag(tmp_path / "mixed.bag", [v[0], v[1, :5]])
    with pytest.raises(InputError, match="message 1: frame size 16x5 differs"):
        io.read_video(mixed)
    short = tmp_path / "short.bag"  # data shorter than height x step
    bt.ros1_bag(
        short,
        [v[0]],
        topic="/x",
        extra=[("/depth", "sensor_msgs/msg/Image", lambda ts: _short_image(bt, ts, v[0]))],
    )
    with pytest.raises(InputError, match="truncated image"):
        io.read_video(short, topic="/depth")
    (tmp_path / "notabag").mkdir()
    with pytest.raises(InputError, match=r"metadata\.yaml"):
        io.probe(tmp_path / "notabag", fmt="rosbag")


def _short_image(bt, ts, frame):  # type: ignore[no-untyped-def]
    msg = bt.image(ts, frame, "16UC1")
    msg.data = msg.data[:-10]
    return msg


# ---------------------------------------------------------------------------------------------
# fuzzing: only InputError (or valid frames) from any bytes
# ---------------------------------------------------------------------------------------------
FUZZ = settings(
    max_examples=60, deadline=timedelta(seconds=10), suppress_health_check=[HealthCheck.too_slow]
)
_SEEDS: dict[str, bytes] = {}


def _seed(suffix: str) -> bytes:
    if suffix not in _SEEDS:
        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / f"x{suffix}"
            v = video(t=2, h=4, w=5)
            if suffix == ".pgm":
                shutil.copy(DATA / "nyu_depth_crop.pgm", p)
            elif suffix == ".bag":
                _bags().ros1_bag(p, v, k=(1, 0, 1, 0, 1, 1, 0, 0, 1))
            else:
                io.write_video(p, v[:1] if suffix == ".exr" else v)
            _SEEDS[suffix] = p.read_bytes()
    return _SEEDS[suffix]


def _fuzz(data: bytes, suffix: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"x{suffix}"
        p.write_bytes(data)
        try:
            v = io.read_video(p)
        except InputError:
            return
        assert v.dtype == np.float32 and v.ndim == 3


_SUFFIXES = [".tif", ".pgm", ".exr", ".bag"]


def _need(suffix: str) -> None:
    module = {".tif": "tifffile", ".exr": "OpenEXR", ".bag": "rosbags"}.get(suffix)
    if module:
        pytest.importorskip(module)


@FUZZ
@given(
    suffix=st.sampled_from(_SUFFIXES),
    flips=st.lists(st.tuples(st.integers(0, 10**6), st.integers(1, 255)), max_size=6),
    cut=st.none() | st.integers(0, 10**6),
)
def test_fuzz_mutated_files(suffix: str, flips: list[tuple[int, int]], cut: int | None) -> None:
    _need(suffix)
    data = bytearray(_seed(suffix))
    for pos, mask in flips:
        data[pos % len(data)] ^= mask
    if cut is not None:
        data = data[: cut % (len(data) + 1)]
    _fuzz(bytes(data), suffix)


@FUZZ
@given(suffix=st.sampled_from(_SUFFIXES), data=st.binary(max_size=400))
def test_fuzz_random_bytes(suffix: str, data: bytes) -> None:
    magic = {".tif": b"II*\0", ".pgm": b"P5 ", ".exr": b"v/1\x01", ".bag": b"#ROSBAG V2.0\n"}
    _need(suffix)
    _fuzz(data, suffix)
    _fuzz(magic[suffix] + data, suffix)
