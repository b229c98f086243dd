"""What the estimated motion costs: the windowed mode with the scenes' true motion.

A diagnostic beside ``realistic_eval.py``. On the scenes seen by a moving camera (a static
scene: every pixel's true motion between two frames follows from the truth's depth and the
camera poses, :func:`upsr.method.camera_motion.reproject`), the windowed mode runs four
times on the same frames (on a static camera's scenes, whose bodies move on their own, the
first and the last):

* ``upsr``: the defaults;
* ``upsr_full_grid``: the flow estimated on the output grid (``flow_scale`` = r), the grid
  of the true motion below (separates the grid's effect from the estimate's);
* ``upsr_true_motion``: the registration of every window (the maps from the reference to each
  frame, and each frame's samples carried to the reference) replaced by the true motion; all
  the rest (trust, radial offsets, fusion, finishing) as in the defaults;
* ``upsr_depth_motion``: the defaults with ``camera_motion="depth"`` and the scene's
  intrinsics (:mod:`upsr.method.camera_motion`: the camera's motion estimated from the noisy
  frames themselves, used in the windows where it goes along the optical axis and at the
  pixels whose flow agrees with it).

Beside nearest and bicubic upsampling it reports the SPEC §6 accuracy, the pixels more than
the edge tolerance (100 mm) off per pixel of the truth's edge lines ("misplaced per edge px":
where the overall rmse comes from), and the estimated registration's error against the true
motion (low-res px) near the truth's edges and elsewhere.

Example::

    .venv/bin/python benchmarks/registration_oracle.py --scenes toward_wall room gallop \\
        deforming --seeds 0 1 2 --sigma 0 10 --out results/registration_oracle
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import upsr
import upsr.method.windowed as windowed
from upsr.geometry.camera import PinholeCamera
from upsr.method.camera_motion import pose_maps, pose_samples
from upsr.research import baselines
from upsr.research.metrics import (
    DISCONTINUITY_MM,
    EDGE_TOLERANCE_MM,
    evaluate,
    near_discontinuity,
)
from upsr.research.synth.realistic import RealisticVideo, make_realistic

sys.path.insert(0, str(Path(__file__).resolve().parent))
from realistic_eval import sensor_frames

METRICS = ("rmse", "surface_rmse", "edge_accuracy", "flying_pixels", "missing")
SHARES = ("edge_accuracy", "flying_pixels", "missing")
REGISTRATION = ("reg_err_edges_median", "reg_err_edges_p90", "reg_err_surfaces_median")


@dataclass(frozen=True)
class Motion:
    """A registration from camera poses: each output pixel of a reference frame carried by
    its depth ``depth`` (T, r·h, r·w), each low-res sample by its depth ``lowres`` (T, h, w),
    through the poses ``world_to_camera`` (T, 4, 4) of the low-res ``camera``."""

    world_to_camera: np.ndarray
    depth: np.ndarray
    lowres: np.ndarray
    camera: PinholeCamera
    scale: int

    @classmethod
    def true(cls, video: RealisticVideo) -> Motion:
        """The scene's own motion (its poses, the truth's depth, the clean samples)."""
        assert video.world_to_camera is not None
        return cls(video.world_to_camera, video.truth, video.lowres, video.camera, video.scale)

    def maps(self, t: int, frames: range) -> np.ndarray:
        """(N, H, W, 2) float32: where each output pixel of frame t lies in each frame of
        ``frames``, as displacements (output px); 0 where there is no depth."""
        cam = self.camera.scaled(self.scale)
        out = np.empty((len(frames), cam.height, cam.width, 2), np.float32)
        poses = self.world_to_camera[list(frames)]
        return pose_maps(self.depth[t], _intrinsics(cam), poses, list(frames).index(t), out)

    def samples(self, k: int, m: int) -> np.ndarray:
        """(h, w, 2) float64: frame k's low-res sample centres in frame m (output px)."""
        poses = self.world_to_camera
        return pose_samples(
            self.lowres[k], _intrinsics(self.camera), self.scale, poses[k], poses[m]
        )


def _intrinsics(camera: PinholeCamera) -> tuple[float, float, float, float]:
    return camera.fx, camera.fy, camera.cx, camera.cy


