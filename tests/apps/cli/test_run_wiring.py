"""``upsr run`` / ``upsr batch`` wiring of issues 13, 15 and 16: depth units, unit checks, ROS 2
bag output, frame names and timestamps, ``--color``, the kernel note, ``--max-memory`` and the
resource check, the intrinsics sidecar published with the video, one-line errors."""

from __future__ import annotations

import json
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile

import upsr
from tests.apps._util import H, T, W, png_folder, run_cli, video
from upsr.apps import _preflight
from upsr.errors import InputError
from upsr.io import identity
from upsr.io import video as io
from upsr.method import windowed as pipeline

FAST = ("-n", "3", "--no-deblur", "--quiet")


def _one_error(rc: int, err: str, match: str = "") -> None:
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1 and lines[0].startswith("upsr: error: "), err
    assert len(lines[0]) <= 200, lines[0]
    assert match in lines[0], lines[0]


@pytest.fixture
def here(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)  # short relative names: messages are not shortened
    return tmp_path


def _tif_metres(path: Path) -> Path:
    tifffile.imwrite(path, (video() / 1000.0).astype(np.float32))
    return path


# --------------------------------------------------------------------------------------------
# A1. input and output depth scales
# --------------------------------------------------------------------------------------------
def test_input_and_output_depth_scales_are_separate(capsys, here: Path) -> None:
    _tif_metres(here / "m.tif")
    rc, _, err = run_cli(capsys, "run", "m.tif", "-o", "mm.npy", "-r", 1, *FAST,
                         "--input-depth-scale", 1)  # fmt: skip
    assert rc == 0, err
    out = np.load("mm.npy")
    assert abs(np.median(out[out > 0]) - np.median(video())) < 50  # mm, not metres
    # the old spelling is the input's only: the .tif output stays in mm
    rc, _, err = run_cli(capsys, "run", "m.tif", "-o", "a.tif", "-r", 1, *FAST,
                         "--depth-scale", 1)  # fmt: skip
    assert rc == 0, err
    assert abs(np.median(tifffile.imread("a.tif")) - np.median(video())) < 50
    rc, _, err = run_cli(capsys, "run", "m.tif", "-o", "m_out.tif", "-r", 1, *FAST,
                         "--input-depth-scale", 1, "--output-depth-scale", 1)  # fmt: skip
    assert rc == 0, err
    assert abs(np.median(tifffile.imread("m_out.tif")) - np.median(video()) / 1000) < 0.05
    rc, _, err = run_cli(capsys, "run", "m.tif", "-o", "x.npy", "-r", 1, *FAST,
                         "--depth-scale", 1, "--input-depth-scale", 1000)  # fmt: skip
    _one_error(rc, err, "disagree")
    # an absurd scale is refused naming the option given (it said "depth_scale")
    for option in ("--input-depth-scale", "--output-depth-scale", "--depth-scale"):
        rc, _, err = run_cli(capsys, "run", "m.tif", "-o", "y.npy", "-r", 1, *FAST, option, 1e10)
        _one_error(rc, err, f"{option} must be 0.001..1e+09 raw units per metre")


def test_depth_scale_help_says_it_is_the_inputs_alias() -> None:
    from typer.testing import CliRunner

    from upsr.apps.cli.main import app

    text = " ".join(CliRunner().invoke(app, ["run", "--help"]).output.split())
    assert "Alias of --input-depth-scale" in text and "--output-depth-scale" in text


# --------------------------------------------------------------------------------------------
# A2. unit checks before processing
# --------------------------------------------------------------------------------------------
def _no_engine(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*a: object, **k: object) -> None:
        raise AssertionError("processing started")

    monkeypatch.setattr(pipeline, "UPSR", refuse)


def test_metres_read_as_mm_warn_or_refuse(capsys, here: Path, monkeypatch) -> None:
    _tif_metres(here / "m.tif")
    rc, _, err = run_cli(capsys, "run", "m.tif", "-o", "w.npy", "-r", 1, *FAST)
    assert rc == 0
    assert err.startswith("upsr: warning: ") and "--input-depth-scale 1" in err
    _no_engine(monkeypatch)
    rc, _, err = run_cli(capsys, "run", "m.tif", "-o", "s.npy", "-r", 1, *FAST, "--strict-units")
    _one_error(rc, err, "plausible")
    assert not Path("s.npy").exists()
    rc, _, err = run_cli(capsys, "run", "m.tif", "-o", "s.npy", "-r", 1, *FAST, "--sensor", "nope")
    assert rc == 2


