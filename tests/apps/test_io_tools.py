"""Intrinsics, point clouds, pictures (compare / view / GIF) and their commands."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from upsr.apps.cli.main import main
from upsr.errors import InputError
from upsr.geometry.intrinsics import load_intrinsics, parse_intrinsics, write_intrinsics
from upsr.io import video as io
from upsr.io.pointcloud import backproject
from upsr.viz.animation import GifWriter
from upsr.viz.pictures import ComparisonWriter, comparison_frame, render_view

DATA = Path(__file__).parents[1] / "io" / "data" / "formats"


def scene(t: int = 3, h: int = 12, w: int = 16) -> np.ndarray:
    """A slanted wall with a box in front, in mm; one invalid pixel per frame."""
    _yy, xx = np.mgrid[0:h, 0:w]
    v = np.empty((t, h, w), np.float32)
    for k in range(t):
        d = 2000.0 + 20.0 * xx
        d[3:8, 4 + k : 9 + k] = 1200.0
        v[k] = d
    v[:, 0, 0] = 0
    return v


# ---------------------------------------------------------------------------------------------
# intrinsics
# ---------------------------------------------------------------------------------------------
def test_parse_and_scale_intrinsics(tmp_path: Path) -> None:
    cam = parse_intrinsics("525, 526 ,319.5,239.5", 640, 480)
    hi = cam.scaled(2)
    assert (hi.fx, hi.fy, hi.cx, hi.cy, hi.width, hi.height) == (
        1050,
        1052,
        639.5,
        479.5,
        1280,
        960,
    )
    # SPEC §1: low-res pixel i is centred at high-res (i + 0.5) r - 0.5: same ray in both
    i, r = 100.0, 3
    cam3 = cam.scaled(r)
    assert (i - cam.cx) / cam.fx == pytest.approx(((i + 0.5) * r - 0.5 - cam3.cx) / cam3.fx)
    for bad in ("1,2,3", "a,b,c,d", "0,1,1,1", "1,1,nan,1"):
        with pytest.raises(InputError):
            parse_intrinsics(bad, 4, 4)
    p = write_intrinsics(tmp_path / "x.json", hi, source=cam, scale=2)
    assert load_intrinsics(p) == hi
    assert json.loads(p.read_text())["input"]["fx"] == 525
    (tmp_path / "bad.json").write_text('{"fx": 1}')
    with pytest.raises(InputError, match="not an intrinsics file"):
        load_intrinsics(tmp_path / "bad.json")


def test_run_writes_scaled_intrinsics(tmp_path: Path) -> None:
    np.save(tmp_path / "in.npy", scene())
    args = ["run", str(tmp_path / "in.npy"), "-o", str(tmp_path / "out.npy"), "-r", "2", "-q"]
    assert main([*args, "-n", "3", "--intrinsics", "20,21,7.5,5.5"]) == 0
    d = json.loads((tmp_path / "out.npy.intrinsics.json").read_text())
    assert (d["fx"], d["fy"], d["cx"], d["cy"], d["width"], d["height"]) == (
        40,
        42,
        15.5,
        11.5,
        32,
        24,
    )
    assert d["scale"] == 2 and d["input"]["cx"] == 7.5
    # the output's intrinsics are found next to it by the next command
    assert io.read_intrinsics(tmp_path / "out.npy").fx == 40
    assert main([*args, "--overwrite", "--intrinsics", "1,2"]) == 2  # bad, nothing written
    assert (tmp_path / "out.npy.intrinsics.json").exists()


def test_run_bag_intrinsics(tmp_path: Path) -> None:
    pytest.importorskip("rosbags")
    from tests.io import bagtools

    bag = bagtools.ros1_bag(
        tmp_path / "r.bag", scene(h=6, w=8).astype(np.uint16), k=bagtools.K_DEFAULT
    )
    out = tmp_path / "o"
    assert main(["run", str(bag), "-o", str(out), "-r", "2", "-n", "3", "-q"]) == 0
    assert io.probe(out).shape == (3, 12, 16)
    d = json.loads((tmp_path / "o.intrinsics.json").read_text())
    assert (d["fx"], d["cx"], d["cy"]) == (1000, 7.5, 5.5)


# ---------------------------------------------------------------------------------------------
# point clouds
# ---------------------------------------------------------------------------------------------
def test_backproject() -> None:
    d = np.array([[1000.0, 0.0], [2000.0, 500.0]], np.float32)
    cam = parse_intrinsics("100,200,0.5,0.5", 2, 2)
    pts, valid = backproject(d, cam)
    assert valid.tolist() == [[True, False], [True, True]]
    np.testing.assert_allclose(
        pts, [[-0.005, -0.0025, 1.0], [-0.01, 0.005, 2.0], [0.0025, 0.00125, 0.5]], rtol=1e-6
    )
    with pytest.raises(InputError, match="intrinsics are for"):
        backproject(np.ones((3, 2)), cam)


def test_export_ply(tmp_path: Path) -> None:
    plyfile = pytest.importorskip("plyfile")
    v = scene()
    np.save(tmp_path / "v.npy", v)
    colours = tmp_path / "rgb"
    colours.mkdir()
    for k in range(3):
        cv2.imwrite(str(colours / f"{k}.png"), np.full((6, 8, 3), (10 * k, 100, 200), np.uint8))
    out = tmp_path / "ply"
    base = ["export-ply", str(tmp_path / "v.npy"), "-o", str(out), "-q"]
    assert main(base) == 2  # no intrinsics
    assert main([*base, "--intrinsics", "20,20,7.5,5.5", "--color", str(colours)]) == 0
    files = sorted(out.glob("*.ply"))
    assert [f.name for f in files] == ["frame_000000.ply", "frame_000001.ply", "frame_000002.ply"]
    vert = plyfile.PlyData.read(str(files[2]))["vertex"]
    assert len(vert) == (v[2] > 0).sum()
    assert set(vert["red"]) == {200} and set(vert["blue"]) == {20}  # colour resized, RGB order
    np.testing.assert_allclose(np.sort(vert["z"])[-1], v[2].max() / 1000.0, rtol=1e-6)
    assert main([*base, "--intrinsics", "20,20,7.5,5.5"]) == 2  # exists
    assert main([*base, "--intrinsics", "20,20,7.5,5.5", "--overwrite"]) == 0  # depth colours
    assert (
        main(
            [
                "export-ply",
                str(DATA / "nyu_depth_crop.pgm"),
                "-o",
                str(tmp_path / "nyu"),
                "--intrinsics",
                "582.6,582.7,13,20",
                "--color",
                str(DATA / "nyu_color_crop.png"),
                "-q",
            ]
        )
        == 0
    )


# ---------------------------------------------------------------------------------------------
# pictures
# ---------------------------------------------------------------------------------------------
def test_comparison_pictures(tmp_path: Path) -> None:
    v = scene()
    hi = np.kron(v, np.ones((2, 2), np.float32))
    img = comparison_frame(v[0], hi[0], 2, hi[0], vmin_mm=1000, vmax_mm=2400, caption="frame 0")
    assert img.dtype == np.uint8 and img.shape[2] == 3 and img.shape[1] > 5 * 32
    with pytest.raises(InputError, match="not r=2 times"):
        comparison_frame(v[0], v[0], 2, vmin_mm=0, vmax_mm=1)
    with ComparisonWriter(tmp_path / "a.gif", fps=4) as w:
        for k in range(3):
            w.write(comparison_frame(v[k], hi[k], 2, vmin_mm=1000, vmax_mm=2400))
    with ComparisonWriter(tmp_path / "a.mp4", fps=4) as w:
        for k in range(3):
            w.write(comparison_frame(v[k], hi[k], 2, vmin_mm=1000, vmax_mm=2400))
    cap = cv2.VideoCapture(str(tmp_path / "a.mp4"))
    n = 0
    while cap.read()[0]:
        n += 1
    assert n == 3
    assert cv2.VideoWriter_fourcc(*"h264") == int(cap.get(cv2.CAP_PROP_FOURCC))
    if hasattr(cv2, "imreadanimation"):
        ok, anim = cv2.imreadanimation(str(tmp_path / "a.gif"))
        assert ok and len(anim.frames) == 3
    assert (tmp_path / "a.gif").read_bytes()[:6] == b"GIF89a"
    with pytest.raises(InputError):
        ComparisonWriter(tmp_path / "a.jpg")
    with pytest.raises(RuntimeError), GifWriter(tmp_path / "b.gif") as g:
        g.write(np.zeros((4, 4, 3), np.uint8))
        raise RuntimeError
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.gif", "a.mp4"]


def test_compare_and_view_commands(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    v = scene(t=4)
    np.save(tmp_path / "low.npy", v)
    hi = np.kron(v, np.ones((2, 2), np.float32))
    hi[:, 5, 5] = 0
    np.save(tmp_path / "up.npy", hi)
    np.save(tmp_path / "truth.npy", hi + 3)
    base = ["compare", str(tmp_path / "low.npy"), str(tmp_path / "up.npy"), "-q"]
    assert (
        main(
            [
                *base,
                "--truth",
                str(tmp_path / "truth.npy"),
                "-o",
                str(tmp_path / "c.png"),
                "-k",
                "-1",
            ]
        )
        == 0
    )
    img = cv2.imread(str(tmp_path / "c.png"))
    assert img is not None and img.shape[1] > img.shape[0]
    assert main([*base, "-o", str(tmp_path / "c.gif"), "--range", "1000,2500"]) == 0
    assert main([*base, "-o", str(tmp_path / "c.mp4"), "--scale", "2"]) == 0
    assert main([*base, "-o", str(tmp_path / "x.mp4"), "--scale", "3"]) == 2
    assert main([*base, "-o", str(tmp_path / "c.gif")]) == 2  # exists
    assert main([*base, "-o", str(tmp_path / "c.png"), "-k", "9", "--overwrite"]) == 2
    assert "frames 0..3" in capsys.readouterr().err
    assert main(["view", str(tmp_path / "up.npy"), "-k", "1", "-o", str(tmp_path / "v.png")]) == 0
    view = cv2.imread(str(tmp_path / "v.png"))
    assert view.shape[1] >= 640 and (view < 200).any()  # a surface was drawn
    assert main(["view", str(tmp_path / "up.npy"), "-o", str(tmp_path / "v.jpg")]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "c.gif",
        "c.mp4",
        "c.png",
        "low.npy",
        "truth.npy",
        "up.npy",
        "v.png",
    ]


def test_render_view_shapes() -> None:
    v = scene()[0]
    cam = parse_intrinsics("20,20,7.5,5.5", 16, 12)
    img = render_view(v, cam, min_width_px=64, shading="depth")
    assert img.shape == (48, 64, 3)
    with pytest.raises(InputError, match="no surface"):
        render_view(np.zeros((12, 16)), cam)
