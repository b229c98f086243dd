"""``upsr batch``: a real Dask cluster, failures reported per recording, resuming."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.apps._util import N, R, check_batch_output
from upsr.apps.cli.main import main


def test_batch_on_dask_cluster(videos, tmp_path: Path) -> None:
    distributed = pytest.importorskip("dask.distributed")
    d, ref = videos
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:
        code = main(
            [
                "batch",
                str(d / "a.npy"),
                str(d / "b.npy"),
                "--out",
                str(tmp_path),
                "-r",
                str(R),
                "-n",
                str(N),
                "--chunk-frames",
                "4",
                "--scheduler",
                cluster.scheduler_address,
                "-q",
            ]
        )
    assert code == 0
    check_batch_output(tmp_path, ref)


def test_batch_failures_and_resume(videos, tmp_path: Path, capsys) -> None:
    d, ref = videos
    bad = tmp_path / "bad.npy"
    bad.write_bytes(b"\x93NUMPY garbage")
    short = tmp_path / "short.npy"
    np.save(short, np.load(d / "b.npy")[:3])
    out = tmp_path / "out"
    args = [
        "batch",
        str(bad),
        str(d / "b.npy"),
        str(short),
        "--out",
        str(out),
        "-r",
        str(R),
        "-n",
        str(N),
        "-w",
        "1",
        "-q",
    ]
    assert main(args) == 2
    cap = capsys.readouterr()
    assert "1 done, 0 skipped (output exists), 2 failed" in cap.out
    assert "bad.npy: unsupported .npy format" in cap.err and "N=5 > 3 frames in" in cap.err
    np.testing.assert_array_equal(np.load(out / "b.npy"), ref["b"])
    assert sorted(p.name for p in out.iterdir()) == [".upsr-batch", "b.npy"]  # nothing partial
    assert [p.name for p in (out / ".upsr-batch" / "outputs").iterdir()] == ["b.npy.json"]
    # default N shrinks to a short recording, as in `upsr run`
    assert main(["batch", str(short), "--out", str(out), "-r", "1", "-q", "-w", "1"]) == 0
    assert np.load(out / "short.npy").shape == (3, 20, 24)
    # the same file twice (overlapping globs): once (it was refused: "give the recordings
    # different names"); two files of one name still are
    twice = tmp_path / "twice"
    assert main(["batch", str(d / "b.npy"), str(d / "b.npy"), "--out", str(twice), "-r", "2",
                 "-q", "-w", "1"]) == 0  # fmt: skip
    assert sorted(p.name for p in twice.iterdir()) == [".upsr-batch", "b.npy"]
    (tmp_path / "other").mkdir()
    np.save(tmp_path / "other" / "b.npy", np.load(d / "b.npy"))
    args = ["batch", str(d / "b.npy"), str(tmp_path / "other" / "b.npy"), "--out", str(twice)]
    assert main([*args, "-r", "2"]) == 2


def test_batch_checks_each_recordings_units_and_output_before_its_work(
    videos, tmp_path: Path, capsys
) -> None:
    """As `upsr run` does: a TUM PNG folder read as mm, an implausible depth with
    --strict-units and a PNG output that cannot hold the depth fail before their work, one
    line each; the other recordings are done."""
    import cv2

    d, ref = videos
    tum = tmp_path / "tum"
    tum.mkdir()
    for i, frame in enumerate(ref["b"][:, ::2, ::2] * 5):  # TUM: 5000 units per metre
        _, buf = cv2.imencode(".png", np.round(frame).astype(np.uint16))
        (tum / f"1305031102.{175304 + 33 * i}.png").write_bytes(buf.tobytes())
    far = tmp_path / "far.npy"
    far_video = np.load(d / "b.npy") * 100.0  # metres read as mm: 100-400 m
    far_video[0] = 0.0  # (an empty first frame: the units of the first with depth)
    np.save(far, far_video)
    out = tmp_path / "out"
    base = ["--out", str(out), "-r", str(R), "-n", str(N), "-w", "1", "-q"]
    assert main(["batch", str(tum), str(far), str(d / "b.npy"), *base, "--strict-units"]) == 2
    cap = capsys.readouterr()
    assert "1 done, 0 skipped (output exists), 2 failed" in cap.out
    assert "TUM" in cap.err and "far.npy" in cap.err
    assert sorted(p.name for p in out.iterdir()) == [".upsr-batch", "b.npy"]
    # the input depth scale given: the TUM folder is read in its units
    assert main(["batch", str(tum), *base, "--input-depth-scale", "5000"]) == 0
    assert np.load(out / "tum.npy").shape[0] == len(list(tum.iterdir()))
    # PNG output at 10 µm units: 65535 units hold 655 mm, the video's depth does not fit
    png = tmp_path / "png"
    args = ["batch", str(d / "b.npy"), "--out", str(png), "-r", str(R), "-n", str(N), "-w", "1"]
    assert main([*args, "-q", "--format", "png", "--output-depth-scale", "100000"]) == 2
    cap = capsys.readouterr()
    assert "1 failed" in cap.out and "b.npy" in cap.err
    assert not list(png.glob("b*"))  # nothing written for it


def test_batch_camera_motion_option(tmp_path: Path, capsys) -> None:
    """``upsr batch --camera-motion depth`` equals ``upsr run --camera-motion depth`` on each
    recording (its intrinsics from --intrinsics); without intrinsics one line per recording."""
    from upsr.research.synth.realistic import make_realistic

    v = make_realistic("toward_wall", (28, 32), scale=2, n_frames=8, seed=1)
    low = (v.lowres + np.random.default_rng(1).laplace(0.0, 7.0, v.lowres.shape)).astype(np.float32)
    np.save(tmp_path / "a.npy", low)
    c = v.camera
    intr = f"{c.fx},{c.fy},{c.cx},{c.cy}"
    common = ["-r", "2", "-n", "5", "-q", "--camera-motion", "depth"]
    run = ["run", str(tmp_path / "a.npy"), "-o", str(tmp_path / "run.npy"), *common]
    assert main([*run, "--intrinsics", intr]) == 0
    batch = ["batch", str(tmp_path / "a.npy"), "--out", str(tmp_path / "out"), "-w", "1"]
    assert main([*batch, *common, "--intrinsics", intr]) == 0
    np.testing.assert_array_equal(
        np.load(tmp_path / "out" / "a.npy"), np.load(tmp_path / "run.npy")
    )
    capsys.readouterr()
    assert main(["batch", str(tmp_path / "a.npy"), "--out", str(tmp_path / "o2"), *common]) == 2
    assert "needs the camera's intrinsics" in capsys.readouterr().err


def test_batch_and_run_valid_range(tmp_path: Path, capsys) -> None:
    """``--valid-range MIN,MAX``: a sensor's stray far values (65535 mm) are no measurement;
    ``upsr run`` equals the same video with them set to 0, ``upsr batch`` equals ``upsr run``;
    a bad range is one line."""
    rng = np.random.default_rng(0)
    ys, xs = np.mgrid[0:20, 0:24].astype(np.float32)
    video = np.stack([2000 + 5 * xs + 3 * ys + rng.normal(0, 5, xs.shape) for _ in range(6)])
    stray = rng.random(video.shape) < 0.02
    np.save(tmp_path / "a.npy", np.where(stray, 65535.0, video).astype(np.float32))
    np.save(tmp_path / "clean.npy", np.where(stray, 0.0, video).astype(np.float32))
    common = ["-r", "2", "-n", "3", "-q"]
    for mode in ([], ["--recursive"]):
        out, ref = tmp_path / f"run{len(mode)}.npy", tmp_path / f"ref{len(mode)}.npy"
        run = ["run", str(tmp_path / "a.npy"), "-o", str(out), *common, *mode]
        assert main([*run, "--valid-range", "100,10000"]) == 0
        assert main(["run", str(tmp_path / "clean.npy"), "-o", str(ref), *common, *mode]) == 0
        np.testing.assert_array_equal(np.load(out), np.load(ref))
        assert np.load(out).max() < 3000
    batch = ["batch", str(tmp_path / "a.npy"), "--out", str(tmp_path / "out"), "-w", "1"]
    assert main([*batch, *common, "--valid-range", "100,10000"]) == 0
    batched = np.load(tmp_path / "out" / "a.npy")
    np.testing.assert_array_equal(batched, np.load(tmp_path / "run0.npy"))
    capsys.readouterr()
    run = ["run", str(tmp_path / "a.npy"), "-o", str(tmp_path / "o.npy"), *common]
    for bad, message in (("4000,300", "0 <= min < max"), ("1,2,3", "MIN,MAX"), ("x", "MIN,MAX")):
        assert main([*run, "--valid-range", bad]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1
    assert main([*run, "--valid-range", "70000,80000"]) == 2
    assert "outside 70000-80000 mm" in capsys.readouterr().err
    assert not (tmp_path / "o.npy").exists()


def test_batch_takes_a_recording_whose_last_chunk_has_no_depth(tmp_path: Path, capsys) -> None:
    """A camera covered for the last frames: the chunks without depth give zeros, as one run
    does (the chunk's read and its engine refused it: the recording failed with 2 workers, not
    with 1); a recording without depth anywhere fails with one line."""
    rng = np.random.default_rng(0)
    ys, xs = np.mgrid[0:16, 0:20].astype(np.float32)
    video = np.stack([1500 + 4 * xs + 2 * ys + rng.normal(0, 3, xs.shape) for _ in range(12)])
    video[7:] = 0.0
    np.save(tmp_path / "covered.npy", video.astype(np.float32))
    common = ["-r", "2", "-n", "3", "-q"]
    assert (
        main(["run", str(tmp_path / "covered.npy"), "-o", str(tmp_path / "run.npy"), *common]) == 0
    )
    batch = ["batch", str(tmp_path / "covered.npy"), "--out", str(tmp_path / "out"), "-w", "2"]
    assert main([*batch, *common, "--chunk-frames", "4"]) == 0, capsys.readouterr().err
    np.testing.assert_array_equal(
        np.load(tmp_path / "out" / "covered.npy"), np.load(tmp_path / "run.npy")
    )
    np.save(tmp_path / "empty.npy", np.zeros_like(video, np.float32))
    capsys.readouterr()
    assert main(["batch", str(tmp_path / "empty.npy"), "--out", str(tmp_path / "o2"), *common]) == 2
    assert "no valid depth" in capsys.readouterr().err


def test_an_output_is_skipped_only_for_its_own_unchanged_input(tmp_path: Path, capsys) -> None:
    """day2/cam.npy was 'skipped (output exists)' beside day1/cam.npy's output, and an input
    changed after its output was made was skipped too: both refused now, one line each."""
    import os

    for day, t in (("day1", 6), ("day2", 5)):
        (tmp_path / day).mkdir()
        np.save(tmp_path / day / "cam.npy", np.full((t, 12, 16), 1500.0, np.float32))
    out = tmp_path / "res"
    base = ["--out", str(out), "-r", "2", "-n", "3", "-w", "1", "-q"]
    assert main(["batch", str(tmp_path / "day1" / "cam.npy"), *base]) == 0
    assert main(["batch", str(tmp_path / "day1" / "cam.npy"), *base]) == 0
    assert "0 done, 1 skipped" in capsys.readouterr().out
    assert main(["batch", str(tmp_path / "day2" / "cam.npy"), *base]) == 2
    assert "was made from another recording" in capsys.readouterr().err
    assert np.load(out / "cam.npy").shape == (6, 24, 32)
    src = tmp_path / "day1" / "cam.npy"
    st = os.stat(src)
    np.save(src, np.full((6, 12, 16), 1200.0, np.float32))
    os.utime(src, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert main(["batch", str(src), *base]) == 2
    assert "was made before cam.npy changed" in capsys.readouterr().err
    assert main(["batch", str(src), *base, "--overwrite"]) == 0
    assert np.load(out / "cam.npy").max() < 1300


def test_a_depth_scale_that_does_not_fit_one_recording_fails_that_one_only(
    tmp_path: Path, capsys
) -> None:
    """--input-depth-scale 1 for a folder of metres and a RealSense bag: the bag fails (its
    units are fixed), the other is done (the whole batch stopped before any work)."""
    bag = Path(__file__).parents[2] / "io" / "data" / "realsense" / "rs259_1mm.db3"
    np.save(tmp_path / "m.npy", np.full((4, 12, 16), 1.5, np.float32))
    out = tmp_path / "res"
    args = ["batch", str(bag), str(tmp_path / "m.npy"), "--out", str(out), "-r", "2", "-n", "3",
            "-w", "1", "-q", "--input-depth-scale", "1"]  # fmt: skip
    assert main(args) == 2
    cap = capsys.readouterr()
    assert "1 done, 0 skipped (output exists), 1 failed" in cap.out
    assert "does not apply to a RealSense recording, which carries its units" in cap.err
    assert np.median(np.load(out / "m.npy")) == pytest.approx(1500.0, abs=1.0)


def test_an_explicit_default_n_reuses_the_output(tmp_path: Path, capsys) -> None:
    """-n 9 on a 12-frame recording after a run without -n (N = 9 either way) was refused as
    made 'with other options (shrink_frames: True -> False)'."""
    np.save(tmp_path / "long.npy", np.full((12, 12, 16), 1500.0, np.float32))
    base = ["batch", str(tmp_path / "long.npy"), "--out", str(tmp_path / "res"), "-r", "2",
            "-w", "1", "-q"]  # fmt: skip
    assert main(base) == 0
    assert main([*base, "-n", "9"]) == 0
    assert "0 done, 1 skipped" in capsys.readouterr().out
    assert main([*base, "-n", "5"]) == 2  # (another N: refused without --overwrite)


def test_a_failure_line_keeps_its_advice(tmp_path: Path, capsys, monkeypatch) -> None:
    """Two absolute paths pushed the line past 200 characters and its middle (the advice)
    was cut out; paths under the current folder are relative now."""
    monkeypatch.chdir(tmp_path)
    deep = tmp_path / "in"
    deep.mkdir(parents=True)
    np.save(deep / "metres.npy", np.full((4, 12, 16), 2.09, np.float32))
    args = ["batch", str(deep / "metres.npy"), "--out", str(deep / "res"), "-r", "2", "-w", "1",
            "-q", "--strict-units"]  # fmt: skip
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "outside 50–100000 mm" in err and "…" not in err and str(tmp_path) not in err


def test_a_recording_named_as_the_batch_state_is_refused_before_any_work(
    tmp_path: Path, capsys
) -> None:
    np.save(tmp_path / ".upsr-batch.npy", np.full((4, 12, 16), 1500.0, np.float32))
    args = ["batch", str(tmp_path / ".upsr-batch.npy"), "--out", str(tmp_path / "res"), "-r",
            "2", "-f", "png", "-q"]  # fmt: skip
    assert main(args) == 2
    assert "would be the batch's own state" in capsys.readouterr().err
    assert not (tmp_path / "res").exists()