def test_units_are_checked_on_the_first_frame_with_depth(capsys, here: Path, monkeypatch) -> None:
    """A camera's first frames are often empty: --strict-units looks at the first with depth
    (it passed a video in metres whose first frame was empty), and the frames read to find it
    are all processed."""
    v = video() / 1000.0  # metres
    v[:2] = 0.0
    np.save("m.npy", v)
    real = pipeline.UPSR
    _no_engine(monkeypatch)
    rc, _, err = run_cli(capsys, "run", "m.npy", "-o", "s.npy", "-r", 1, *FAST, "--strict-units")
    _one_error(rc, err, "--input-depth-scale 1")
    assert not Path("s.npy").exists()
    monkeypatch.setattr(pipeline, "UPSR", real)
    rc, _, err = run_cli(capsys, "run", "m.npy", "-o", "s.npy", "-r", 1, *FAST, "--strict-units",
                         "--input-depth-scale", 1)  # fmt: skip
    assert rc == 0, err
    out = np.load("s.npy")
    assert out.shape[0] == v.shape[0] and not out[:2].any() and out[2:].all()


def test_tum_pngs_read_as_mm_are_refused_before_processing(capsys, here: Path, monkeypatch) -> None:
    folder = here / "depth"
    folder.mkdir()
    for i, frame in enumerate(video() * 5):  # TUM: 5000 units per metre
        _, buf = cv2.imencode(".png", frame.astype(np.uint16))
        (folder / f"1305031102.{175304 + 33 * i}.png").write_bytes(buf.tobytes())
    real = pipeline.UPSR
    _no_engine(monkeypatch)
    rc, _, err = run_cli(capsys, "run", "depth", "-o", "t.npy", "-r", 1, *FAST)
    _one_error(rc, err, "TUM")
    assert not Path("t.npy").exists()
    monkeypatch.setattr(pipeline, "UPSR", real)
    for fix in (["--input-format", "tum"], ["--input-depth-scale", 5000]):
        rc, _, err = run_cli(capsys, "run", "depth", "-o", "t.npy", "-r", 1, *FAST, *fix,
                             "--overwrite")  # fmt: skip
        assert rc == 0, err
        out = np.load("t.npy")
        assert abs(np.median(out[out > 0]) - np.median(video())) < 50
    # a depth scale given for a format that fixes the units, even 1000 (mm), was ignored
    for cmd in (["run", "depth", "-o", "u.npy", "-r", 1, *FAST], ["batch", "depth", "--out", "b",
                "-r", 1, "-q"], ["view", "depth", "-o", "v.png"], ["export-ply", "depth", "-o",
                "ply", "--intrinsics", "50,50,7.5,5.5"]):  # fmt: skip
        rc, _, err = run_cli(capsys, *cmd, "--input-format", "tum", "--input-depth-scale", 1000)
        _one_error(rc, err, "--input-depth-scale does not apply to tum input")
    assert sorted(p.name for p in here.iterdir()) == ["depth", "t.npy"]


def test_a_sun_rgbd_png_read_as_mm_is_refused_with_the_right_format(capsys, here: Path) -> None:
    """A SUN RGB-D frame's raw values fit TUM's range too: the advice names SUN, and the
    frame read with it has the depth of ``--input-format sun``."""
    sun = Path(__file__).resolve().parents[2] / "io" / "data" / "formats" / "sun_depth_crop.png"
    rc, _, err = run_cli(capsys, "run", sun, "-o", "s.npy", "-r", 1, *FAST, "-n", 1)
    _one_error(rc, err, "use --input-format sun")
    assert "TUM" not in err and not Path("s.npy").exists()
    rc, _, err = run_cli(
        capsys, "run", sun, "-o", "s.npy", "-r", 1, *FAST, "-n", 1, "--input-format", "sun"
    )
    assert rc == 0, err


@pytest.mark.parametrize("suffix", ["exr", "png"])
def test_multi_frame_single_file_fails_before_processing(
    capsys, here: Path, monkeypatch, suffix: str
) -> None:
    np.save("in.npy", video())
    _no_engine(monkeypatch)
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", f"v.{suffix}", "-r", 2, *FAST)
    _one_error(rc, err, f"single .{suffix} file holds one frame")
    assert ".part" not in err and ".upsr" not in err
    assert sorted(p.name for p in here.iterdir()) == ["in.npy"]


