"""Peak memory of ``upsr run`` against the estimate it checks before running.

Each case is a new process that runs ``upsr run`` (the windowed mode, its default workers) on
T = N dense frames (a room seen by a camera, Kinect noise) and reports its peak resident size
(``ru_maxrss``); a run on 8×8 frames gives the process's own size (Python, numpy, OpenCV,
numba), which the estimate does not count. Beside it the estimate of
:func:`upsr.method.resources.peak_memory_bytes` for the same run. The estimate must not be
below what the run takes (a run that passes the check must not be killed half-way).

Example::

    .venv/bin/python benchmarks/memory_eval.py --out docs/results/memory
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = ["main"]

#: (h, w, r, N): frames and window; T = N frames.
CASES = (
    (240, 320, 4, 9),
    (480, 640, 2, 9),
    (240, 320, 8, 5),
    (480, 640, 8, 1),
    (480, 640, 8, 3),
    (480, 640, 16, 1),
)

CHILD = r"""
import resource, sys
from upsr.apps.cli.main import main
rc = main(sys.argv[1:])
print("MAXRSS", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, rc)
"""


def _peak(args: list[str]) -> int:
    """Peak resident bytes of one ``upsr`` command line in a new process."""
    done = subprocess.run(
        [sys.executable, "-c", CHILD, *args], capture_output=True, text=True, check=True
    )
    line = next(x for x in done.stdout.splitlines() if x.startswith("MAXRSS"))
    _, peak, rc = line.split()
    if rc != "0":
        raise RuntimeError(f"upsr {' '.join(args)} failed: {done.stderr[-500:]}")
    return int(peak)


def _frames(h: int, w: int, t: int) -> np.ndarray:
    from upsr.research.synth.realistic import degrade, make_realistic

    video = make_realistic("room", (h, w), scale=1, n_frames=t)
    return degrade(video, "kinect", np.random.default_rng(0)).astype(np.float32)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="docs/results/memory")
    args = p.parse_args(argv)
    from upsr.apps._preflight import engine_workers
    from upsr.method.resources import peak_memory_bytes

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        np.save(d / "tiny.npy", np.full((3, 8, 8), 1500.0, np.float32))
        base = _peak(["run", str(d / "tiny.npy"), "-o", str(d / "t.npy"), "-r", "2", "-n", "3",
                      "-q"])  # fmt: skip
        print(f"process alone: {base / 2**20:.0f} MB", flush=True)
        for h, w, r, n in CASES:
            np.save(d / "in.npy", _frames(h, w, n))
            peak = _peak(["run", str(d / "in.npy"), "-o", str(d / "o.npy"), "-r", str(r), "-n",
                          str(n), "-q", "--overwrite", "--max-memory", "1000G"])  # fmt: skip
            est = peak_memory_bytes((n, h, w), r, n, workers=engine_workers(None))
            row = {"frames": f"{w}×{h}", "r": r, "N": n, "peak_mb": (peak - base) / 2**20,
                   "estimate_mb": est / 2**20, "ratio": est / max(peak - base, 1)}  # fmt: skip
            rows.append(row)
            print(f"{w}×{h} r={r} N={n}: {row['peak_mb']:.0f} MB over the process, estimate "
                  f"{row['estimate_mb']:.0f} MB (×{row['ratio']:.2f})", flush=True)  # fmt: skip
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps({"process_mb": base / 2**20, "rows": rows}))
    lines = [
        "# Peak memory of `upsr run` against its estimate",
        "",
        "`benchmarks/memory_eval.py --out docs/results/memory`: T = N dense Kinect-like frames,",
        f"windowed mode, default workers; the process alone {base / 2**20:.0f} MB (not estimated).",
        "",
        "| frames | r | N | peak over the process (MB) | estimate (MB) | estimate / peak |",
        "|---|---|---|---|---|---|",
        *(
            f"| {x['frames']} | {x['r']} | {x['N']} | {x['peak_mb']:.0f} | "
            f"{x['estimate_mb']:.0f} | {x['ratio']:.2f} |"
            for x in rows
        ),
    ]
    (out / "results.md").write_text("\n".join(lines) + "\n")
    return 0 if all(x["ratio"] >= 1.0 for x in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
