"""Helpers shared by the tests of upsr.apps: synthetic videos, running the CLI, checks."""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from upsr.apps.cli import main as cli

BIN = Path(sys.executable).parent / "upsr"
T, H, W = 5, 12, 16
R, N = 2, 5  # the batch tests' r and N


def video(seed: int = 0, t: int = T, h: int = H, w: int = W) -> np.ndarray:
    rng = np.random.default_rng(seed)
    _yy, xx = np.mgrid[0:h, 0:w]
    frames = []
    for k in range(t):  # a foreground square moving right over a slanted background
        d = 2000.0 + 10.0 * xx + rng.normal(0, 5, (h, w))
        d[3:9, 2 + k : 8 + k] = 1000.0
        frames.append(d)
    return np.round(np.array(frames)).astype(np.float32)


def png_folder(folder: Path, v: np.ndarray, dtype: type = np.uint16) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for i, frame in enumerate(v):
        ok, buf = cv2.imencode(".png", frame.astype(dtype))
        assert ok
        (folder / f"{i:03d}.png").write_bytes(buf.tobytes())
    return folder


def digest(path: Path) -> str:
    h = hashlib.sha256()
    for p in sorted([path] if path.is_file() else path.rglob("*")):
        h.update(str(p.relative_to(path.parent)).encode())
        if p.is_file():
            h.update(p.read_bytes())
    return h.hexdigest()


def listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


def run_cli(capsys: pytest.CaptureFixture[str], *args: object) -> tuple[int, str, str]:
    rc = cli.main([str(a) for a in args])
    out, err = capsys.readouterr()
    return rc, out, err


def assert_user_error(rc: int, out: str, err: str, match: str = "") -> None:
    assert rc == 2, (rc, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("upsr: error: "), err
    assert "Traceback" not in err and out == ""
    assert match.lower() in lines[0].lower(), (match, lines[0])


def scene(t: int = 3, h: int = 12, w: int = 16) -> np.ndarray:
    """A slanted wall with a box in front, in mm; one invalid pixel per frame."""
    _yy, xx = np.mgrid[0:h, 0:w]
    v = np.empty((t, h, w), np.float32)
    for k in range(t):
        d = 2000.0 + 20.0 * xx
        d[3:8, 4 + k : 9 + k] = 1200.0
        v[k] = d
    v[:, 0, 0] = 0
    return v


def check_batch_output(out: Path, ref: dict[str, np.ndarray]) -> None:
    """The batch outputs OUT/<name>.npy equal the single runs ``ref``; no work folder left."""
    for k, v in ref.items():
        np.testing.assert_array_equal(np.load(out / f"{k}.npy"), v)
    work = out / ".upsr-batch"  # only the options records of the outputs are left
    assert not work.exists() or [p.name for p in work.iterdir()] == ["outputs"]
    assert not (out / ".upsr-batch.lock").exists()
