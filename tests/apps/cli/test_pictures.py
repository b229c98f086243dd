"""``upsr compare`` and ``upsr view``, and the pictures they draw (GIF, panels, 3-D view)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.apps._util import run_cli, scene
from upsr.apps.cli.main import main
from upsr.errors import InputError
from upsr.geometry.intrinsics import parse_intrinsics
from upsr.viz.animation import GifWriter
from upsr.viz.pictures import ComparisonWriter, comparison_frame, render_view


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


def test_pictures_never_write_into_or_over_an_input(tmp_path, capsys) -> None:
    """`upsr view FRAMES -o FRAMES/000.png --overwrite` replaced a depth frame with a picture;
    `export-ply` wrote its PLY files among the input's frames."""
    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(3):
        cv2.imwrite(str(frames / f"{k:03d}.png"), np.full((20, 24), 1500 + k, np.uint16))
    before = {p.name: p.read_bytes() for p in frames.iterdir()}
    for args in (
        ["view", frames, "-o", frames / "000.png", "--overwrite"],
        ["compare", frames, frames, "-o", frames / "001.png", "--overwrite", "--scale", "1"],
        ["export-ply", frames, "-o", frames, "--intrinsics", "20,20,12,10", "--overwrite"],
    ):
        rc, _, err = run_cli(capsys, *args)
        assert rc == 2 and "input" in err and len(err.strip().splitlines()) == 1, err
    assert {p.name: p.read_bytes() for p in frames.iterdir()} == before


def test_view_and_export_ply_warn_of_a_file_in_metres_read_as_mm(tmp_path: Path, capsys) -> None:
    """A TIFF written in metres (``--output-depth-scale 1``) read at the default 1000 units
    per metre renders and back-projects a scene 1000 times too small: both commands say so
    and name their option (``--depth-scale``), as ``upsr run`` warns."""
    pytest.importorskip("tifffile")
    from upsr.io import video as io

    io.write_video(tmp_path / "m.tif", scene()[:2], depth_scale=1.0)
    for command in (
        ["view", tmp_path / "m.tif", "-o", tmp_path / "v.png"],
        ["export-ply", tmp_path / "m.tif", "-o", tmp_path / "p", "--intrinsics", "40,40,15,12",
         "-q"],
    ):  # fmt: skip
        rc, _, err = run_cli(capsys, *command)
        assert rc == 0 and "look like metres (--depth-scale 1)" in err, err
        rc, _, err = run_cli(capsys, *command, "--depth-scale", "1", "--overwrite")
        assert rc == 0 and "warning" not in err, err


@pytest.mark.parametrize("suffix", ["png", "gif"])
def test_compare_refuses_frames_without_depth(tmp_path: Path, capsys, suffix: str) -> None:
    """An all-zero (or NaN) video gave a black picture with exit 0, where run, view and
    export-ply refuse it."""
    np.save(tmp_path / "z.npy", np.zeros((3, 6, 8), np.float32))
    out = tmp_path / f"c.{suffix}"
    rc, _, err = run_cli(capsys, "compare", tmp_path / "z.npy", tmp_path / "z.npy", "-r", 1,
                         "-o", out, "-q")  # fmt: skip
    assert rc == 2 and "no valid depth in the frame(s) compared" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["z.npy"]
