"""upsr batch: chunks equal to single runs, local processes and a real Dask cluster, resuming."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import upsr
from upsr.apps.batch import chunk_plan, run_batch
from upsr.apps.cli.main import main
from upsr.errors import InputError
from upsr.method.config import UPSRConfig
from upsr.method.windowed import window_start
from upsr.research.synth.scenes import dynamic_scene

R, N = 2, 5


@pytest.fixture(scope="module")
def videos(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, np.ndarray]]:
    """Two short noisy moving scenes (13 and 9 frames) and their single-run results."""
    d = tmp_path_factory.mktemp("rec")
    a = dynamic_scene(n_frames=13, lowres_shape=(20, 24), scale=R, noise_sigma_mm=20, seed=1)
    b = dynamic_scene(n_frames=9, lowres_shape=(20, 24), scale=R, noise_sigma_mm=30, seed=2)
    np.save(d / "a.npy", a.lowres)
    np.save(d / "b.npy", b.lowres)
    ref = {k: upsr.super_resolve(v.lowres, R, N) for k, v in (("a", a), ("b", b))}
    return d, ref


@settings(max_examples=60, deadline=None)
@given(t=st.integers(1, 40), n=st.integers(1, 12), m=st.integers(1, 15))
def test_chunk_windows_match_single_run(t: int, n: int, m: int) -> None:
    if n > t:
        with pytest.raises(InputError):
            chunk_plan(t, n, m)
        return
    cfg = UPSRConfig(scale=1, n_frames=n)
    plan = chunk_plan(t, n, m)
    assert [p[0] for p in plan] == list(range(0, t, m)) and plan[-1][1] == t
    for a, b, lo, hi in plan:
        assert hi - lo >= n and hi <= t
        for out in range(a, b):  # the chunk's window = the single run's window
            assert window_start(out - lo, hi - lo, cfg) + lo == window_start(out, t, cfg)
    for (_, b, _, hi), (_, _, lo2, _) in itertools.pairwise(plan):
        moved = window_start(b, t, cfg) == window_start(b - 1, t, cfg) + 1
        assert hi - lo2 == n - 1 if moved else hi - lo2 <= n  # overlap by N - 1 frames


def _check(out: Path, ref: dict[str, np.ndarray]) -> None:
    for k, v in ref.items():
        np.testing.assert_array_equal(np.load(out / f"{k}.npy"), v)
    assert not (out / ".upsr-batch").exists()


def test_batch_in_process_equals_single_runs(videos, tmp_path: Path) -> None:
    d, ref = videos
    cfg = UPSRConfig(scale=R, n_frames=N)
    res = run_batch(
        [d / "a.npy", d / "b.npy"], tmp_path, cfg, workers=1, chunk_frames=3, progress=False
    )
    assert res.exit_code == 0 and [r.status for r in res.recordings] == ["done", "done"]
    _check(tmp_path, ref)
    # resumable: finished outputs are skipped
    res = run_batch([d / "a.npy", d / "b.npy"], tmp_path, cfg, workers=1, progress=False)
    assert [r.status for r in res.recordings] == ["skipped", "skipped"]


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
    _check(tmp_path, ref)


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
    assert sorted(p.name for p in out.iterdir()) == ["b.npy"]  # nothing partial
    # default N shrinks to a short recording, as in `upsr run`
    assert main(["batch", str(short), "--out", str(out), "-r", "1", "-q", "-w", "1"]) == 0
    assert np.load(out / "short.npy").shape == (3, 20, 24)
    assert main(["batch", str(d / "b.npy"), str(d / "b.npy"), "--out", str(out), "-r", "2"]) == 2


def test_batch_reuses_finished_chunks(videos, tmp_path: Path, monkeypatch) -> None:
    from upsr.apps import batch

    d, ref = videos
    cfg = UPSRConfig(scale=R, n_frames=N)
    calls: list[int] = []
    real = batch._run_chunk

    def flaky(spec):  # the 3rd chunk dies the first time (an interrupted run)
        calls.append(spec["out_start"])
        if spec["out_start"] == 8 and calls.count(8) == 1:
            raise KeyboardInterrupt
        return real(spec)

    monkeypatch.setattr(batch, "_run_chunk", flaky)
    with pytest.raises(KeyboardInterrupt):
        run_batch([d / "a.npy"], tmp_path, cfg, workers=1, chunk_frames=4, progress=False)
    assert not (tmp_path / "a.npy").exists()
    parts = sorted(p.name for p in (tmp_path / ".upsr-batch").rglob("*.npy"))
    assert parts == ["chunk_000000000_000000004.npy", "chunk_000000004_000000008.npy"]
    computed = []

    def counting(spec):
        result = real(spec)
        if not result.get("reused"):
            computed.append(spec["out_start"])
        return result

    monkeypatch.setattr(batch, "_run_chunk", counting)
    res = run_batch([d / "a.npy"], tmp_path, cfg, workers=1, chunk_frames=4, progress=False)
    assert res.exit_code == 0
    assert sorted(computed) == [8, 12]  # chunks [8, 12) and [12, 13) only: the others reused
    _check(tmp_path, {"a": ref["a"]})


def test_chunks_read_only_their_frames_and_finish_only_their_outputs(
    videos, tmp_path: Path, monkeypatch
) -> None:
    from upsr.io import npy
    from upsr.method.windowed import UPSR

    d, ref = videos
    reads: list[tuple[int, int | None, int]] = []  # (start, stop, frames decoded)
    real_frames = npy.frames

    def spy(path, opts=None, fmt="npy", start=0, stop=None):  # type: ignore[no-untyped-def]
        reads.append((start, stop, 0))
        for frame in real_frames(path, opts, fmt, start, stop):
            reads[-1] = (reads[-1][0], reads[-1][1], reads[-1][2] + 1)
            yield frame

    finished: list[int] = []
    real_finish = UPSR._finish

    def counting(self, t, n_total):  # type: ignore[no-untyped-def]
        finished.append(t)
        return real_finish(self, t, n_total)

    monkeypatch.setattr(npy, "frames", spy)
    monkeypatch.setattr(UPSR, "_finish", counting)
    cfg = UPSRConfig(scale=R, n_frames=N)
    res = run_batch([d / "a.npy"], tmp_path, cfg, workers=1, chunk_frames=4, progress=False)
    assert res.exit_code == 0
    _check(tmp_path, {"a": ref["a"]})
    plan = chunk_plan(13, N, 4)
    # _prepare reads the first N frames; every chunk exactly its input frames [lo, hi)
    assert reads[0] == (0, N, N)
    assert sorted(reads[1:]) == sorted((lo, hi, hi - lo) for _, _, lo, hi in plan)
    assert len(finished) == 13  # one window per output frame: none for the overlaps
