"""upsr batch under faults: dying workers, a killed driver, two batches on one folder,
relative paths with a scheduler, reruns with other options, --out onto an input folder; and
CLI options without a bound (issue 16)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import upsr
from tests.apps._util import assert_user_error, listing, png_folder, run_cli
from tests.hostile import _batch_hooks
from upsr.apps import batch
from upsr.apps.batch import run_batch
from upsr.method.config import UPSRConfig

SRC = Path(upsr.__file__).resolve().parents[1]


def _video(t: int = 10, h: int = 16, w: int = 20, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    _yy, xx = np.mgrid[0:h, 0:w]
    v = np.empty((t, h, w), np.float32)
    for k in range(t):
        d = 2000.0 + 10.0 * xx + rng.normal(0, 5, (h, w))
        d[4:10, 2 + k % 8 : 8 + k % 8] = 1200.0
        v[k] = np.round(d)
    return v


@pytest.fixture(scope="module")
def recs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray]:
    d = tmp_path_factory.mktemp("recs")
    v = _video()
    for name in ("a", "b", "crash"):
        np.save(d / f"{name}.npy", v)
    return d, upsr.super_resolve(v, 2, 3)


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(SRC), str(SRC.parent)])}


def _cli(*args: object) -> list[str]:
    return [sys.executable, "-m", "upsr.apps.cli.main", *map(str, args)]


# ---------------------------------------------------------------------------------------------
# 1. crash isolation, workers die with the driver
# ---------------------------------------------------------------------------------------------
def test_local_worker_death_fails_only_its_recording(recs, tmp_path: Path, monkeypatch) -> None:
    d, ref = recs
    monkeypatch.setattr(batch, "run_chunk", _batch_hooks.crashing_run_chunk)
    cfg = UPSRConfig(scale=2, n_frames=3)
    res = run_batch(
        [d / "a.npy", d / "crash.npy", d / "b.npy"],
        tmp_path,
        cfg,
        workers=2,
        chunk_frames=4,
        progress=False,
    )
    status = {r.input.name: r.status for r in res.recordings}
    assert status == {"a.npy": "done", "crash.npy": "failed", "b.npy": "done"}
    crash = res.failed[0]
    assert "worker process died (killed by SIGKILL)" in crash.error and "\n" not in crash.error
    assert res.exit_code == 1
    for name in ("a", "b"):
        np.testing.assert_array_equal(np.load(tmp_path / f"{name}.npy"), ref)
    assert not (tmp_path / "crash.npy").exists()
    assert not list((tmp_path / ".upsr-batch").glob("crash*"))


def test_dask_worker_death_fails_only_its_recording(recs, tmp_path: Path, monkeypatch) -> None:
    distributed = pytest.importorskip("dask.distributed")
    import dask

    d, ref = recs
    monkeypatch.setattr(batch, "run_chunk", _batch_hooks.crashing_run_chunk)
    monkeypatch.syspath_prepend(str(SRC.parent))  # the workers import tests.hostile
    cfg = UPSRConfig(scale=2, n_frames=3)
    with (
        # a worker runs one task at a time and holds no queued ones (which would die with
        # it); a task that killed one worker is not given another
        dask.config.set(
            {
                "distributed.scheduler.allowed-failures": 0,
                "distributed.scheduler.worker-saturation": 1.0,
            }
        ),
        distributed.LocalCluster(
            n_workers=1,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
    ):
        res = run_batch(
            [d / "crash.npy", d / "a.npy"],
            tmp_path,
            cfg,
            scheduler=cluster.scheduler_address,
            chunk_frames=10,
            progress=False,
        )
    status = {r.input.name: r.status for r in res.recordings}
    assert status["crash.npy"] == "failed", res.recordings
    assert status["a.npy"] == "done", res.recordings
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), ref)


def _children(pid: int) -> list[int]:
    out = []
    for p in Path("/proc").iterdir():
        if p.name.isdigit():
            try:
                fields = (p / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.append(int(p.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")
def test_workers_die_with_a_killed_batch(tmp_path: Path) -> None:
    v = _video(t=40, h=24, w=32)
    for name in ("a", "b"):
        np.save(tmp_path / f"{name}.npy", v)
    cmd = _cli(tmp_path / "a.npy", tmp_path / "b.npy")
    cmd[3:3] = ["batch"]
    cmd += ["--out", tmp_path / "out", "-r", "2", "-n", "3", "-w", "2", "-q"]
    proc = subprocess.Popen(list(map(str, cmd)), env=_env(), stderr=subprocess.DEVNULL)
    try:
        workers: list[int] = []
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            workers = [c for c in _children(proc.pid) if "spawn_main" in _cmdline(c)]
            if len(workers) == 2:
                break
            time.sleep(0.05)
        assert len(workers) == 2, "the batch did not start its 2 workers"
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and any(map(_alive, workers)):
            time.sleep(0.05)
        assert not any(map(_alive, workers)), "worker processes outlived the killed batch"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


# ---------------------------------------------------------------------------------------------
# 2. one batch per output folder
# ---------------------------------------------------------------------------------------------
def test_second_batch_on_one_out_is_refused(recs, tmp_path: Path, capsys) -> None:
    d, ref = recs
    out = tmp_path / "out"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time; from pathlib import Path; from upsr.apps.batch import "
            "_batch_folder\nwith _batch_folder(Path(sys.argv[1])):\n"
            "    print('locked', flush=True); time.sleep(60)",
            str(out),
        ],
        env=_env(),
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        (out / ".upsr-batch" / "a.npy.0123456789ab").mkdir(parents=True)  # its chunks
        rc, o, e = run_cli(capsys, "batch", d / "a.npy", "--out", out, "-r", 2, "-n", 3, "-q")
        assert_user_error(rc, o, e, "is in use by another upsr batch")
        assert f"PID {holder.pid}" in e
        assert (out / ".upsr-batch" / "a.npy.0123456789ab").is_dir()  # not deleted
        assert not (out / "a.npy").exists()
    finally:
        holder.kill()
        holder.communicate()  # (closes its pipe)
    # the lock is gone with its holder
    rc = run_cli(capsys, "batch", d / "a.npy", "--out", out, "-r", 2, "-n", 3, "-q", "-w", 1)[0]
    assert rc == 0
    np.testing.assert_array_equal(np.load(out / "a.npy"), ref)
    assert not (out / ".upsr-batch.lock").exists()


# ---------------------------------------------------------------------------------------------
# 3. scheduler address, absolute paths, options recorded per output
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "address", ["http://127.0.0.1:8786", "127.0.0.1:8786", "tcp://", "tcp://h:99999", "tcp://h"]
)
def test_scheduler_address_is_checked(recs, tmp_path: Path, capsys, address: str) -> None:
    d, _ = recs
    rc, o, e = run_cli(
        capsys, "batch", d / "a.npy", "--out", tmp_path / "o", "-r", 2, "--scheduler", address
    )
    assert_user_error(rc, o, e, "not a Dask scheduler address")
    assert not (tmp_path / "o").exists()


def test_tasks_get_absolute_paths(recs, tmp_path: Path, monkeypatch) -> None:
    d, ref = recs
    specs = []
    real = batch._run_chunk

    def spy(spec):  # type: ignore[no-untyped-def]
        specs.append(spec)
        return real(spec)

    monkeypatch.setattr(batch, "_run_chunk", spy)
    (tmp_path / "in").mkdir()
    np.save(tmp_path / "in" / "a.npy", np.load(d / "a.npy"))
    monkeypatch.chdir(tmp_path)
    cfg = UPSRConfig(scale=2, n_frames=3)
    res = run_batch([Path("in/a.npy")], Path("out"), cfg, workers=1, progress=False)
    assert res.exit_code == 0 and specs
    for spec in specs:
        assert Path(spec["input"]).is_absolute() and Path(spec["part"]).is_absolute()
    np.testing.assert_array_equal(np.load(tmp_path / "out" / "a.npy"), ref)


def test_rerun_with_other_options_is_not_skipped(recs, tmp_path: Path, capsys) -> None:
    d, ref = recs
    base = ["batch", d / "a.npy", "--out", tmp_path, "-n", 3, "-q", "-w", 1]
    assert run_cli(capsys, *base, "-r", 2)[0] == 0
    rc, o, e = run_cli(capsys, *base, "-r", 1)
    assert rc == 2 and len(e.strip().splitlines()) == 1 and len(e.strip()) <= 200
    assert "made with other options (config.scale: 2 -> 1" in e and "--overwrite" in e
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), ref)  # untouched
    rc, o, e = run_cli(capsys, *base, "-r", 2)  # the same options: skipped
    assert rc == 0 and "1 skipped" in o
    assert run_cli(capsys, *base, "-r", 1, "--overwrite")[0] == 0
    assert np.load(tmp_path / "a.npy").shape == (10, 16, 20)
    rc, o, _ = run_cli(capsys, *base, "-r", 1)
    assert rc == 0 and "1 skipped" in o


def test_output_published_but_not_recorded_is_recomputed(recs, tmp_path: Path, monkeypatch):
    """A batch that died after publishing an output, before recording it as done."""
    d, ref = recs
    cfg = UPSRConfig(scale=2, n_frames=3)
    real = batch._write_record

    def die_when_done(rec, options, state):  # type: ignore[no-untyped-def]
        if state == "done":
            raise KeyboardInterrupt
        real(rec, options, state)

    monkeypatch.setattr(batch, "_write_record", die_when_done)
    with pytest.raises(KeyboardInterrupt):
        run_batch([d / "a.npy"], tmp_path, cfg, workers=1, progress=False)
    np.save(tmp_path / "a.npy", np.zeros((1, 2, 2), np.float32))  # say, no sidecar yet
    monkeypatch.setattr(batch, "_write_record", real)
    res = run_batch([d / "a.npy"], tmp_path, cfg, workers=1, progress=False)
    assert [r.status for r in res.recordings] == ["done"]
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), ref)


# ---------------------------------------------------------------------------------------------
# 4. --out onto an input folder
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("sub", ["", "sub", "sub/deeper"])
def test_out_inside_an_input_folder_is_refused(tmp_path: Path, capsys, sub: str) -> None:
    frames = png_folder(tmp_path / "frames", _video(t=4))
    before = listing(frames)
    out = frames / sub if sub else frames
    rc, o, e = run_cli(capsys, "batch", frames, "--out", out, "-r", 2, "-n", 3, "-q", "-w", 1)
    assert_user_error(rc, o, e, "is inside the input folder")
    assert listing(frames) == before


def test_output_onto_another_recordings_input_is_refused(recs, tmp_path: Path, capsys) -> None:
    d, _ = recs
    out = tmp_path / "out"
    out.mkdir()
    victim = out / "b.npy"  # recording a's data, through a link
    np.save(victim, _video(seed=3))
    (tmp_path / "a.npy").symlink_to(victim)
    before = victim.read_bytes()
    args = ["batch", tmp_path / "a.npy", d / "b.npy", "--out", out, "-r", 2, "--overwrite"]
    assert_user_error(*run_cli(capsys, *args), "choose another output folder")
    assert victim.read_bytes() == before and sorted(p.name for p in out.iterdir()) == ["b.npy"]


# ---------------------------------------------------------------------------------------------
# 5. exit codes and messages of options
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("cmd", ["run", "batch"])
def test_frames_error_names_the_option_given(recs, tmp_path: Path, capsys, cmd: str) -> None:
    d, _ = recs
    where = ["-o", tmp_path / "x.npy"] if cmd == "run" else ["--out", tmp_path / "o"]
    rc, o, e = run_cli(capsys, cmd, d / "a.npy", *where, "-r", 2, "-n", -5)
    assert_user_error(rc, o, e, "--frames (-n) must be an integer >= 1, got -5")
    rc, o, e = run_cli(capsys, cmd, d / "a.npy", *where, "-r", 0)
    assert_user_error(rc, o, e, "--scale (-r) must be an integer >= 1, got 0")
    assert listing(tmp_path) == []


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["compare", "{a}", "{a}", "-o", "{t}/c.gif", "--fps", "1e-300"], "--fps must be"),
        (["compare", "{a}", "{a}", "-o", "{t}/c.gif", "--fps", "nan"], "--fps must be"),
        (["compare", "{a}", "{a}", "-o", "{t}/c.gif", "--fps", "1e9"], "--fps must be"),
        (["view", "{a}", "-o", "{t}/v.png", "--width", "100000"], "--width must be 16..8192"),
        (["view", "{a}", "-o", "{t}/v.png", "--yaw", "inf"], "--yaw must be a finite"),
        (["run", "{a}", "-o", "{t}/o.npy", "-r", "2", "--workers", "100000"], "--workers"),
        (["batch", "{a}", "--out", "{t}/o", "-r", "2", "--workers", "100000"], "--workers"),
    ],
)
def test_unbounded_options_are_refused(recs, tmp_path: Path, capsys, args, match) -> None:
    d, _ = recs
    argv = [a.format(a=d / "a.npy", t=tmp_path) for a in args]
    assert_user_error(*run_cli(capsys, *argv), match)
    assert listing(tmp_path) == []
