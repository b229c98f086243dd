"""How ``upsr batch`` splits a recording into chunks, and the helpers of one chunk (run in a
worker): its config, its engine, its part; the check of the batch options."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from upsr.errors import InputError
from upsr.method.config import UPSRConfig

#: output suffix per format (a folder for png, exr and rosbag)
_OUT_SUFFIX = {"npy": ".npy", "npz": ".npz", "tiff": ".tif", "png": "", "exr": "", "rosbag": ""}


def _config_from_dict(d: dict[str, Any]) -> UPSRConfig:
    from upsr.method.config import DeblurConfig

    d = dict(d)
    deblur = DeblurConfig(**d.pop("deblur"))
    if d.get("depth_range_mm") is not None:
        d["depth_range_mm"] = tuple(d["depth_range_mm"])
    return UPSRConfig(deblur=deblur, **d)


def _part_ok(part: Path, n: int, shape: tuple[int, int]) -> bool:
    if not part.is_file():
        return False
    try:
        arr = np.load(part, mmap_mode="r", allow_pickle=False)
        return tuple(arr.shape) == (n, *shape) and arr.dtype == np.float32
    except Exception:
        return False


def _chunk_engine(cfg: UPSRConfig, keep: range) -> Any:
    """A one-thread UP-SR engine that finishes only the windows of the outputs in ``keep``.

    Every frame is still ingested (prefilter, flows: later windows need them); the windows of
    the other outputs (those before the chunk's first output and after its last, which only
    exist because the chunk's input overlaps its neighbours') are not computed: their output
    is None.
    """
    from upsr.method.windowed import UPSR

    class ChunkEngine(UPSR):
        def _finish(self, t: int, n_total: int) -> Any:
            if t not in keep:
                return None
            return super()._finish(t, n_total)

        def flush(self) -> list[Any]:
            # a chunk without depth (a camera covered at the end) is part of a recording
            # whose depth the plan checked: its outputs are 0, as a single run gives them
            self._any_valid = True
            return super().flush()

    # the cluster runs chunks side by side: one thread per chunk, no window threads
    return ChunkEngine(config=cfg, workers=0)


def chunk_plan(n_total: int, n_frames: int, chunk_frames: int) -> list[tuple[int, int, int, int]]:
    """Split a video into chunks that give exactly the outputs of a single run.

    Parameters
    ----------
    n_total : int
        T, frames of the video.
    n_frames : int
        N, window length (1 ≤ N ≤ T).
    chunk_frames : int
        Output frames per chunk (≥ 1; the last chunk may be shorter).

    Returns
    -------
    list of (out_start, out_stop, in_start, in_stop)
        Chunk k produces the outputs [out_start, out_stop) from the input frames
        [in_start, in_stop) = [s(out_start), s(out_stop − 1) + N), where s is the window start
        of a single run; every window of the chunk then lies inside its input frames and is
        placed where the single run places it.
    """
    if n_frames < 1 or n_total < n_frames:
        raise InputError(f"N={n_frames} frames per window but the video has {n_total} frame(s)")
    if chunk_frames < 1:
        raise InputError(f"chunk_frames must be >= 1, got {chunk_frames}")
    half = (n_frames - 1) // 2

    def start(t: int) -> int:
        return min(max(t - half, 0), n_total - n_frames)

    plan = []
    for a in range(0, n_total, chunk_frames):
        b = min(a + chunk_frames, n_total)
        plan.append((a, b, start(a), start(b - 1) + n_frames))
    return plan


def _check_batch_options(
    out: Path, output_format: str | None, workers: int | None, chunk_frames: int
) -> str:
    """Check the options of :func:`run_batch` (before any work); return the output format."""
    from upsr.apps._preflight import max_workers

    most = max_workers()
    if workers is not None and not 1 <= workers <= most:
        raise InputError(f"--workers must be 1..{most}, got {workers}")
    if chunk_frames < 0:
        raise InputError(f"--chunk-frames must be >= 0, got {chunk_frames}")
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    out_fmt = (output_format or "npy").lower()
    if out_fmt not in _OUT_SUFFIX:
        raise InputError(
            f"cannot write {output_format!r} (output formats: {', '.join(_OUT_SUFFIX)})"
        )
    return out_fmt