@contextlib.contextmanager
def window_maps(make: Callable[[dict[str, int], Callable], Callable]) -> Iterator[None]:
    """The windowed engine's ``cumulative_flows`` replaced by ``make(window, original)``,
    where ``window`` holds the reference t and first frame s of the window being finished."""
    window: dict[str, int] = {}
    finish, cumulative = windowed.UPSR._finish, windowed.cumulative_flows

    def _finish(self, t, n_total):  # type: ignore[no-untyped-def]
        window["t"], window["s"] = t, windowed.window_start(t, n_total, self.config)
        return finish(self, t, n_total)

    windowed.UPSR._finish = _finish  # type: ignore[method-assign]
    windowed.cumulative_flows = make(window, cumulative)
    try:
        yield
    finally:
        windowed.UPSR._finish = finish  # type: ignore[method-assign]
        windowed.cumulative_flows = cumulative


@contextlib.contextmanager
def registered_by(motion: Motion) -> Iterator[None]:
    """Replace the windowed engine's registration by ``motion`` (``flow_scale`` = r)."""

    def make(window, _):  # type: ignore[no-untyped-def]
        def _cumulative(ref, backward, forward, shape, *, out, **_):  # type: ignore[no-untyped-def]
            assert shape == motion.depth.shape[1:], "a registration from poses needs flow_scale = r"
            out[...] = motion.maps(window["t"], range(window["s"], window["s"] + len(out)))
            return list(out)

        return _cumulative

    chain = windowed.UPSR._chain
    windowed.UPSR._chain = lambda self, k, m: motion.samples(k, m)  # type: ignore[method-assign]
    try:
        with window_maps(make):
            yield
    finally:
        windowed.UPSR._chain = chain  # type: ignore[method-assign]


def captured_maps(store: list) -> contextlib.AbstractContextManager[None]:
    """Keep (t, first frame, maps) of every window the engine registers."""

    def make(window, cumulative):  # type: ignore[no-untyped-def]
        def _cumulative(*args, out, **kwargs):  # type: ignore[no-untyped-def]
            res = cumulative(*args, out=out, **kwargs)
            store.append((window["t"], window["s"], out.copy()))
            return res

        return _cumulative

    return window_maps(make)


def edge_lines(truth: np.ndarray) -> np.ndarray:
    """Truth pixels with a 4-neighbour more than the discontinuity threshold away."""
    m = np.zeros(truth.shape, bool)
    for ax in (-2, -1):
        step = np.abs(np.diff(truth, axis=ax)) > DISCONTINUITY_MM
        lo = [slice(None)] * truth.ndim
        hi = [slice(None)] * truth.ndim
        lo[ax], hi[ax] = slice(1, None), slice(None, -1)
        m[tuple(lo)] |= step
        m[tuple(hi)] |= step
    return m & (truth > 0)


def misplaced_per_edge_px(est: np.ndarray, truth: np.ndarray) -> float:
    """Pixels more than the edge tolerance off, per pixel of the truth's edge lines (each
    edge counted once)."""
    off = (est > 0) & (truth > 0) & (np.abs(est - truth) > EDGE_TOLERANCE_MM)
    return float(off.sum() / max(edge_lines(truth).sum() / 2, 1))


def registration_error(video: RealisticVideo, store: list) -> dict[str, float]:
    """Median and 90th percentile (low-res px) of |estimated − true| map, near the truth's
    edges (within r px) and on the surfaces."""
    r = video.scale
    truth = Motion.true(video)
    near_e, surf = [], []
    for t, s, maps in store:
        err = np.linalg.norm(maps - truth.maps(t, range(s, s + len(maps))), axis=-1) / r
        edge = near_discontinuity(video.truth[t], r)
        valid = video.truth[t] > 0
        for i in range(len(maps)):
            if s + i != t:
                near_e.append(err[i][edge & valid])
                surf.append(err[i][~edge & valid])
    e, f = np.concatenate(near_e), np.concatenate(surf)
    return {
        "reg_err_edges_median": float(np.median(e)),
        "reg_err_edges_p90": float(np.quantile(e, 0.9)),
        "reg_err_surfaces_median": float(np.median(f)),
    }


