"""The README's examples run as written (issue 15): every ``upsr`` line of its shell blocks that
needs no external data (``../shared``, recordings, a Dask cluster), on small generated inputs,
and the Open3D recipe after them."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import cv2
import numpy as np
import pytest

import upsr
from tests.apps._util import video
from upsr.apps.cli.main import main

README = Path(__file__).resolve().parents[3] / "README.md"
#: lines that need data the repository does not ship, or are synopses / other tools
_EXTERNAL = re.compile(r"\.\./shared|\$S|data/|recording\.bag|INPUT|LOWRES|tcp://|--out DIR")
_SKIP_COMMANDS = {"demo", "analyze", "experiment", "batch", "live"}  # long runs, cameras


def _blocks(kind: str) -> list[str]:
    return re.findall(rf"```{kind}\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


def shell_examples() -> list[str]:
    lines = []
    for block in _blocks("sh"):
        for line in block.splitlines():
            line = line.split(" #")[0].strip()
            if not line.startswith("upsr ") or _EXTERNAL.search(line):
                continue
            if line.split()[1] in _SKIP_COMMANDS:
                continue
            lines.append(re.sub(r"\s*\[[^\]]*\]", "", line))  # optional parts
    return lines


def test_the_readme_has_the_examples_this_test_runs() -> None:
    commands = {line.split()[1] for line in shell_examples()}
    assert {"run", "compare", "view", "export-ply"} <= commands


def test_readme_shell_examples_and_open3d_recipe_run(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    low = video(t=5, h=24, w=32)
    np.save("low.npy", low)
    np.save("out.npy", upsr.super_resolve(low, 2, 3))
    np.save("truth.npy", np.load("out.npy"))
    np.save("video.npy", video(t=3, h=48, w=64))
    Path("rgb").mkdir()
    for i in range(3):
        img = np.zeros((48, 64, 3), np.uint8)
        img[:, :, i] = 200
        cv2.imwrite(f"rgb/{i:06d}.png", img)
    for line in shell_examples():
        rc = main(shlex.split(line)[1:] + ["--quiet"] * (line.split()[1] == "run"))
        _, err = capsys.readouterr()
        assert rc == 0, f"{line}: {err}"
    assert Path("results/sr.color/000000.png").is_file()
    assert any(Path("results/ply").glob("*.ply"))
    pytest.importorskip("open3d")
    recipes = [b for b in _blocks("python") if "open3d" in b]
    assert recipes
    for code in recipes:
        scope: dict[str, object] = {}
        exec(compile(code, "README.md", "exec"), scope)
        if "colored" in scope:
            assert len(scope["colored"].points) > 0  # type: ignore[attr-defined]