# --------------------------------------------------------------------------------------------
# A3/A4. ROS 2 bag output; frame names and timestamps
# --------------------------------------------------------------------------------------------
def test_rosbag_output_with_camera_info(capsys, here: Path) -> None:
    np.savez("in.npz", depth=video(), timestamps=np.arange(T, dtype=np.int64) * 33_000_000 + 7)
    rc, _, err = run_cli(capsys, "run", "in.npz", "-o", "bag", "-r", 2, *FAST,
                         "--format", "rosbag", "--intrinsics", "20,21,7.5,5.5")  # fmt: skip
    assert rc == 0, err
    assert (here / "bag" / "metadata.yaml").is_file()
    back = upsr.io.read_video("bag")
    assert back.shape == (T, 2 * H, 2 * W)
    ref = upsr.io.read_video("in.npz")
    assert abs(np.median(back[back > 0]) - np.median(ref)) < 50
    np.testing.assert_array_equal(
        upsr.io.read_timestamps("bag"), np.arange(T, dtype=np.int64) * 33_000_000 + 7
    )
    cam = io.read_intrinsics("bag")
    assert cam is not None and (cam.width, cam.height) == (2 * W, 2 * H)
    assert cam.fx == pytest.approx(40.0) and cam.cx == pytest.approx(15.5)


def test_frame_names_and_timestamps_are_kept(capsys, here: Path) -> None:
    folder = here / "depth"
    folder.mkdir()
    names = [f"1305031102.{175304 + 33 * i}" for i in range(T)]
    for name, frame in zip(names, video(), strict=True):
        _, buf = cv2.imencode(".png", frame.astype(np.uint16))
        (folder / f"{name}.png").write_bytes(buf.tobytes())
    rc, _, err = run_cli(capsys, "run", "depth", "-o", "sr", "-r", 2, *FAST,
                         "--intrinsics", "20,20,7.5,5.5", "--input-depth-scale", 1000)  # fmt: skip
    assert rc == 0, err
    assert sorted(p.stem for p in (here / "sr").iterdir()) == names
    side = json.loads(Path("sr.intrinsics.json").read_text())
    assert side["frame_names"] == names
    stamps = side["timestamps_ns"]  # TUM names are seconds
    assert len(stamps) == T
    assert all(abs(t - float(n) * 1e9) < 1e3 for t, n in zip(stamps, names, strict=True))
    rc, _, err = run_cli(capsys, "run", "depth", "-o", "sr2", "-r", 2, *FAST, "--renumber",
                         "--input-depth-scale", 1000)  # fmt: skip
    assert rc == 0, err
    assert sorted(p.name for p in (here / "sr2").iterdir())[0] == "000000.png"


def test_npz_timestamps_travel_to_npz_output(capsys, here: Path) -> None:
    stamps = np.arange(T, dtype=np.int64) * 10 + 5
    np.savez("in.npz", depth=video(), timestamps=stamps)
    rc, _, err = run_cli(capsys, "run", "in.npz", "-o", "o.npz", "-r", 2, *FAST)
    assert rc == 0, err
    np.testing.assert_array_equal(np.load("o.npz")["timestamps"], stamps)


# --------------------------------------------------------------------------------------------
# A5. --color
# --------------------------------------------------------------------------------------------
def _colour_folder(folder: Path, n: int) -> Path:
    folder.mkdir()
    for i in range(n):
        img = np.full((H, W, 3), 40 * i, np.uint8)
        img[:, : W // 2, 2] = 255
        cv2.imwrite(str(folder / f"c{i:02d}.png"), img)
    return folder


def test_color_is_resampled_to_the_output_grid(capsys, here: Path, monkeypatch) -> None:
    np.save("in.npy", video())
    _colour_folder(here / "rgb", T)
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "sr", "-r", 2, *FAST, "--color", "rgb")
    assert rc == 0, err
    files = sorted((here / "sr.color").iterdir())
    assert [f.name for f in files] == sorted(p.name for p in (here / "sr").iterdir())
    img = cv2.imread(str(files[0]), cv2.IMREAD_UNCHANGED)
    assert img.shape == (2 * H, 2 * W, 3) and img.dtype == np.uint8
    # a wrong number of images, or an existing colour folder, fail before processing
    _no_engine(monkeypatch)
    _colour_folder(here / "rgb3", 3)
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "x", "-r", 2, *FAST, "--color", "rgb3")
    _one_error(rc, err, "colour image")
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "sr", "-r", 2, *FAST, "--color", "rgb")
    _one_error(rc, err, "exists")


