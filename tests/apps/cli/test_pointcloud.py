"""``upsr export-ply``: back-projection and coloured PLY files."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.apps._util import scene
from upsr.apps.cli.main import main
from upsr.errors import InputError
from upsr.geometry.intrinsics import parse_intrinsics
from upsr.io.pointcloud import backproject

DATA = Path(__file__).parents[2] / "io" / "data" / "formats"


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


def test_a_failed_export_leaves_nothing_and_keeps_the_earlier_one(tmp_path: Path) -> None:
    """A frame refused part-way (a negative depth) left the files before it, and with
    --overwrite mixed the new frames into an earlier export: all or nothing now."""
    pytest.importorskip("plyfile")
    v = scene()
    bad = v.copy()
    bad[2, 1, 1] = -3.0
    np.save(tmp_path / "v.npy", v)
    np.save(tmp_path / "bad.npy", bad)
    cmd = ["-q", "--intrinsics", "20,20,7.5,5.5"]
    assert main(["export-ply", str(tmp_path / "bad.npy"), "-o", str(tmp_path / "a"), *cmd]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.npy", "v.npy"]
    out = tmp_path / "b"
    assert main(["export-ply", str(tmp_path / "v.npy"), "-o", str(out), *cmd]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert main(["export-ply", str(tmp_path / "bad.npy"), "-o", str(out), *cmd, "--overwrite"]) == 2
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b", "bad.npy", "v.npy"]
