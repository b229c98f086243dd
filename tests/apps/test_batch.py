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


def test_batch_of_a_near_scene_equals_its_single_run(tmp_path: Path) -> None:
    """A camera at close range: every chunk runs with the depth thresholds the single run
    scaled from the video's first frames (a chunk's own frames lie nearer or farther)."""
    import numpy as np

    import upsr
    from upsr.research.synth.scenes import dynamic_scene

    scene = dynamic_scene(n_frames=13, lowres_shape=(20, 24), scale=R, noise_sigma_mm=2, seed=1)
    video = (scene.lowres * np.linspace(0.08, 0.2, 13)[:, None, None]).astype(np.float32)
    np.save(tmp_path / "near.npy", video)
    cfg = UPSRConfig(scale=R, n_frames=N)
    res = run_batch([tmp_path / "near.npy"], tmp_path / "out", cfg, workers=1, chunk_frames=3,
                    progress=False)  # fmt: skip
    assert res.exit_code == 0
    check_batch_output(tmp_path / "out", {"near": upsr.super_resolve(video, R, N)})


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


def test_chunks_of_an_input_rewritten_with_its_old_size_and_mtime_are_not_reused(
    tmp_path: Path,
) -> None:
    """The same size and the old mtime restored (cp -p, rsync -t, a coarse file system): its
    chunks were reused, the resumed output mixing old and new frames."""
    import os

    import numpy as np

    from upsr.apps._batch_plan import _fingerprint

    p = tmp_path / "a.npy"
    np.save(p, np.full((4, 6, 8), 1500.0, np.float32))
    before = _fingerprint(p, {"n": 3})
    st = os.stat(p)
    np.save(p, np.full((4, 6, 8), 1200.0, np.float32))
    os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert os.stat(p).st_size == st.st_size and os.stat(p).st_mtime_ns == st.st_mtime_ns
    assert _fingerprint(p, {"n": 3}) != before
    assert _fingerprint(p, {"n": 3}) == _fingerprint(p, {"n": 3})


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


def test_batch_registers_by_the_cameras_motion_as_a_single_run(tmp_path: Path) -> None:
    """``camera_motion="depth"``: each recording with its intrinsics, chunks equal to the
    single run (a step is estimated from the identity in every chunk), not the flow's
    output; recorded in the options (a rerun with the flow is refused); without intrinsics
    the recording fails with one line."""
    import numpy as np

    import upsr
    from upsr.research.synth.realistic import make_realistic

    v = make_realistic("toward_wall", (28, 32), scale=2, n_frames=12, seed=0)
    low = (v.lowres + np.random.default_rng(0).laplace(0.0, 7.0, v.lowres.shape)).astype(np.float32)
    np.save(tmp_path / "a.npy", low)
    c = v.camera
    intr = (c.fx, c.fy, c.cx, c.cy)
    cfg = UPSRConfig(scale=2, n_frames=5)
    out = tmp_path / "out"
    res = run_batch(
        [tmp_path / "a.npy"], out, cfg, workers=1, chunk_frames=3, progress=False,
        intrinsics=",".join(map(str, intr)), camera_motion="depth",
    )  # fmt: skip
    assert res.exit_code == 0, [r.error for r in res.recordings]
    want = upsr.super_resolve(low, 2, 5, camera_motion="depth", camera_intrinsics=intr)
    np.testing.assert_array_equal(np.load(out / "a.npy"), want)
    assert not np.array_equal(want, upsr.super_resolve(low, 2, 5))
    res = run_batch([tmp_path / "a.npy"], out, cfg, workers=1, progress=False)
    assert res.exit_code == 2 and "other options" in res.recordings[0].error
    res = run_batch(
        [tmp_path / "a.npy"], tmp_path / "none", cfg, workers=1, progress=False,
        camera_motion="depth",
    )  # fmt: skip
    assert res.exit_code == 2 and "needs the camera's intrinsics" in res.recordings[0].error
    with pytest.raises(InputError, match="'flow' or 'depth'"):
        run_batch([tmp_path / "a.npy"], out, cfg, camera_motion="imu", progress=False)
