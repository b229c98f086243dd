"""The ``upsr`` entry point: interrupts, internal errors, warnings, help, version, the script."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import upsr
from tests.apps._util import BIN, H, T, W, listing, run_cli, video
from upsr.apps.cli import main as cli
from upsr.method import windowed as pipeline


def test_interrupt_leaves_no_output(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    np.save(tmp_path / "in.npy", video())

    def interrupted(self: object, frames: object) -> Iterator[np.ndarray]:
        yield np.ones((2 * H, 2 * W), np.float32)
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline.UPSR, "process", interrupted)
    rc, _out, err = run_cli(
        capsys, "run", tmp_path / "in.npy", "-o", tmp_path / "new" / "o.npy", "-r", 2, "-n", 3, "-q"
    )
    assert rc == 130 and "interrupted" in err and "Traceback" not in err
    assert listing(tmp_path) == ["in.npy"]


def test_internal_error(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    np.save(tmp_path / "in.npy", video())

    def broken(self: object, frames: object) -> Iterator[np.ndarray]:
        yield np.ones((2 * H, 2 * W), np.float32)
        raise ZeroDivisionError("oops")

    monkeypatch.setattr(pipeline.UPSR, "process", broken)
    args = ["run", tmp_path / "in.npy", "-o", tmp_path / "o.npy", "-r", 2, "-n", 3, "-q"]
    rc, _, err = run_cli(capsys, *args)
    assert rc == 1
    assert err.strip() == (
        "upsr: internal error: ZeroDivisionError: oops (rerun with --debug for a traceback)"
    )
    assert listing(tmp_path) == ["in.npy"]
    rc, _, err = run_cli(capsys, "--debug", *args)
    assert rc == 1 and "Traceback" in err and "ZeroDivisionError" in err
    rc, _out, err = run_cli(
        capsys, "--debug", "run", tmp_path / "nothere.npy", "-o", tmp_path / "o.npy", "-r", 2
    )
    assert rc == 2 and "Traceback" in err and err.strip().endswith("no such file or folder")


def test_warnings_are_one_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # short names: the message is not shortened
    np.save("in.npy", video() / 1000)  # metres in a .npy (mm): a unit trap
    rc, _out, err = run_cli(capsys, "run", "in.npy", "-o", "o.npy", "-r", 1, "-n", 1, "-q")
    assert rc == 0
    assert err.startswith("upsr: warning: ") and "plausible" in err and "metres" in err
    assert "look like metres (--input-depth-scale 1)" in err  # (the advice, never cut)
    assert len(err.strip().splitlines()) == 1 and len(err.strip()) <= 200


def test_png_output_that_cannot_hold_the_depth_is_refused_first(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    np.save("in.npy", video() * 40)  # up to ~100 m: does not fit 16-bit mm PNGs
    args = ("run", "in.npy", "-o", "o", "-r", 1, "-n", 1, "-q")
    rc, _out, err = run_cli(capsys, *args)
    assert rc == 2 and "--output-depth-scale" in err
    assert len(err.strip().splitlines()) == 1 and len(err.strip()) <= 200
    assert not (tmp_path / "o").exists()
    rc, _out, err = run_cli(capsys, *args, "--output-depth-scale", 500)
    assert rc == 0, err


def test_a_tum_png_under_a_long_path_keeps_its_advice_on_the_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    import cv2

    folder = tmp_path / ("a_long_folder_name_of_a_recording_session" * 3)
    folder.mkdir()
    cv2.imwrite(str(folder / "depth.png"), np.full((24, 32), 30000, np.uint16))  # 6 m at 5000/m
    rc, _out, err = run_cli(capsys, "run", folder / "depth.png", "-o", tmp_path / "o.npy", "-r", 2)
    line = err.strip().splitlines()[-1]
    assert rc == 2 and "--input-format tum" in line and len(line) <= 220
    assert not (tmp_path / "o.npy").exists()


def test_help_texts() -> None:
    runner = CliRunner()
    res = runner.invoke(cli.app, ["run", "--help"])
    assert res.exit_code == 0
    text = " ".join(res.output.split())
    for needle in (
        "--scale",
        "--frames",
        "[default: 9, or all the frames of a shorter video]",
        "mm",
        "--depth-scale",
        "TUM",
        "5000",
        "--no-deblur",
        "--overwrite",
        "Examples:",
        "upsr run video.npy",
    ):
        assert needle in text, needle
    res = runner.invoke(cli.app, ["--help"])
    assert res.exit_code == 0 and "run" in res.output and "demo" in res.output
    res = runner.invoke(cli.app, ["demo", "--help"])
    assert res.exit_code == 0 and "--seed" in res.output


def test_no_arguments_prints_help(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _err = run_cli(capsys)
    assert rc == 0 and "Usage" in out and "run" in out


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run_cli(capsys, "--version")
    assert rc == 0 and out.strip() == f"upsr {upsr.__version__}"


def _proc(*args: object, **kw: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(BIN), *map(str, args)], capture_output=True, text=True, timeout=300, **kw
    )  # type: ignore[call-overload]


def test_python_dash_m_upsr_is_the_command_line() -> None:
    p = subprocess.run(
        [sys.executable, "-m", "upsr", "--version"], capture_output=True, text=True, timeout=120
    )
    assert p.returncode == 0 and p.stdout.strip() == f"upsr {upsr.__version__}"


@pytest.mark.skipif(not BIN.exists(), reason="console script not installed")
def test_console_script_success_and_errors(tmp_path: Path) -> None:
    np.save(tmp_path / "in.npy", video())
    p = _proc("run", tmp_path / "in.npy", "-o", tmp_path / "o.npz", "-r", 2, "-n", 3)
    assert p.returncode == 0, p.stderr
    assert len(p.stdout.strip().splitlines()) == 1 and "frames/s" in p.stdout
    assert np.load(tmp_path / "o.npz")["depth"].shape == (T, 2 * H, 2 * W)

    np.save(tmp_path / "bad.npy", video().astype(object), allow_pickle=True)
    p = _proc("run", tmp_path / "bad.npy", "-o", tmp_path / "o2.npy", "-r", 2, "-n", 3)
    assert p.returncode == 2 and p.stdout == ""
    assert p.stderr.strip().splitlines() == [
        f"upsr: error: {tmp_path / 'bad.npy'}: object arrays are refused (they would need "
        f"unpickling); save depth as a numeric array"
    ]
    p = _proc("run", tmp_path / "in.npy", "-o", tmp_path / "o3.npy", "--scale", "0")
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1
    p = _proc("--version")
    assert p.returncode == 0 and p.stdout.strip() == f"upsr {upsr.__version__}"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["bad.npy", "in.npy", "o.npz"]


@pytest.mark.parametrize("code", ["ENOSPC", "EROFS", "ENAMETOOLONG"])
def test_a_full_or_read_only_disk_is_one_line_not_an_internal_error(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, code: str
) -> None:
    import errno
    import os

    np.save(tmp_path / "in.npy", video())
    where = str(tmp_path / ".o.npy.~abc-1-2.part")  # (one of upsr's temporaries)

    def full(self: object, frames: object) -> Iterator[np.ndarray]:
        raise OSError(getattr(errno, code), os.strerror(getattr(errno, code)), where)
        yield

    monkeypatch.setattr(pipeline.UPSR, "process", full)
    rc, _out, err = run_cli(
        capsys, "run", tmp_path / "in.npy", "-o", tmp_path / "o.npy", "-r", 2, "-n", 3, "-q"
    )
    assert rc == 2 and "internal error" not in err and len(err.strip().splitlines()) == 1
    assert f"upsr: error: {tmp_path}: {os.strerror(getattr(errno, code))}" in err


_SLOW_RUN = """
import signal, sys, time
import numpy as np
from upsr.apps.cli import main as cli
from upsr.method import windowed

