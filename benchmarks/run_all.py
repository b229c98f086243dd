"""Run every benchmark (``make bench``): speed (ToF always; Samba, speed-up and memory when the
Samba meshes are at ``--data``, default ``../shared/data``), speed beside a busy process,
``upsr live`` on SDK recordings played in real time (with pyrealsense2), the flow grid, the
synthetic scenes, the realistic sensor scenes (``--out docs/results`` writes them to
docs/results/realistic), the scenes built outside the rules' development (an audit), the
companding of disparity-quantised depth (its knee's fit, its knee step), whether the
sensor mixes depths at edges (the mixed-pixel removal's decision), stray
far values and ``--valid-range``, close range and
``--edge-mm``, thin parts on a ToF sensor, the deblurring iterations and speckle removal, and
the Samba accuracy tables. Each benchmark prints its table and writes ``results.json`` under
``--out``."""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import close_range_eval
import companding_eval
import deblur_eval
import flow_grid_eval
import footprint_eval
import live_eval
import load_eval
import memory_eval
import outside_eval
import realistic_eval
import samba_eval
import speed_eval
import stray_eval
import synthetic_eval
import thin_parts_eval


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="results/bench")
    p.add_argument("--data", default=str(samba_eval.DEFAULT_DATA))
    args = p.parse_args()
    out = Path(args.out)
    print("== speed ==", flush=True)
    speed_eval.main(["--data", args.data, "--out", str(out / "speed")])
    print("\n== peak memory against the estimate the commands check ==", flush=True)
    memory_eval.main(["--out", str(out / "memory")])
    print("\n== speed beside another busy process (the kernels' OpenMP wait policy) ==", flush=True)
    load_eval.main(["--out", str(out / "load")])
    print("\n== upsr live on SDK recordings played in real time ==", flush=True)
    if importlib.util.find_spec("pyrealsense2") is None:
        print("pyrealsense2 is not installed (pip install 'upsr[realsense]'): skipped")
    else:
        live_eval.main(["--out", str(out / "live")])
    print("\n== flow grid ==", flush=True)
    flow_grid_eval.main(["--data", args.data, "--out", str(out / "flow_grid")])
    print("\n== synthetic scenes ==", flush=True)
    synthetic_eval.main(["--out", str(out / "synthetic")])
    print("\n== realistic sensors (ToF footprint, Kinect, large and camera motion) ==", flush=True)
    realistic_eval.main(["--out", str(out / "realistic")])
    print("\n== scenes built outside the rules' development (an audit) ==", flush=True)
    outside_eval.main(["--out", str(out / "outside")])
    print("\n== the companding of depth quantised in disparity ==", flush=True)
    companding_eval.main(["--out", str(out / "companding")])
    print("\n== whether the sensor mixes depths at edges (remove_mixed=auto) ==", flush=True)
    footprint_eval.main(["--out", str(out / "footprint")])
    print("\n== a camera at close range and --edge-mm ==", flush=True)
    close_range_eval.main(["--out", str(out / "close_range")])
    print("\n== a sensor's stray far values and --valid-range ==", flush=True)
    stray_eval.main(["--out", str(out / "stray")])
    print("\n== thin parts on a ToF sensor (random bars, with and without split) ==", flush=True)
    thin_parts_eval.main(["--out", str(out / "thin_parts")])
    print("\n== deblurring iterations and speckle removal ==", flush=True)
    deblur_eval.main(["--data", args.data, "--out", str(out / "deblur")])
    if (Path(args.data) / "samba" / "mesh_0000.obj").is_file():
        for r in (2, 4):
            print(f"\n== Samba, r = {r} ==", flush=True)
            samba_eval.main(
                ["--data", args.data, "--scale", str(r), "--out", str(out / f"samba_r{r}")]
            )
    else:
        print(f"\nSamba meshes not found under {args.data}: Samba benchmark skipped")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