# --------------------------------------------------------------------------------------------
# A6. the note while numba compiles
# --------------------------------------------------------------------------------------------
def test_kernel_note_on_a_cold_cache(capsys, here: Path, monkeypatch) -> None:
    np.save("in.npy", video())
    monkeypatch.setattr(_preflight, "kernel_cache_warm", lambda: False)
    monkeypatch.setitem(_preflight._STATE, "noted", False)
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "a.npy", "-r", 1, "-n", 1)
    assert rc == 0
    assert _preflight.KERNEL_NOTE in err
    monkeypatch.setitem(_preflight._STATE, "noted", False)
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "b.npy", "-r", 1, "-n", 1, "-q")
    assert rc == 0 and _preflight.KERNEL_NOTE not in err


def test_kernel_note_of_batch_and_demo(capsys, here: Path, monkeypatch) -> None:
    """`make demo` sat at 0/15 frames for 79 s on a cold cache without the note; batch too."""
    from upsr.apps import demo as demo_module

    np.save("in.npy", video())
    monkeypatch.setattr(_preflight, "kernel_cache_warm", lambda: False)
    monkeypatch.setitem(_preflight._STATE, "noted", False)
    rc, _, err = run_cli(capsys, "batch", "in.npy", "--out", "b", "-r", 1, "-n", 1)
    assert rc == 0 and _preflight.KERNEL_NOTE in err
    monkeypatch.setitem(_preflight._STATE, "noted", False)

    def no_demo(*args, **kwargs):
        raise InputError("stopped after the note")

    monkeypatch.setattr(demo_module, "run_demo", no_demo)
    rc, _, err = run_cli(capsys, "demo", "--out", "d")
    assert rc == 2 and _preflight.KERNEL_NOTE in err and "stopped after the note" in err


def test_recursive_refuses_the_windowed_modes_flags(capsys, here: Path) -> None:
    np.save("in.npy", video())
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "a.npy", "-r", 2, "--recursive",
                         "--no-registration-check")  # fmt: skip
    _one_error(rc, err, "check_registration (--no-registration-check): options of the windowed")
    assert not Path("a.npy").exists()
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "a.npy", "-r", 2, "--recursive", "-n", 13)
    assert rc == 0, err  # (N caps a pixel's state: any video length)


def test_the_intrinsics_file_beside_the_output_is_checked_before_processing(capsys, here: Path):
    """It replaced an --intrinsics input named so, and an existing file without --overwrite;
    a name too long for it failed after all the work."""
    np.save("in.npy", video())
    Path("o.npy.intrinsics.json").write_text('{"width": 16, "height": 12, "fx": 20, "fy": 20, '
                                             '"cx": 7.5, "cy": 5.5}')  # fmt: skip
    before = Path("o.npy.intrinsics.json").read_bytes()
    for extra in ([], ["--overwrite"]):
        rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "o.npy", "-r", 2, *FAST,
                             "--intrinsics", "o.npy.intrinsics.json", *extra)  # fmt: skip
        _one_error(rc, err, "would replace the input o.npy.intrinsics.json")
    assert Path("o.npy.intrinsics.json").read_bytes() == before and not Path("o.npy").exists()
    Path("w.npy.intrinsics.json").write_text("my notes")
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "w.npy", "-r", 2, *FAST,
                         "--intrinsics", "20,20,7.5,5.5")  # fmt: skip
    _one_error(rc, err, "w.npy.intrinsics.json already exists")
    long = "x" * 248 + ".npy"  # a legal name; its intrinsics file's is not
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", long, "-r", 2, *FAST,
                         "--intrinsics", "20,20,7.5,5.5")  # fmt: skip
    _one_error(rc, err, "longer than 255 bytes")
    assert sorted(p.name for p in here.iterdir()) == [
        "in.npy", "o.npy.intrinsics.json", "w.npy.intrinsics.json"
    ]  # fmt: skip


