"""``upsr live`` as a user runs it: SDK recordings played back in real time, a new process each.

For each case a recording is written by the RealSense SDK itself
(:func:`upsr.research.synth.recording.write_realsense_recording`, one frame every 1/30 s so that
it plays back at the camera's rate) from a dense realistic scene
(:mod:`upsr.research.synth.realistic`, σ = 10 mm, the case's sensor model), then ``upsr live
REC -o OUT.npy -r R -q`` runs on it in a new process, as from a shell: the recording is played
back through the SDK as a camera, frames that arrive while one is processed are dropped. From
its summary line: frames processed, frames dropped, frames/s, latency (arrival → output)
median and maximum; the median of ``--runs`` runs (by frames processed) is reported, with
every run's figures. A new process's first frame loads the compiled kernels unless ``upsr
live`` loads them before the stream starts (:mod:`upsr.method.warmup`): the camera's frames
meanwhile are dropped.

Examples::

    .venv/bin/python benchmarks/live_eval.py --out docs/results/live
    .venv/bin/python benchmarks/live_eval.py --cases 2 --live-args="--flow-preset fast"
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["main"]

#: (label, scene, low-res (h, w), r, sensor)
CASES = (
    ("ToF 64×56 → 256×224, room", "room", (56, 64), 4, "tof"),
    ("160×120 → 320×240, animal", "gallop", (120, 160), 2, "laplace"),
    ("320×240 → 640×480, room", "room", (240, 320), 2, "laplace"),
)
FPS = 30
SUMMARY = re.compile(r"upsr live: (\d+) frames .* \(([\d.]+) frames/s, (.*), (\d+) dropped\)")
#: The latency figures of the summary (an older upsr gave the last frame's only: None).
LATENCY = re.compile(r"latency (\d+) ms median, (\d+) ms max")


def record(path: Path, scene: str, shape: tuple[int, int], r: int, sensor: str, n: int) -> None:
    """Write the case's recording (``n`` frames, paced at :data:`FPS`)."""
    from upsr.research.synth.realistic import degrade, make_realistic
    from upsr.research.synth.recording import write_realsense_recording

    video = make_realistic(scene, shape, scale=r, n_frames=n)
    low = degrade(video, sensor, np.random.default_rng(0), sigma_mm=10.0)
    write_realsense_recording(path, low, fps=FPS, real_time=True)


def run_live(recording: Path, r: int, out: Path, extra: Sequence[str] = ()) -> dict[str, Any]:
    """``upsr live RECORDING -o OUT -r R -q [extra]`` in a new process: its summary's
    figures."""
    out.unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "upsr", "live", str(recording), "-o", str(out), "-r", str(r)]
    proc = subprocess.run([*cmd, "-q", *extra], capture_output=True, text=True, check=False)
    m = SUMMARY.search(proc.stdout)
    if proc.returncode != 0 or m is None:
        raise RuntimeError(f"upsr live failed ({proc.returncode}): {proc.stdout}{proc.stderr}")
    done, fps, latency, dropped = m.groups()
    lat = LATENCY.search(latency)
    return {
        "frames": int(done),
        "fps": float(fps),
        "latency_median_ms": int(lat.group(1)) if lat else None,
        "latency_max_ms": int(lat.group(2)) if lat else None,
        "dropped": int(dropped),
        "written": int(np.load(out, mmap_mode="r").shape[0]),
    }


def _ms(value: int | None) -> str:
    return "–" if value is None else f"{value} ms"


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=90, help="frames per recording (3 s)")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--out", type=Path, default=Path("results/bench/live"))
    p.add_argument("--cases", type=int, nargs="+", help="indices of CASES to run (default: all)")
    p.add_argument(
        "--live-args", default="", help='more options of upsr live, e.g. "--flow-preset fast"'
    )
    args = p.parse_args(argv)
    extra = shlex.split(args.live_args)
    cases = [CASES[i] for i in args.cases] if args.cases else list(CASES)
    rows = []
    with tempfile.TemporaryDirectory(prefix="upsr-live-") as tmp:
        for label, scene, shape, r, sensor in cases:
            rec = Path(tmp) / f"{scene}_{shape[1]}x{shape[0]}.db3"
            record(rec, scene, shape, r, sensor, args.frames)
            runs = [run_live(rec, r, Path(tmp) / "out.npy", extra) for _ in range(args.runs)]
            runs.sort(key=lambda run: run["frames"])
            rows.append({"case": label, "recorded": args.frames, **runs[len(runs) // 2]})
            rows[-1]["runs"] = runs
            print(f"  {label}: done", flush=True)
    options = f" `{args.live_args}`" if args.live_args else ""
    lines = [
        f"upsr live{options}, SDK recordings of {args.frames} frames played in real time at "
        f"{FPS}/s",
        "",
        "| case | processed | dropped | frames/s | latency median | max | runs (processed / "
        "dropped) |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        each = ", ".join(f"{x['frames']}/{x['dropped']}" for x in row["runs"])
        lines.append(
            f"| {row['case']} | {row['frames']} | {row['dropped']} | {row['fps']:.1f} | "
            f"{_ms(row['latency_median_ms'])} | {_ms(row['latency_max_ms'])} | {each} |"
        )
    print("\n" + "\n".join(lines))
    args.out.mkdir(parents=True, exist_ok=True)
    result = {"fps_recorded": FPS, "frames": args.frames, "live_args": extra, "rows": rows}
    (args.out / "results.json").write_text(json.dumps(result, indent=2))
    (args.out / "results.md").write_text("\n".join(lines) + "\n")
    return result


if __name__ == "__main__":
    main()
