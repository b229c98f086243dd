"""``upsr run``: success paths, options, every kind of bad input, exit codes, no debris."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

import upsr
from tests.apps._util import (
    H,
    T,
    W,
    assert_user_error,
    digest,
    listing,
    png_folder,
    run_cli,
    scene,
    video,
)
from upsr.apps.cli.main import main
from upsr.io import video as io
from upsr.method import windowed as pipeline


@pytest.fixture(params=["npy", "npz", "png"])
def video_input(request: pytest.FixtureRequest, tmp_path: Path) -> Path:
    v = video()
    if request.param == "npy":
        np.save(tmp_path / "in.npy", v)
        return tmp_path / "in.npy"
    if request.param == "npz":
        np.savez_compressed(tmp_path / "in.npz", depth=v)
        return tmp_path / "in.npz"
    return png_folder(tmp_path / "in", v)


@pytest.mark.parametrize("out_name", ["out.npy", "out.npz", "out"])
def test_run_success(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, video_input: Path, out_name: str
) -> None:
    before = digest(video_input)
    out = tmp_path / "res" / out_name
    rc, stdout, stderr = run_cli(capsys, "run", video_input, "-o", out, "-r", 2, "-n", 3, "--quiet")
    assert rc == 0, stderr
    assert stderr == ""
    lines = stdout.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"upsr: {T} frames {W}x{H} -> {2 * W}x{2 * H} (r=2, N=3) in ")
    assert lines[0].endswith(f"-> {out}")
    result = upsr.io.read_video(out)
    assert result.dtype == np.float32 and result.shape == (T, 2 * H, 2 * W)
    assert (result > 0).mean() > 0.9
    assert abs(float(np.median(result[result > 0])) - np.median(video())) < 100
    assert digest(video_input) == before  # the input is untouched
    if out.suffix == ".npy":
        raw = np.load(out, allow_pickle=False)
        assert raw.dtype == np.float32 and raw.shape == (T, 2 * H, 2 * W)
    assert [p.name for p in out.parent.iterdir()] == [out.name]  # no temporaries left


def test_run_options_reach_the_config(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    seen = {}
    real = pipeline.UPSR

    class Spy(real):  # type: ignore[misc,valid-type]
        def __init__(self, *a: object, **k: object) -> None:
            super().__init__(*a, **k)
            seen["cfg"] = self.config
            seen["workers"] = self.workers

    monkeypatch.setattr(pipeline, "UPSR", Spy)
    np.save(tmp_path / "in.npy", video())
    rc, _, err = run_cli(
        capsys,
        "run",
        tmp_path / "in.npy",
        "-o",
        tmp_path / "o.npy",
        "-r",
        3,
        "-n",
        5,
        "--lam",
        0.25,
        "--alpha",
        0.5,
        "--btv-radius",
        3,
        "--iterations",
        4,
        "--blur",
        "box",
        "--flow",
        "farneback",
        "--flow-preset",
        "fast",
        "--flow-scale",
        2,
        "--refine-preset",
        "ultrafast",
        "--speckle-px",
        0,
        "--no-refine",
        "--workers",
        0,
        "-q",
    )
    assert rc == 0, err
    assert seen["workers"] == 0
    cfg = seen["cfg"]
    assert (cfg.flow_scale, cfg.refine_preset) == (2, "ultrafast")
    assert cfg.speckle_size_px == 0
    assert (cfg.scale, cfg.n_frames, cfg.flow, cfg.flow_preset, cfg.refine) == (
        3,
        5,
        "farneback",
        "fast",
        False,
    )
    d = cfg.deblur
    assert (d.enabled, d.lam, d.alpha, d.radius_px, d.iterations, d.blur) == (
        True,
        0.25,
        0.5,
        3,
        4,
        "box",
    )
    rc, _, err = run_cli(
        capsys,
        "run",
        tmp_path / "in.npy",
        "-o",
        tmp_path / "o2.npy",
        "-r",
        1,
        "-n",
        1,
        "--no-deblur",
        "--keep-all-motion",
        "-q",
    )
    assert rc == 0, err
    assert seen["cfg"].deblur.enabled is False
    assert seen["cfg"].zero_motion_tolerance is None


def test_run_png_depth_scale_and_overwrite(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    v = video()
    png_folder(tmp_path / "tum", v * 5)  # TUM: raw = mm * 5
    out = tmp_path / "out"
    args = [
        "run",
        tmp_path / "tum",
        "-o",
        out,
        "-r",
        1,
        "-n",
        1,
        "--no-deblur",
        "-q",
        "--depth-scale",
        5000,
        "--format",
        "npy",
    ]
    rc, _, err = run_cli(capsys, *args)
    assert rc == 0, err
    np.testing.assert_allclose(np.load(out), v, atol=1e-3)  # r=1, N=1, no deblur: identity
    rc, _, err = run_cli(capsys, *args)
    assert_user_error(rc, "", err, "already exists")
    rc, _, err = run_cli(capsys, *args, "--overwrite")
    assert rc == 0, err


def test_progress_bar_on_stderr(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    np.save(tmp_path / "in.npy", video())
    rc, out, err = run_cli(
        capsys, "run", tmp_path / "in.npy", "-o", tmp_path / "o.npy", "-r", 2, "-n", 3
    )
    assert rc == 0
    assert "frame" in err and len(out.strip().splitlines()) == 1


def _npy(arr: np.ndarray) -> Callable[[Path], Path]:
    def make(d: Path) -> Path:
        np.save(d / "in.npy", arr, allow_pickle=arr.dtype == object)
        return d / "in.npy"

    return make


def _npz(arr: np.ndarray) -> Callable[[Path], Path]:
    def make(d: Path) -> Path:
        np.savez(d / "in.npz", arr)
        return d / "in.npz"

    return make


def _with(index: tuple[int, ...], value: float) -> np.ndarray:
    v = video()
    v[index] = value
    return v


def _truncated(d: Path) -> Path:
    np.save(d / "in.npy", video())
    data = (d / "in.npy").read_bytes()
    (d / "in.npy").write_bytes(data[: len(data) - 100])
    return d / "in.npy"


def _corrupt_npz(d: Path) -> Path:
    np.savez_compressed(d / "in.npz", depth=video())
    data = bytearray((d / "in.npz").read_bytes())
    data[80:140] = bytes(60)
    (d / "in.npz").write_bytes(bytes(data))
    return d / "in.npz"


def _not_a_zip(d: Path) -> Path:
    (d / "in.npz").write_bytes(b"this is not a zip file at all")
    return d / "in.npz"


def _mixed_png(d: Path) -> Path:
    f = png_folder(d / "in", video())
    _ok, buf = cv2.imencode(".png", np.ones((H, W + 2), np.uint16))
    (f / "002.png").write_bytes(buf.tobytes())
    return f


def _png8(d: Path) -> Path:
    return png_folder(d / "in", np.clip(video() / 20, 0, 255), np.uint8)


def _png_rgb(d: Path) -> Path:
    return png_folder(d / "in", np.repeat(video()[..., None], 3, axis=-1))


def _corrupt_png(d: Path) -> Path:
    f = png_folder(d / "in", video())
    data = bytearray((f / "003.png").read_bytes())
    data[50:60] = bytes(10)
    (f / "003.png").write_bytes(bytes(data))
    return f


def _truncated_png(d: Path) -> Path:
    f = png_folder(d / "in", video())
    data = (f / "001.png").read_bytes()
    (f / "001.png").write_bytes(data[:-40])
    return f


def _empty_folder(d: Path) -> Path:
    (d / "in").mkdir()
    return d / "in"


def _missing(d: Path) -> Path:
    return d / "nothere.npy"


def _wrong_suffix(d: Path) -> Path:
    (d / "in.mp4").write_bytes(b"\x00" * 100)
    return d / "in.mp4"


def _unreadable(d: Path) -> Path:
    np.save(d / "in.npy", video())
    (d / "in.npy").chmod(0)
    return d / "in.npy"


BAD_INPUTS: dict[str, tuple[Callable[[Path], Path], str]] = {
    "2d_npy": (_npy(video()[0]), "shape (T, h, w)"),
    "4d_npy": (_npy(video()[None]), "shape (T, h, w)"),
    "complex_npy": (_npy(video().astype(np.complex64)), "numeric"),
    "bool_npy": (_npy(video() > 0), "numeric"),
    "string_npy": (_npy(video().astype(str)), "numeric"),
    "object_npy": (_npy(video().astype(object)), "object arrays"),
    "object_npz": (_npz(video().astype(object)), "object arrays"),
    "complex_npz": (_npz(video().astype(np.complex128)), "numeric"),
    "2d_npz": (_npz(video()[0]), "shape (T, h, w)"),
    "plus_inf": (_npy(_with((3, 2, 2), np.inf)), "frame 3"),
    "minus_inf": (_npy(_with((1, 2, 2), -np.inf)), "frame 1"),
    "negative": (_npy(_with((4, 5, 5), -1.0)), "frame 4: depth contains negative"),
    "negative_npz": (_npz(_with((2, 5, 5), -3.0)), "frame 2"),
    "all_zero": (_npy(np.zeros((T, H, W), np.float32)), "no valid depth"),
    "all_nan": (_npy(np.full((T, H, W), np.nan, np.float32)), "no valid depth"),
    "empty_npy": (_npy(np.zeros((0, H, W), np.float32)), "empty"),
    "truncated_npy": (_truncated, "truncated"),
    "corrupt_npz": (_corrupt_npz, "in.npz"),
    "not_a_zip": (_not_a_zip, "in.npz"),
    "mixed_png_sizes": (_mixed_png, "002.png: frame size"),
    "png_8bit": (_png8, "8-bit"),
    "png_rgb": (_png_rgb, "RGB"),
    "corrupt_png": (_corrupt_png, "003.png"),
    "truncated_png": (_truncated_png, "001.png"),
    "empty_folder": (_empty_folder, "no PNG frames"),
    "nonexistent": (_missing, "no such file"),
    "unknown_suffix": (_wrong_suffix, "unknown input format"),
}


if os.geteuid() != 0:  # root can read anything
    BAD_INPUTS["unreadable"] = (_unreadable, "cannot read")


def _refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, case: str, *options: object
) -> None:
    """``upsr run`` on the bad input ``case`` with ``options``: exit 2 with one line, no
    output, the input folder untouched."""
    make, match = BAD_INPUTS[case]
    d = tmp_path / "work"
    d.mkdir()
    inp = make(d)
    before = listing(d)
    out = tmp_path / "out" / "result.npy"
    rc, stdout, err = run_cli(capsys, "run", inp, "-o", out, "-r", 2, *options)
    # the progress bar may have been drawn (and erased with \r) before the error
    assert_user_error(rc, stdout, err.split("\r")[-1], match)
    assert not (tmp_path / "out").exists()
    assert listing(d) == before


@pytest.mark.parametrize("quiet", [True, False], ids=["quiet", "bar"])
@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, case: str, quiet: bool
) -> None:
    _refused(capsys, tmp_path, case, "-n", 3, *(["--quiet"] if quiet else []))


@pytest.mark.parametrize(
    "case", ["plus_inf", "minus_inf", "negative", "negative_npz", "all_zero", "all_nan"]
)
def test_bad_frames_in_recursive_mode(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, case: str
) -> None:
    """A bad frame in the middle of a video, with each frame finished on a helper thread
    while the next updates the state: the same one-line error, no output."""
    _refused(capsys, tmp_path, case, "--recursive", "--quiet")


def test_empty_frame_in_the_middle_is_fine(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    v = video()
    v[2] = 0
    v[3, :4] = np.nan
    np.save(tmp_path / "in.npy", v)
    rc, _, err = run_cli(
        capsys, "run", tmp_path / "in.npy", "-o", tmp_path / "o.npy", "-r", 2, "-n", 3, "-q"
    )
    assert rc == 0, err
    assert np.load(tmp_path / "o.npy").shape == (T, 2 * H, 2 * W)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["-r", "0"], "--scale (-r) must be an integer >= 1"),
        (["-r", "-2"], "--scale (-r) must be an integer >= 1"),
        (["-r", "1.5"], "--scale"),
        (["-r", "x"], "--scale"),
        (["-r", "2", "-n", "0"], "--frames (-n) must be an integer >= 1"),
        (["-r", "2", "-n", "-1"], "--frames (-n)"),
        (["-r", "2", "-n", "6"], "N=6 > 5 frames"),
        (["-r", "2", "-n", "3", "--lam", "-1"], "lam"),
        (["-r", "2", "-n", "3", "--alpha", "0"], "alpha"),
        (["-r", "2", "-n", "3", "--btv-radius", "0"], "radius"),
        (["-r", "2", "-n", "3", "--iterations", "-1"], "iterations"),
        (["-r", "2", "-n", "3", "--blur", "median"], "--blur"),
        (["-r", "2", "-n", "3", "--flow", "raft"], "--flow"),
        (["-r", "2", "-n", "3", "--flow-scale", "3"], "flow_scale"),
        (["-r", "2", "-n", "3", "--flow-scale", "0"], "--flow-scale"),
        (["-r", "2", "-n", "3", "--refine-preset", "slow"], "--refine-preset"),
        (["-r", "2", "-n", "3", "--speckle-px", "-1"], "--speckle-px"),
        (["-r", "2", "-n", "3", "--workers", "-1"], "--workers"),
        (["-r", "2", "-n", "3", "--depth-scale", "0"], "--depth-scale must be"),
        (["-r", "2", "-n", "3", "--key", "depth"], "only applies to .npz"),
        (["-r", "2", "-n", "3", "--bogus"], "No such option"),
        (["-n", "3"], "Missing option '--scale'"),
    ],
)
def test_bad_options(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, args: list[str], match: str
) -> None:
    np.save(tmp_path / "in.npy", video())
    rc, out, err = run_cli(capsys, "run", tmp_path / "in.npy", "-o", tmp_path / "o.npy", *args)
    assert_user_error(rc, out, err, match)
    assert listing(tmp_path) == ["in.npy"]


def test_missing_output_option(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    np.save(tmp_path / "in.npy", video())
    rc, out, err = run_cli(capsys, "run", tmp_path / "in.npy", "-r", "2")
    assert_user_error(rc, out, err, "Missing option '--output'")


def test_output_is_input_or_exists(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    np.save(tmp_path / "in.npy", video())
    frames = png_folder(tmp_path / "frames", video())
    before = digest(tmp_path)
    common = ["-r", "2", "-n", "3", "-q"]
    cases = [
        (["run", tmp_path / "in.npy", "-o", tmp_path / "in.npy", "--overwrite"], "is the input"),
        (["run", tmp_path / "in.npy", "-o", tmp_path / "in.npy"], "is the input"),
        (["run", frames, "-o", frames, "--overwrite"], "is the input"),
        (["run", tmp_path / "in.npy", "-o", tmp_path, "--overwrite"], "contains the input"),
        (["run", tmp_path / "in.npy", "-o", frames], "already exists"),
        (["run", tmp_path / "in.npy", "-o", tmp_path / "o.mp4"], "unknown output format"),
    ]
    for args, match in cases:
        rc, out, err = run_cli(capsys, *args, *common)
        assert_user_error(rc, out, err, match)
    assert digest(tmp_path) == before


def test_default_window_shrinks_to_a_short_video_but_explicit_n_does_not(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    src = tmp_path / "short.npy"
    np.save(src, video(t=4))
    out = tmp_path / "out.npy"
    rc, stdout, err = run_cli(capsys, "run", src, "-o", out, "-r", 2)
    assert rc == 0, err
    assert "N=4" in stdout and "N = 4" in err  # (a note, not with --quiet)
    assert np.load(out).shape == (4, 2 * H, 2 * W)
    rc, stdout, err = run_cli(capsys, "run", src, "-o", tmp_path / "o2.npy", "-r", 2, "-n", 9)
    assert_user_error(rc, stdout, err, "N=9 > 4 frames")
    assert not (tmp_path / "o2.npy").exists()


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


def test_run_registers_by_the_cameras_motion_from_depth(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """--camera-motion depth takes the input's intrinsics; the output equals the API's, in
    both modes; without intrinsics one line and exit 2, nothing written."""
    from upsr.research.synth.realistic import make_realistic

    v = make_realistic("toward_wall", (28, 32), scale=2, n_frames=5, seed=0)
    low = v.lowres + np.random.default_rng(0).laplace(0.0, 7.0, v.lowres.shape)
    np.save(tmp_path / "in.npy", low.astype(np.float32))
    c = v.camera
    intr = f"{c.fx},{c.fy},{c.cx},{c.cy}"
    out = tmp_path / "out.npy"
    args = ["run", tmp_path / "in.npy", "-o", out, "-r", 2, "-n", 5, "--quiet",
            "--camera-motion", "depth"]  # fmt: skip
    rc, _, err = run_cli(capsys, *args)
    assert rc == 2 and not out.exists()
    assert err.strip().splitlines() == [
        "upsr: error: --camera-motion depth needs the camera's intrinsics: --intrinsics "
        "FX,FY,CX,CY or intrinsics carried by the input"
    ]
    for mode in ("windowed", "recursive"):
        flags = ["--recursive"] if mode == "recursive" else []
        rc, _, err = run_cli(capsys, *args, "--intrinsics", intr, "--overwrite", *flags)
        assert rc == 0, err
        low = np.load(tmp_path / "in.npy")
        expected = upsr.super_resolve(low, 2, 5, mode=mode, camera_motion="depth",
                                      camera_intrinsics=(c.fx, c.fy, c.cx, c.cy))  # fmt: skip
        np.testing.assert_allclose(np.load(out), expected, atol=1e-3)
        assert not np.array_equal(expected, upsr.super_resolve(low, 2, 5, mode=mode))


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


def test_run_reports_the_per_video_choices(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, video_input: Path
) -> None:
    """Without --quiet, what ``fusion_estimator="auto"`` and the trust chose for the video
    (upsr.method.statistics) is one line on stderr; with --quiet nothing."""
    out = tmp_path / "out.npy"
    rc, stdout, stderr = run_cli(capsys, "run", video_input, "-o", out, "-r", 2, "-n", 3)
    assert rc == 0, stderr
    line = [s for s in stderr.replace("\r", "\n").splitlines() if "fused by the" in s]
    assert len(line) == 1 and line[0].startswith("upsr: fused by the m")
    assert "mm" in line[0] and "mixed pixels" in line[0] and "depth thresholds" not in line[0]
    assert len(stdout.strip().splitlines()) == 1
    # a scene 10 times nearer (below 1 m): its thresholds scaled, said on the same line
    near = tmp_path / "near.npy"
    np.save(near, video() * 0.1)
    rc, _, stderr = run_cli(capsys, "run", near, "-o", tmp_path / "n.npy", "-r", 2, "-n", 3)
    assert rc == 0, stderr
    assert "depth thresholds x0." in stderr and "(a near scene)" in stderr
    # the recursive mode's choices too (it printed none)
    rc, _, stderr = run_cli(capsys, "run", near, "-o", tmp_path / "r.npy", "-r", 2, "--recursive")
    assert rc == 0, stderr
    line = [s for s in stderr.replace("\r", "\n").splitlines() if "fused by the" in s]
    assert len(line) == 1 and line[0].startswith("upsr: fused by the mean")
    assert "depth thresholds x0." in line[0] and "(a near scene)" in line[0]


def test_run_says_where_a_far_kinect_video_is_companded(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A Kinect's disparity levels beyond ~5.8 m (upsr.method.companding): said on the choices
    line, in both modes; not for continuous depth (the test above)."""
    from upsr.research.synth.degradation import kinect

    wall = np.round(kinect(np.full((5, 16, 20), 7000.0), np.random.default_rng(0)))
    src = tmp_path / "wall.npy"
    np.save(src, wall.astype(np.uint16))
    for extra in ((), ("--recursive",)):
        out = tmp_path / f"o{len(extra)}.npy"
        rc, _, stderr = run_cli(capsys, "run", src, "-o", out, "-r", 2, "-n", 3, *extra)
        assert rc == 0, stderr
        assert "disparity levels: depth companded beyond 5.7" in stderr
        assert abs(np.median(np.load(out)[:, 4:-4, 4:-4]) - 7000.0) < 60.0
    # --no-compand: the levels stay surfaces of their own (the wall a staircase)
    out = tmp_path / "off.npy"
    rc, _, stderr = run_cli(capsys, "run", src, "-o", out, "-r", 2, "-n", 3, "--no-compand")
    assert rc == 0, stderr
    assert "companded" not in stderr
    assert not np.array_equal(np.load(out), np.load(tmp_path / "o0.npy"))
