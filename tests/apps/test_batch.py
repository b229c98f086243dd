"""upsr.apps.batch: chunks equal to single runs, in-process runs, reused chunks."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.apps._util import N, R, check_batch_output
from upsr.apps.batch import chunk_plan, run_batch
from upsr.errors import InputError
from upsr.method.config import UPSRConfig
from upsr.method.windowed import window_start


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


def test_batch_in_process_equals_single_runs(videos, tmp_path: Path) -> None:
    d, ref = videos
    cfg = UPSRConfig(scale=R, n_frames=N)
    res = run_batch(
        [d / "a.npy", d / "b.npy"], tmp_path, cfg, workers=1, chunk_frames=3, progress=False
    )
    assert res.exit_code == 0 and [r.status for r in res.recordings] == ["done", "done"]
    check_batch_output(tmp_path, ref)
    # resumable: finished outputs are skipped
    res = run_batch([d / "a.npy", d / "b.npy"], tmp_path, cfg, workers=1, progress=False)
    assert [r.status for r in res.recordings] == ["skipped", "skipped"]


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
    check_batch_output(tmp_path, {"a": ref["a"]})


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
    check_batch_output(tmp_path, {"a": ref["a"]})
    plan = chunk_plan(13, N, 4)
    # _prepare reads the first N frames; every chunk exactly its input frames [lo, hi)
    assert reads[0] == (0, N, N)
    assert sorted(reads[1:]) == sorted((lo, hi, hi - lo) for _, _, lo, hi in plan)
    assert len(finished) == 13  # one window per output frame: none for the overlaps