# the test sends SIGINT: give the child Python's own handler whatever the parent inherited
signal.signal(signal.SIGINT, signal.default_int_handler)
signal.signal(signal.SIGTERM, signal.SIG_DFL)
signal.signal(signal.SIGHUP, signal.SIG_DFL)

def slow(self, frames):
    for f in frames:
        time.sleep(0.3)
        print("frame", flush=True, file=sys.stderr)
        yield np.repeat(np.repeat(f, 2, 0), 2, 1)

windowed.UPSR.process = slow
sys.exit(cli.main(sys.argv[1:]))
"""


@pytest.mark.parametrize(
    "sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=["SIGINT", "SIGTERM", "SIGHUP"]
)
def test_signal_leaves_no_output(tmp_path: Path, sig: int) -> None:
    np.save(tmp_path / "in.npy", np.ones((40, H, W), np.float32))
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            _SLOW_RUN,
            "run",
            str(tmp_path / "in.npy"),
            "-o",
            str(tmp_path / "out" / "o.npy"),
            "-r",
            "2",
            "-n",
            "3",
            "-q",
        ],
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stderr is not None
    seen = 0
    while seen < 2:  # wait until it is writing
        line = proc.stderr.readline()
        assert line, "the child exited early"
        seen += line.strip() == "frame"
    assert (tmp_path / "out").exists()
    proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 128 + sig, err  # (a closed terminal's SIGHUP too: 129)
    assert ("interrupted" if sig == signal.SIGINT else "terminated") in err
    assert "Traceback" not in err
    assert listing(tmp_path) == ["in.npy"]


@pytest.mark.parametrize(
    ("code", "forbidden"),
    [
        (
            "from upsr.apps.cli.main import main; main(['--version'])",
            ("upsr.method.windowed", "upsr.method", "upsr.research", "upsr.io", "numba", "numpy"),
        ),
        ("import upsr.apps.cli.main", ("upsr.method", "upsr.research", "numpy", "tqdm", "cv2")),
        ("import upsr", ("importlib.metadata", "numpy")),
    ],
    ids=["--version", "import cli", "import upsr"],
)
def test_start_up_loads_nothing_heavy(code: str, forbidden: tuple[str, ...]) -> None:
    """``upsr --version`` costs python + typer: each command imports what it needs itself."""
    probe = f"{code}; import sys; print('\\n'.join(sys.modules), file=sys.stderr)"
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    loaded = set(proc.stderr.split())
    assert not loaded & set(forbidden), loaded & set(forbidden)
    if "--version" in code:
        assert proc.stdout.strip() == f"upsr {upsr.__version__}"