def test_quiet_keeps_the_summary_line_only(capsys, here: Path) -> None:
    np.save("in.npy", video())  # 5 frames: N = 5, a note without -q
    rc, out, err = run_cli(capsys, "run", "in.npy", "-o", "a.npy", "-r", 2, "--no-deblur")
    assert rc == 0 and "note: the video has 5 frame(s)" in err
    rc, out, err = run_cli(capsys, "run", "in.npy", "-o", "b.npy", "-r", 2, "--no-deblur", "-q")
    assert rc == 0 and err == "" and len(out.strip().splitlines()) == 1


# --------------------------------------------------------------------------------------------
# B. resources, sidecar, output paths, one-line errors
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("cmd", ["run", "batch"])
def test_huge_work_is_refused_at_once(capsys, here: Path, cmd: str) -> None:
    np.save("in.npy", np.full((3, 56, 64), 1500, np.float32))
    where = ["-o", "o.npy"] if cmd == "run" else ["--out", "o"]
    start = time.perf_counter()
    rc, _, err = run_cli(capsys, cmd, "in.npy", *where, "-r", 150, "-n", 3)
    assert rc == 2 and "150" in err and len(err.strip().splitlines()) == 1
    # within the bound on r, the memory model refuses (and --max-memory lowers the limit)
    rc, _, err = run_cli(capsys, cmd, "in.npy", *where, "-r", 16, "-n", 3, "--max-memory", "10M")
    assert time.perf_counter() - start < 10
    if cmd == "run":
        _one_error(rc, err, "--max-memory")
    else:
        assert rc == 2 and "--max-memory" in err, err
    assert not Path("o.npy").exists() and not list(Path().glob("o/*.npy"))
    rc, _, err = run_cli(capsys, cmd, "in.npy", *where, "-r", 2, "-n", 3, "--max-memory", "lots")
    _one_error(rc, err, "--max-memory")


def test_max_memory_sets_the_frame_budget(capsys, here: Path) -> None:
    from upsr.io import _base

    np.save("in.npy", video())
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "o.npy", "-r", 1, *FAST,
                         "--max-memory", "1G")  # fmt: skip
    assert rc == 0, err
    assert _base.frame_budget() == (1 << 30) // 4
    run_cli(capsys, "run", "in.npy", "-o", "p.npy", "-r", 1, *FAST)
    assert _base._FRAME_BUDGET is None


def test_failing_sidecar_leaves_no_video(capsys, here: Path, monkeypatch) -> None:
    np.save("in.npy", video())

    def full(self: object, path: object, data: object) -> None:
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(io.VideoWriter, "add_sidecar", full)
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "o.npy", "-r", 2, *FAST,
                         "--intrinsics", "20,20,7.5,5.5")  # fmt: skip
    assert rc != 0 and "No space left" in err
    assert sorted(p.name for p in here.iterdir()) == ["in.npy"]


def test_output_inside_the_input_folder_is_refused_even_with_overwrite(capsys, here: Path) -> None:
    png_folder(here / "in", video())
    rc, _, err = run_cli(capsys, "run", "in", "-o", "in/x.npy", "-r", 2, *FAST, "--overwrite")
    _one_error(rc, err, "inside the input folder")
    rc, _, err = run_cli(capsys, "run", "in", "-o", "in", "-r", 2, *FAST, "--overwrite")
    _one_error(rc, err, "is the input")


def test_long_input_errors_are_one_line_of_200(capsys, here: Path, monkeypatch) -> None:
    np.save("in.npy", video())

    def boom(*a: object, **k: object) -> None:
        raise upsr.InputError("bad " + "x" * 1000 + "\n(the cause)")

    monkeypatch.setattr(io, "probe", boom)
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "o.npy", "-r", 2)
    _one_error(rc, err, "(the cause)")


