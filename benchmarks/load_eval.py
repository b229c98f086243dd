"""Speed beside another busy process: the OpenMP wait policy of the compiled kernels.

A camera's host runs other work (a robot's planner, a game). numba's parallel kernels run on
OpenMP threads, and by the OpenMP runtime's default a thread that waits for work spins; with
another process on one of the two cores, a spinning thread holds its core while the thread it
waits for is descheduled, and every parallel kernel waits a scheduler slice. ``import upsr``
therefore sets ``OMP_WAIT_POLICY=PASSIVE`` unless the user set it (``upsr/__init__.py``).

For each wait policy (upsr's ``PASSIVE``; the runtime's default, reached by an empty value,
which libgomp rejects with a warning and ignores) and each load (nothing else running; one
process spinning on a core), a child process streams the dense ToF room (64×56 → 256×224,
r = 4, N = 9, σ = 10 mm, :mod:`upsr.research.synth.realistic`) through the recursive mode
frame by frame (``push``) and through the windowed mode (``push``, windows side by side on
both cores), and a 320×240 → 640×480 room through the recursive mode: frames per second after
warm-up and CPU ms per frame (all threads of the child): the median of three runs (the
policies alternating) and the slowest and fastest of them (under load the runtime's default
collapses in some runs and not in others, by where the scheduler puts the threads).

Example::

    .venv/bin/python benchmarks/load_eval.py --out docs/results/load
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["main"]

#: (label, scene, low-res shape, r, mode, frames timed after warm-up)
CASES = (
    ("ToF 64×56 → 256×224, recursive", "room", (56, 64), 4, "recursive", 60),
    ("ToF 64×56 → 256×224, windowed", "room", (56, 64), 4, "windowed", 60),
    ("320×240 → 640×480, recursive", "room", (240, 320), 2, "recursive", 20),
)
#: OMP_WAIT_POLICY values: upsr's, and "" (invalid: the OpenMP runtime's own default).
POLICIES = {"PASSIVE (upsr)": "PASSIVE", "runtime default": ""}
#: Runs per case and policy (the median is reported).
RUNS = 3


def _child(case_json: str) -> None:
    """In the child process (its OMP_WAIT_POLICY set before upsr loads numba's OpenMP layer):
    stream one case twice (the first compiles and warms up) and print the second's frames/s
    and CPU ms per frame as one JSON line."""
    import upsr
    from upsr.research.synth.realistic import degrade, make_realistic

    scene, h, w, r, mode, timed = json.loads(case_json)
    n = 9
    video = make_realistic(scene, (h, w), scale=r, n_frames=n + timed)
    sensor = "tof" if r == 4 else "laplace"
    low = degrade(video, sensor, np.random.default_rng(0), sigma_mm=10.0)

    def stream() -> tuple[float, float]:
        engine = upsr.UPSR(r, n, mode=mode)
        start = cpu = 0.0
        for k, frame in enumerate(low):
            if k == n:
                start, cpu = time.perf_counter(), time.process_time()
            engine.push(frame)
        return (time.perf_counter() - start) / timed, (time.process_time() - cpu) / timed

    stream()  # compile, warm up
    wall, cpu = stream()
    print(json.dumps({"fps": 1.0 / wall, "cpu_ms_per_frame": 1000.0 * cpu}))


def _spin(stop: Any) -> None:
    while not stop.is_set():
        pass


def _run_once(case: tuple, policy: str) -> dict[str, float]:
    _, scene, (h, w), r, mode, timed = case
    env = dict(os.environ, OMP_WAIT_POLICY=policy)
    arg = json.dumps([scene, h, w, r, mode, timed])
    done = subprocess.run(
        [sys.executable, __file__, "--child", arg],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="results/load")
    p.add_argument("--child", help=argparse.SUPPRESS)  # (one case, in the child process)
    args = p.parse_args(argv)
    if args.child:
        _child(args.child)
        return 0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for busy in (0, 1):
        stop = mp.Event()
        spinners = [mp.Process(target=_spin, args=(stop,), daemon=True) for _ in range(busy)]
        for s in spinners:
            s.start()
        try:
            for case in CASES:
                runs: dict[str, list[dict[str, float]]] = {label: [] for label in POLICIES}
                for _ in range(RUNS):
                    for label, policy in POLICIES.items():
                        runs[label].append(_run_once(case, policy))
                for label, done in runs.items():
                    res = {k: float(np.median([d[k] for d in done])) for k in done[0]}
                    fps = [d["fps"] for d in done]
                    res |= {"fps_min": min(fps), "fps_max": max(fps), "runs": done}
                    rows.append({"case": case[0], "busy_processes": busy, "policy": label, **res})
                    print(
                        f"  {case[0]:34s} busy {busy}  {label:16s} {res['fps']:7.1f} frames/s "
                        f"({min(fps):.1f}-{max(fps):.1f}) {res['cpu_ms_per_frame']:6.1f} ms CPU",
                        flush=True,
                    )
        finally:
            stop.set()
            for s in spinners:
                s.join()
    command = "benchmarks/load_eval.py " + " ".join(sys.argv[1:] if argv is None else argv)
    payload = {"command": command, "date": time.strftime("%Y-%m-%d %H:%M"), "results": rows}
    (out / "results.json").write_text(json.dumps(payload, indent=2))
    lines = [
        "# Speed beside another busy process",
        "",
        f"`{command}` ({payload['date']}, {os.cpu_count()} cores)",
        "",
        "| case | busy processes | OMP_WAIT_POLICY | frames/s, median (min–max) | "
        "CPU ms per frame |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| {r['case']} | {r['busy_processes']} | {r['policy']} | {r['fps']:.1f} "
        f"({r['fps_min']:.1f}–{r['fps_max']:.1f}) | {r['cpu_ms_per_frame']:.1f} |"
        for r in rows
    ]
    (out / "results.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out / 'results.json'} and results.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
