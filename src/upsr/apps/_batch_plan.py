"""Planning one recording of ``upsr batch``: probe, checks, per-video statistics, chunks.

Everything here runs before any of the recording's work (:func:`prepare_recording`): a
recording that fails a check is reported as failed, the others go on.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import math
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from upsr.apps._batch_state import WORK_DIR
from upsr.apps._chunks import chunk_plan
from upsr.errors import InputError
from upsr.method.config import UPSRConfig

if TYPE_CHECKING:
    from upsr.apps.batch import Recording

__all__ = ["prepare_recording"]


def _fingerprint(inp: Path, spec: dict[str, Any]) -> str:
    """What a chunk was made from: the input (its files' names, sizes, modification and
    change times, :func:`~upsr.apps._batch_state.input_identity`: a file rewritten with the
    same size and its old mtime restored, as ``cp -p``, ``rsync -t`` or a coarse file system
    leave it, has a new change time; its chunks were reused, mixing old and new frames) and
    the options ``spec``."""
    from upsr.apps._batch_state import input_identity

    p = Path(inp)
    blob = json.dumps([str(p.resolve()), input_identity(p), spec], sort_keys=True, default=str)
    return hashlib.sha1(blob.encode()).hexdigest()[:12]


def prepare_recording(
    rec: Recording,
    cfg: UPSRConfig,
    read: dict[str, Any],
    chunk_frames: int,
    workers: int,
    intrinsics: str | None,
    shrink_frames: bool = False,
    limits: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Probe, check the resources, compute the video statistics and plan the chunks of one
    recording (``limits``: ``out_fmt``, ``max_memory``, ``workers`` of the memory check,
    ``units``, and ``camera_motion``: "depth" registers by the camera's motion with the
    recording's intrinsics, refused where it has none)."""
    from upsr.apps._camera import camera_motion_config, input_camera
    from upsr.apps._preflight import check_first_frame, check_run_resources, check_scale_applies
    from upsr.io import identity
    from upsr.io import video as io

    lim = limits or {}
    sensor, strict, scale_given, out_scale = lim.get("units", ("default", False, False, 1000.0))
    # (this recording's failure)
    check_scale_applies([rec.input], read["fmt"], scale_given, read["topic"], read["depth_scale"])
    info = io.probe(rec.input, key=read["key"], fmt=read["fmt"], topic=read["topic"])
    if shrink_frames and cfg.n_frames > info.n_frames:
        cfg = dataclasses.replace(cfg, n_frames=info.n_frames)
    rec.config = cfg
    if cfg.n_frames > info.n_frames:
        raise InputError(
            f"N={cfg.n_frames} > {info.n_frames} frames in {rec.input}: use --frames "
            f"{info.n_frames} or less"
        )
    rec.n_frames = info.n_frames
    check_run_resources(
        info.shape,
        cfg,
        workers=lim.get("workers", workers),
        out_fmt=lim.get("out_fmt", "npy"),
        output=rec.output,
        max_memory=lim.get("max_memory"),
    )
    rec.camera = input_camera(rec.input, info, intrinsics, fmt=read["fmt"], topic=read["topic"])
    if lim.get("camera_motion", "flow") == "depth":
        cfg = rec.config = camera_motion_config(cfg, rec.camera, f"{rec.input}: ")
    rec.frame_names = identity.read_frame_names(rec.input, fmt=read["fmt"])
    rec.timestamps = identity.read_timestamps(
        rec.input, fmt=read["fmt"], topic=read["topic"], key=read["key"]
    )
    first = []
    # the first N frames only (not exhausted: their validity is not the whole video's)
    with contextlib.closing(io.iter_frames(rec.input, **read, stop=cfg.n_frames)) as frames:
        for frame in frames:
            first.append(frame)
            if len(first) == cfg.n_frames:
                break
    from upsr.method.statistics import pinned_config

    # the units of its first frame and the output's capacity, before any of its work
    check_first_frame(
        rec.input,
        next((f for f in first if (f > 0).any()), first[0]),
        rec.output,
        info.n_frames,
        in_fmt=info.format,
        out_fmt=lim.get("out_fmt", "npy"),
        units_options=(sensor, strict),
        scale_given=scale_given,
        scales=(read["depth_scale"], out_scale),
    )
    pinned = pinned_config(np.stack(first), cfg)
    m = chunk_frames or max(4 * cfg.n_frames, math.ceil(info.n_frames / max(workers, 1)))
    config = dataclasses.asdict(pinned)
    base = {
        "input": str(rec.input),
        **read,
        "config": config,
        "height": info.height,
        "width": info.width,
    }
    fp = _fingerprint(rec.input, {**base, "chunk_frames": m})
    work = rec.output.parent / WORK_DIR / f"{rec.output.name}.{fp}"
    # chunks of an earlier run with other inputs/options are stale
    with contextlib.suppress(OSError):
        for old in (rec.output.parent / WORK_DIR).glob(f"{rec.output.name}.*"):
            if old != work and old.name.rsplit(".", 1)[0] == rec.output.name:
                shutil.rmtree(old, ignore_errors=True)
    rec.work = work
    specs = []
    for a, b, lo, hi in chunk_plan(info.n_frames, cfg.n_frames, m):
        part = work / f"chunk_{a:09d}_{b:09d}.npy"
        specs.append(
            {
                **base,
                "out_start": a,
                "out_stop": b,
                "in_start": lo,
                "in_stop": hi,
                "part": str(part),
            }
        )
    return specs