#: Sensor models (:func:`upsr.research.synth.realistic.degrade`) and their row labels, as in
#: ``realistic_eval.py`` (the same noise for the same label and seed).
SENSORS = {"laplace": "laplace", "gaussian": "gauss", "tof": "tof"}


def run_case(
    scene: str, seed: int, sigma: float, n: int, frames: int, sensor: str = "laplace"
) -> list[dict[str, Any]]:
    """The rows of one scene, seed, sensor and σ (a static camera's scenes: no true-motion
    rows)."""
    video = make_realistic(scene, (56, 64), scale=4, n_frames=frames, seed=seed)
    r = video.scale
    label = f"{SENSORS[sensor]}{sigma:g}"
    low = sensor_frames(video, label, sensor, sigma, seed)
    outs = {
        "nearest": baselines.nearest(low, r),
        "bicubic": baselines.bicubic(low, r),
        "upsr": np.stack(list(upsr.UPSR(r, n, workers=0).process(low))),
    }
    reg: dict[str, float] = {}
    if video.world_to_camera is not None:
        store: list = []
        with captured_maps(store):
            outs["upsr_full_grid"] = np.stack(
                list(upsr.UPSR(r, n, workers=0, flow_scale=r).process(low))
            )
        with registered_by(Motion.true(video)):
            outs["upsr_true_motion"] = np.stack(
                list(upsr.UPSR(r, n, workers=0, flow_scale=r).process(low))
            )
        reg = registration_error(video, store)
    depth = upsr.UPSR(r, n, workers=0, camera_motion="depth",
                      camera_intrinsics=_intrinsics(video.camera))  # fmt: skip
    outs["upsr_depth_motion"] = np.stack(list(depth.process(low)))
    rows = []
    for method, est in outs.items():
        m = evaluate(est, video.truth, r)
        row = {"scene": scene, "seed": seed, "sensor": label, "method": method}
        row.update({k: float(m[k]) for k in METRICS})
        row["misplaced_per_edge_px"] = misplaced_per_edge_px(est, video.truth)
        if method == "upsr_full_grid":
            row.update(reg)
        rows.append(row)
    return rows


def _fmt(row: dict[str, Any]) -> str:
    cells = [row["scene"], str(row["seed"]), row["sensor"], row["method"]]
    for k in (*METRICS, "misplaced_per_edge_px"):
        cells.append(f"{100 * row[k]:.2f}" if k in SHARES else f"{row[k]:.3f}")
    reg = [row.get(k) for k in REGISTRATION]
    cells.append(" / ".join(f"{x:.2f}" for x in reg) if reg[0] is not None else "–")
    return "| " + " | ".join(cells) + " |"


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=["toward_wall", "room"])
    p.add_argument("--seeds", nargs="+", type=int, default=[0])
    p.add_argument("--sensor", default="laplace", choices=list(SENSORS))
    p.add_argument("--sigma", nargs="+", type=float, default=[0.0, 10.0], help="noise σ (mm)")
    p.add_argument("--frames", type=int, default=9)
    p.add_argument("-n", type=int, default=9, help="window N")
    p.add_argument("--out", type=Path, default=Path("results/registration_oracle"))
    args = p.parse_args(argv)
    header = (
        "| scene | seed | sensor | method | rmse | surface rmse | edge % | flying % | missing % "
        "| misplaced per edge px | registration error near edges median / p90, surfaces "
        "median (low-res px) |\n|" + "---|" * 11
    )
    print(header)
    rows = []
    for scene in args.scenes:
        for seed in args.seeds:
            for sigma in args.sigma:
                for row in run_case(scene, seed, sigma, args.n, args.frames, args.sensor):
                    rows.append(row)
                    print(_fmt(row), flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "results.json").write_text(json.dumps(rows, indent=1))
    cmd = "benchmarks/registration_oracle.py " + " ".join(argv or sys.argv[1:])
    (args.out / "results.md").write_text(
        "# The windowed mode with the true motion\n\n`" + cmd.strip() + "`\n\n" + header + "\n"
        + "\n".join(_fmt(r) for r in rows) + "\n"
    )  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
