"""Speed of two commits of upsr side by side, in alternated processes (A, B, A, B, ...).

This machine's speed drifts by 30 % and more within an hour, so that figures of two runs of a
benchmark cannot be compared: a change is measured against its parent in one sitting. Each
revision's ``src`` folder is taken out of git (``git archive``) into a scratch folder; each
run is a new process with that folder first on ``PYTHONPATH`` and a numba cache of its own
(warmed by a first, untimed run), and the runs alternate between the revisions.

Cases: ``tof`` (issue #14's ToF stream, :func:`speed_eval.tof_benchmark`: 64×56 → 256×224,
r = 4, N = 9, frames/s, the median of its three runs) and ``dense0`` … ``dense3`` (the dense
rows of :data:`speed_eval.DENSE_CASES`, ``--frames`` output frames timed after the first window:
seconds per output frame; the windowed mode through ``push``, or with ``--mode`` the recursive
mode frame by frame or pipelined on two threads). Same outputs are
checked by the tests, not here.

Example::

    .venv/bin/python benchmarks/ab_eval.py --revs 44f115a db9c0f9 --case dense3 --pairs 3
    .venv/bin/python benchmarks/ab_eval.py --revs 4a8d055 bd45b38 --case dense0 \
        --mode recursive_pipelined --pairs 5
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["main"]

ROOT = Path(__file__).resolve().parent.parent

#: The child's program: one timed run of a case, its figure printed as JSON on the last line.
CHILD = r"""
import json, sys, time
sys.path.insert(0, {bench!r})
import numpy as np
import speed_eval
case, frames, mode = {case!r}, {frames}, {mode!r}
if case == "tof":
    r = speed_eval.tof_benchmark(150, {{}})
    print(json.dumps({{"fps": r["fps"], "fps_runs": r["fps_runs"],
                       "cpu_ms_per_frame": r["cpu_ms_per_frame"]}}))
else:
    from upsr.research.synth.realistic import degrade, make_realistic
    _, name, shape, r, sensor, _ = speed_eval.DENSE_CASES[int(case[5:])]
    video = make_realistic(name, shape, scale=r, n_frames=9 + frames)
    low = degrade(video, sensor, np.random.default_rng(0), sigma_mm=10.0)
    path, pipelined = mode.split("_")[0], mode.endswith("pipelined")
    speed_eval._stream(low[:10], r, 9, path, 9)  # compile for this shape
    spf, _ = speed_eval._stream(low, r, 9, path, 9, pipelined=pipelined)
    print(json.dumps({{"s_per_frame": spf, "fps": 1.0 / spf}}))
"""


def _checkout(rev: str, into: Path) -> Path:
    """The ``src`` folder of ``rev`` (a commit, or "." for the working tree) under ``into``."""
    if rev == ".":
        return ROOT / "src"
    into.mkdir(parents=True)
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", rev, "src"], check=True, capture_output=True
    ).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into / "src"


def _run(src: Path, cache: Path, case: str, frames: int, mode: str) -> dict[str, Any]:
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(cache))
    code = CHILD.format(bench=str(ROOT / "benchmarks"), case=case, frames=frames, mode=mode)
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, check=True, capture_output=True, text=True
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--revs", nargs=2, required=True, metavar=("A", "B"), help="git revisions")
    p.add_argument("--case", default="tof", choices=("tof", "dense0", "dense1", "dense2", "dense3"))
    p.add_argument("--pairs", type=int, default=3, help="alternated pairs of timed runs")
    p.add_argument("--frames", type=int, default=24, help="timed output frames (dense cases)")
    p.add_argument(
        "--mode",
        default="windowed",
        choices=("windowed", "recursive", "recursive_pipelined"),
        help="dense cases: the windowed mode, the recursive mode frame by frame or pipelined",
    )
    p.add_argument("--out", default=None, help="folder for results.json (default: print only)")
    args = p.parse_args(argv)
    key = "fps" if args.case == "tof" else "s_per_frame"
    runs: dict[str, list[dict[str, Any]]] = {rev: [] for rev in args.revs}
    with tempfile.TemporaryDirectory(prefix="upsr-ab-") as tmp:
        trees = {rev: _checkout(rev, Path(tmp) / f"rev{i}") for i, rev in enumerate(args.revs)}
        caches = {rev: Path(tmp) / f"numba{i}" for i, rev in enumerate(args.revs)}
        for rev in args.revs:  # compile each revision's kernels into its cache, untimed
            _run(trees[rev], caches[rev], args.case, 3, args.mode)
        for pair in range(args.pairs):
            for rev in args.revs:
                result = _run(trees[rev], caches[rev], args.case, args.frames, args.mode)
                runs[rev].append(result)
                print(f"pair {pair + 1} {rev}: {key} {result[key]:.4f}", flush=True)
    summary = {
        rev: {"median": statistics.median(r[key] for r in rs), "runs": [r[key] for r in rs]}
        for rev, rs in runs.items()
    }
    a, b = (summary[rev]["median"] for rev in args.revs)
    print(f"{args.case}: {key} median {args.revs[0]} {a:.4f}, {args.revs[1]} {b:.4f}", end=" ")
    print(f"(B/A {b / a:.3f})")
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        payload = {
            "command": " ".join(sys.argv),
            "date": time.strftime("%Y-%m-%d %H:%M"),
            "args": vars(args),
            "summary": summary,
            "runs": runs,
        }
        (out / "results.json").write_text(json.dumps(payload, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
