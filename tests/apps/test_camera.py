"""Intrinsics: parsing, scaling, and the one camera look-up of the commands (upsr.apps._camera)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.apps._util import assert_user_error, run_cli, scene
from upsr.apps._camera import input_camera
from upsr.apps.batch import run_batch
from upsr.errors import InputError
from upsr.geometry.intrinsics import load_intrinsics, parse_intrinsics, write_intrinsics
from upsr.io import video as io
from upsr.method.config import UPSRConfig


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


# ---------------------------------------------------------------------------------------------
# the one look-up: --intrinsics, else what the input carries, else none
# ---------------------------------------------------------------------------------------------
def _video(tmp_path: Path, name: str = "in.npy") -> tuple[Path, object]:
    path = tmp_path / name
    np.save(path, scene())
    return path, io.probe(path)


def test_input_camera_flag_sidecar_or_none(tmp_path: Path) -> None:
    path, info = _video(tmp_path)
    assert input_camera(path, info, None, fmt=None, topic=None) is None
    cam = input_camera(path, info, "20,21,7.5,5.5", fmt=None, topic=None)
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (20, 21, 7.5, 5.5, 16, 12)
    write_intrinsics(io.intrinsics_path(path), parse_intrinsics("30,31,8,6", 16, 12))
    side = input_camera(path, info, None, fmt=None, topic=None)
    assert (side.fx, side.fy, side.cx, side.cy) == (30, 31, 8, 6)
    flag = input_camera(path, info, "20,21,7.5,5.5", fmt=None, topic=None)
    assert flag.fx == 20  # --intrinsics wins over the sidecar
    with pytest.raises(InputError):
        input_camera(path, info, "1,2", fmt=None, topic=None)


def test_input_camera_from_a_json_file(tmp_path: Path) -> None:
    """--intrinsics FILE.json: upsr's own sidecar, or an Open3D PinholeCameraIntrinsic (K
    column-major), made for the input's frame size."""
    path, info = _video(tmp_path)
    ours = write_intrinsics(tmp_path / "cam.json", parse_intrinsics("30,31,8,6", 16, 12))
    cam = input_camera(path, info, str(ours), fmt=None, topic=None)
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (30, 31, 8, 6, 16, 12)
    open3d = tmp_path / "open3d.json"
    matrix = [20.0, 0.0, 0.0, 0.0, 21.0, 0.0, 7.5, 5.5, 1.0]
    open3d.write_text(json.dumps({"width": 16, "height": 12, "intrinsic_matrix": matrix}))
    cam = input_camera(path, info, str(open3d), fmt=None, topic=None)
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (20, 21, 7.5, 5.5)
    other = write_intrinsics(tmp_path / "big.json", parse_intrinsics("30,31,8,6", 32, 24))
    with pytest.raises(InputError, match="intrinsics of 32x24 images, the input's frames are"):
        input_camera(path, info, str(other), fmt=None, topic=None)
    with pytest.raises(InputError, match="cannot read"):
        input_camera(path, info, str(tmp_path / "none.json"), fmt=None, topic=None)


def test_input_camera_reads_what_open3d_writes(tmp_path: Path) -> None:
    o3d = pytest.importorskip("open3d")
    path, info = _video(tmp_path)
    intr = o3d.camera.PinholeCameraIntrinsic(16, 12, 20.0, 21.0, 7.5, 5.5)
    o3d.io.write_pinhole_camera_intrinsic(str(tmp_path / "o3d.json"), intr)
    cam = input_camera(path, info, str(tmp_path / "o3d.json"), fmt=None, topic=None)
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (20, 21, 7.5, 5.5, 16, 12)


def _mismatched(tmp_path: Path) -> Path:
    path, _ = _video(tmp_path)
    write_intrinsics(io.intrinsics_path(path), parse_intrinsics("30,31,8,6", 32, 24))
    return path


def test_input_camera_refuses_intrinsics_of_another_size(tmp_path: Path) -> None:
    path = _mismatched(tmp_path)
    with pytest.raises(
        InputError, match="its intrinsics are for 32x24 images, the frames are 16x12"
    ):
        input_camera(path, io.probe(path), None, fmt=None, topic=None)
    # --intrinsics overrides a wrong sidecar
    cam = input_camera(path, io.probe(path), "20,21,7.5,5.5", fmt=None, topic=None)
    assert cam.width == 16


@pytest.mark.parametrize("command", ["run", "view", "export-ply"])
def test_every_command_uses_the_one_look_up(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    path = _mismatched(tmp_path)
    out = {"run": "o.npy", "view": "v.png", "export-ply": "ply"}[command]
    args = [command, str(path), "-o", str(tmp_path / out)]
    if command == "run":
        args += ["-r", "2", "-n", "3", "-q"]
    rc, stdout, err = run_cli(capsys, *args)
    assert_user_error(rc, stdout, err, "its intrinsics are for 32x24 images")
    assert not (tmp_path / out).exists()


def test_batch_uses_the_one_look_up(tmp_path: Path) -> None:
    path = _mismatched(tmp_path)
    cfg = UPSRConfig(scale=2, n_frames=3)
    res = run_batch([path], tmp_path / "out", cfg, workers=1, progress=False)
    (rec,) = res.recordings
    assert res.exit_code == 2 and rec.status == "failed" and rec.error_kind == "input"
    assert "its intrinsics are for 32x24 images" in rec.error
    res = run_batch(
        [path], tmp_path / "out", cfg, workers=1, progress=False, intrinsics="20,21,7.5,5.5"
    )
    assert res.exit_code == 0
    assert load_intrinsics(tmp_path / "out" / "in.npy.intrinsics.json").fx == 40
