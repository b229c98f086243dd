"""``upsr demo``: the command calls :func:`upsr.apps.demo.run_demo` and prints its table."""

from __future__ import annotations

import sys
import types
from pathlib import Path

import pytest

import upsr
from tests.apps._util import run_cli


def test_demo_command(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    try:
        import upsr.apps.demo as demo_module
    except ImportError:  # being written by someone else: stand in for it
        demo_module = types.ModuleType("upsr.apps.demo")
        monkeypatch.setitem(sys.modules, "upsr.apps.demo", demo_module)
        monkeypatch.setattr(upsr, "demo", demo_module, raising=False)
    calls = {}

    def run_demo(out_dir: Path, *, seed: int = 0, progress: bool = True) -> dict:
        calls.update(out_dir=Path(out_dir), seed=seed, progress=progress)
        return {"upsr": {"rmse": 1.0}}

    monkeypatch.setattr(demo_module, "run_demo", run_demo, raising=False)
    monkeypatch.setattr(
        demo_module, "format_metrics_table", lambda m: f"TABLE {sorted(m)}", raising=False
    )
    rc, out, err = run_cli(capsys, "demo", "--out", tmp_path / "d", "--seed", 3, "-q")
    assert rc == 0, err
    assert calls == {"out_dir": tmp_path / "d", "seed": 3, "progress": False}
    assert "TABLE ['upsr']" in out and str(tmp_path / "d") in out