# --------------------------------------------------------------------------------------------
# C. issue 13 flags reach the config, in run and batch alike
# --------------------------------------------------------------------------------------------
def test_issue13_flags_reach_the_config(capsys, here: Path, monkeypatch) -> None:
    seen = {}
    real = pipeline.UPSR

    class Spy(real):  # type: ignore[misc,valid-type]
        def __init__(self, *a: object, **k: object) -> None:
            super().__init__(*a, **k)
            seen["cfg"] = self.config

    monkeypatch.setattr(pipeline, "UPSR", Spy)
    np.save("in.npy", video())
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "o.npy", "-r", 2, *FAST, "--fill-holes",
                         "--no-trust", "--fusion-estimator", "mean", "--no-mixed-removal",
                         "--no-radial", "--no-registration-check", "--no-edge-votes",
                         "--no-thin-parts", "--noise-model", "constant")  # fmt: skip
    assert rc == 0, err
    cfg = seen["cfg"]
    assert not cfg.edge_votes and not cfg.thin_parts
    assert cfg.fill_holes and cfg.trust_k is None and cfg.fusion_estimator == "mean"
    assert cfg.trust_noise_profile == "constant"
    assert cfg.remove_mixed is False and not cfg.radial_compensation
    assert not cfg.check_registration
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "p.npy", "-r", 2, *FAST, "--trust-k", 2.5)
    assert rc == 0 and seen["cfg"].trust_k == 2.5 and not seen["cfg"].fill_holes
    assert seen["cfg"].remove_mixed == "auto" and seen["cfg"].radial_compensation
    assert seen["cfg"].trust_noise_profile == "auto"
    assert seen["cfg"].check_registration and seen["cfg"].edge_votes and seen["cfg"].thin_parts
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "m.npy", "-r", 2, *FAST, "--mixed-removal")
    assert rc == 0 and seen["cfg"].remove_mixed is True
    rc, _, err = run_cli(capsys, "run", "in.npy", "-o", "q.npy", "-r", 2, *FAST, "--trust-k", 2,
                         "--no-trust")  # fmt: skip
    _one_error(rc, err, "--no-trust")


def test_batch_output_scale_names_and_sidecar(capsys, here: Path) -> None:
    png_folder(here / "rec", video())
    rc, _, err = run_cli(capsys, "batch", "rec", "--out", "out", "-r", 2, "-n", 3, "-w", 1,
                         "--format", "png", "--output-depth-scale", 5000, "--no-deblur", "-q",
                         "--intrinsics", "20,20,7.5,5.5")  # fmt: skip
    assert rc == 0, err
    files = sorted((here / "out" / "rec").iterdir())
    assert [f.name for f in files] == [f"{i:03d}.png" for i in range(T)]
    raw = cv2.imread(str(files[0]), cv2.IMREAD_UNCHANGED)
    assert abs(np.median(raw[raw > 0]) / 5 - np.median(video())) < 50
    side = json.loads((here / "out" / "rec.intrinsics.json").read_text())
    assert side["frame_names"] == [f"{i:03d}" for i in range(T)]


def test_timestamps_that_go_back_are_kept_with_a_warning(capsys, here: Path) -> None:
    """A camera clock reset (times 30, 40, 10 ms) refused the whole recording ("timestamps go
    back in time", even for a .npy output); now kept as recorded, with one warning."""
    np.savez("in.npz", depth=video()[:3], timestamps=np.array([30, 40, 10]) * 10**6)
    rc, _, err = run_cli(capsys, "run", "in.npz", "-o", "out.npz", "-r", 1, *FAST)
    assert rc == 0, err
    assert "warning: in.npz: the timestamps go back in time at frame 2" in err
    stamps = identity.read_timestamps(Path("out.npz"))
    np.testing.assert_array_equal(stamps, np.array([30, 40, 10]) * 10**6)


def test_a_bags_16_bit_depth_in_other_units_takes_the_input_depth_scale(capsys, here: Path) -> None:
    """realsense-ros publishes a D405's raw 0.1 mm units as 16UC1: the output was 10 times
    too deep, and --input-depth-scale 10000 was refused for any bag. 16-bit depth takes it;
    32FC1 (metres, REP 117) and a RealSense recording (its own units) refuse it, even 1000."""
    from tests.io import bagtools

    raw = np.full((3, 6, 8), 15000, np.uint16)  # 1500 mm at 0.1 mm
    bagtools.ros2_bag(here / "d405", list(raw), encoding="16UC1")
    rc, _, err = run_cli(capsys, "run", "d405", "-o", "a.npy", "-r", 1, *FAST,
                         "--input-depth-scale", 10000)  # fmt: skip
    assert rc == 0, err
    assert np.median(np.load("a.npy")) == pytest.approx(1500.0, abs=1.0)
    bagtools.ros2_bag(here / "m", list(raw / 10000.0), encoding="32FC1")
    rc, _, err = run_cli(capsys, "run", "m", "-o", "b.npy", "-r", 1, *FAST,
                         "--input-depth-scale", 1000)  # fmt: skip
    _one_error(rc, err, "does not apply to 32FC1 depth, in metres")
    assert not Path("b.npy").exists()
