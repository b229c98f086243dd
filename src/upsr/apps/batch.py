"""Super-resolve many recordings: on this machine's cores or on a Dask distributed cluster.

Each recording is split into chunks of consecutive output frames; a chunk reads the input
frames its windows need (UP-SR's window for output t is the frames [s, s + N) with
s = clip(t − (N−1)//2, 0, T − N), :func:`upsr.method.windowed.window_start`), so
neighbouring chunks overlap by N − 1 input frames. Every choice the engine fixes once per video
from its first N frames (the flow images' 8-bit depth mapping, the noise estimate, the fusion's
estimator and trust noise: :func:`upsr.method.statistics.pinned_config`) is made once per
recording and given to every chunk: the result is identical, frame for frame, to a single run
over the whole recording.

Chunks run in worker processes (``workers``) or as tasks on an existing Dask scheduler
(``scheduler="tcp://host:port"``, the ``[dask]`` extra; inputs and the output folder must be
reachable under the same paths by the workers, e.g. a shared file system). Every chunk is
written atomically into a hidden work folder (``OUT/.upsr-batch/``), the recording's output
is assembled from its chunks and renamed into place when complete; then its chunks are
removed. Run again after an interruption: finished outputs are skipped and finished chunks of
unfinished recordings are reused (when the input and every option are unchanged). A recording
that fails is reported, its partial chunks are removed, and the others go on.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from upsr._atomic import remove_stale_in
from upsr.apps._batch_plan import prepare_recording
from upsr.apps._batch_state import (
    WORK_DIR,
    _batch_folder,
    _check_out_vs_inputs,
    _differences,
    _options_record,
    _read_record,
    _write_record,
    input_identity,
)
from upsr.apps._chunks import (
    _OUT_SUFFIX,
    _check_batch_options,
    _chunk_engine,
    _config_from_dict,
    _part_ok,
    chunk_plan,
)
from upsr.apps._executors import _DaskExecutor, _LocalExecutor, check_scheduler_address
from upsr.errors import InputError
from upsr.method.config import UPSRConfig

__all__ = [
    "BatchResult",
    "Recording",
    "chunk_plan",
    "output_name",
    "run_batch",
    "run_chunk",
]


# ---------------------------------------------------------------------------------------------
# planning
# ---------------------------------------------------------------------------------------------
# ---------------------------------------------------------------------------------------------
# the task (runs in a worker process)
# ---------------------------------------------------------------------------------------------
def run_chunk(spec: dict[str, Any]) -> dict[str, Any]:
    """Compute one chunk and write it (atomically) to ``spec["part"]`` as ``.npy``.

    ``spec`` is a plain dict (it crosses process and network boundaries): ``input``, read
    options ``key``/``topic``/``fmt``/``depth_scale``, ``config`` (:class:`UPSRConfig` fields),
    ``out_start``, ``out_stop``, ``in_start``, ``in_stop``, ``part``.

    Returns
    -------
    dict
        ``{"part", "frames", "seconds", "reused"}``, or ``{"error", "kind"}`` (kind "input"
        for bad input, "internal" otherwise) — a task never raises.
    """
    try:
        return _run_chunk(spec)
    except InputError as e:
        return {"error": str(e), "kind": "input"}
    except Exception as e:
        detail = "".join(traceback.format_exception_only(type(e), e)).strip()
        return {"error": detail, "kind": "internal"}


def _run_chunk(spec: dict[str, Any]) -> dict[str, Any]:
    from upsr.io import video as io

    start = time.perf_counter()
    cfg = _config_from_dict(spec["config"])
    a, b, lo, hi = spec["out_start"], spec["out_stop"], spec["in_start"], spec["in_stop"]
    part = Path(spec["part"])
    out_shape = (spec["height"] * cfg.scale, spec["width"] * cfg.scale)
    if _part_ok(part, b - a, out_shape):
        return {"part": str(part), "frames": b - a, "seconds": 0.0, "reused": True}
    # only the input frames [lo, hi) the chunk's windows need are read (the format seeks)
    frames = io.iter_frames(
        spec["input"],
        key=spec["key"],
        topic=spec["topic"],
        fmt=spec["fmt"],
        depth_scale=spec["depth_scale"],
        start=lo,
        stop=hi,
    )
    # the chunk is a video of hi - lo frames; its outputs a - lo ... b - lo - 1 are kept
    engine = _chunk_engine(cfg, range(a - lo, b - lo))
    part.parent.mkdir(parents=True, exist_ok=True)
    with (
        contextlib.closing(frames),
        io.VideoWriter(part, n_frames=b - a, fmt="npy", overwrite=True) as writer,
    ):
        for t, out in enumerate(engine.process(frames), start=lo):
            if a <= t < b:
                writer.write(out)
    return {
        "part": str(part),
        "frames": b - a,
        "seconds": time.perf_counter() - start,
        "reused": False,
    }


# ---------------------------------------------------------------------------------------------
# recordings
# ---------------------------------------------------------------------------------------------
@dataclass
class Recording:
    """One input of a batch and what became of it.

    Attributes
    ----------
    input : pathlib.Path
    output : pathlib.Path
    status : str
        "pending", "done", "skipped" (output already there) or "failed".
    error : str
        Why it failed.
    error_kind : str
        "input" (bad input, exit status 2) or "internal" (status 1).
    n_frames, seconds : int, float
    """

    input: Path
    output: Path
    status: str = "pending"
    error: str = ""
    error_kind: str = ""
    n_frames: int = 0
    seconds: float = 0.0
    chunks: list[dict[str, Any]] = field(default_factory=list)
    done_chunks: int = 0
    camera: Any = None
    work: Path | None = None
    config: UPSRConfig | None = None
    frame_names: list[str] | None = None
    timestamps: Any = None


@dataclass
class BatchResult:
    """Outcome of :func:`run_batch`: the recordings and an exit status (0, 1 or 2)."""

    recordings: list[Recording]

    @property
    def failed(self) -> list[Recording]:
        """Recordings that failed."""
        return [r for r in self.recordings if r.status == "failed"]

    @property
    def exit_code(self) -> int:
        """0 all fine; 2 some failed on bad input; 1 some failed internally."""
        if any(r.error_kind == "internal" for r in self.failed):
            return 1
        return 2 if self.failed else 0


def output_name(path: Path) -> str:
    """Base name of a recording's output: the file's stem or the folder's name."""
    p = Path(os.path.abspath(path))
    if p.suffix.lower() in (".db3", ".mcap") and (p.parent / "metadata.yaml").is_file():
        p = p.parent
    return p.stem if p.is_file() else p.name


def _assemble(
    rec: Recording,
    cfg: UPSRConfig,
    out_fmt: str | None,
    depth_scale: float,
    keep_names: bool = True,
) -> None:
    """Write the output of ``rec`` from its chunks, with its intrinsics sidecar (published
    with the video: a failing sidecar leaves no complete-looking output)."""
    from upsr.apps._camera import intrinsics_sidecar
    from upsr.io import video as io

    out_cam = None if rec.camera is None else rec.camera.scaled(cfg.scale)
    with io.VideoWriter(
        rec.output,
        n_frames=rec.n_frames,
        fmt=out_fmt,
        depth_scale=depth_scale,
        overwrite=True,
        frame_names=rec.frame_names if keep_names else None,
        timestamps_ns=rec.timestamps,
        camera=out_cam,
    ) as writer:
        text = intrinsics_sidecar(rec.camera, cfg.scale, rec.timestamps, rec.frame_names)
        if text is not None:
            writer.add_sidecar(io.intrinsics_path(rec.output), text)
        measured = False
        for spec in rec.chunks:
            part = np.load(spec["part"], mmap_mode="r", allow_pickle=False)
            for frame in part:
                measured = measured or bool((frame > 0).any())
                writer.write(np.asarray(frame))
            del part
        if not measured:  # (a chunk without depth is fine, a recording without any is not)
            raise InputError(f"{rec.input}: no valid depth in any frame (all pixels are 0 or NaN)")
    _drop_work(rec)


def _drop_work(rec: Recording) -> None:
    if rec.work is not None:
        shutil.rmtree(rec.work, ignore_errors=True)
        with contextlib.suppress(OSError):
            rec.work.parent.rmdir()  # only if empty


def run_batch(
    inputs: Sequence[str | os.PathLike[str]],
    out_dir: str | os.PathLike[str],
    config: UPSRConfig,
    *,
    key: str | None = None,
    topic: str | None = None,
    input_format: str | None = None,
    depth_scale: float = 1000.0,
    output_format: str | None = None,
    intrinsics: str | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    chunk_frames: int = 0,
    overwrite: bool = False,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
    shrink_frames: bool = False,
    output_depth_scale: float = 1000.0,
    max_memory: int | None = None,
    keep_names: bool = True,
    sensor: str = "default",
    strict_units: bool = False,
    scale_given: bool = False,
    camera_motion: str = "flow",
) -> BatchResult:
    """Super-resolve every recording of ``inputs`` into ``out_dir``.

    Parameters
    ----------
    inputs : sequence of path-like
        Recordings (any input format of :mod:`upsr.io`).
    out_dir : path-like
        Output folder (created). Output ``<name>.npy`` per recording (``output_format``
        chooses npz, tiff, png or exr), plus ``<output>.intrinsics.json`` when the intrinsics
        are known.
    config : UPSRConfig
        Method parameters (as ``upsr run``).
    key, topic, input_format, depth_scale
        Read options, as for :func:`upsr.io.iter_frames` (``depth_scale``: the input's raw
        units per metre).
    intrinsics : str, optional
        ``"fx,fy,cx,cy"`` of the inputs (else read from the format when it carries them).
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://host:port``); default: local
        processes.
    workers : int, optional
        Local worker processes (default: the number of CPU cores; 1 = in this process).
    chunk_frames : int
        Output frames per chunk; 0 = automatic (about T / workers, at least 4·N).
    overwrite : bool
        Recompute outputs that exist (default: skip them: resuming).
    progress : bool
        A progress bar over the recordings on stderr.
    log : callable, optional
        Receives one line per finished, skipped or failed recording.
    shrink_frames : bool
        A recording shorter than N frames uses all its frames (N = T) instead of failing.
    output_depth_scale : float
        PNG/TIFF/EXR outputs: raw units per metre (1000: mm).
    max_memory : int, optional
        Bytes a recording's work may use (``--max-memory``) instead of what is available:
        each recording's estimate is checked before its work.
    keep_names : bool
        PNG/EXR folder outputs keep the input's frame names (False: 000000, …).
    camera_motion : {"flow", "depth"}
        ``UPSRConfig.camera_motion``, with each recording's intrinsics (none: it fails).
    sensor, strict_units, scale_given
        Each recording's first frame is checked as by ``upsr run`` (the plausible range of
        ``sensor``, refused with ``strict_units``, else warned; TUM PNGs read as mm refused
        unless ``scale_given``: the input depth scale was given), and so is its output's
        capacity, before its work: a failing recording is reported, the others go on.

    Returns
    -------
    BatchResult
    """
    # absolute paths: the tasks run in workers with other working directories
    out = Path(os.path.abspath(out_dir))
    if not inputs:
        raise InputError("no input recordings given")
    if camera_motion not in ("flow", "depth"):
        raise InputError(f"camera_motion must be 'flow' or 'depth', not {camera_motion!r}")
    out_fmt = _check_batch_options(out, output_format, workers, chunk_frames)
    if scheduler is not None:
        check_scheduler_address(scheduler)
    recs = _recordings(inputs, out, _OUT_SUFFIX[out_fmt])
    _check_out_vs_inputs(out, recs)
    read = {"key": key, "topic": topic, "fmt": input_format, "depth_scale": depth_scale}
    options = _options_record(config, read, out_fmt, intrinsics, shrink_frames)
    if output_depth_scale != 1000.0:  # (absent at the default: records of earlier batches)
        options["output_depth_scale"] = output_depth_scale
    if not keep_names:
        options["keep_names"] = False
    if camera_motion != "flow":  # (absent at the default: records of earlier batches)
        options["camera_motion"] = camera_motion
    say = log or (lambda line: None)
    with _batch_folder(out):
        return _run_locked(
            recs,
            config,
            read,
            options,
            say,
            out_fmt=out_fmt,
            depth_scale=output_depth_scale,
            intrinsics=intrinsics,
            scheduler=scheduler,
            workers=workers,
            chunk_frames=chunk_frames,
            overwrite=overwrite,
            progress=progress,
            shrink_frames=shrink_frames,
            limits={
                "max_memory": max_memory,
                "keep_names": keep_names,
                "units": (sensor, strict_units, scale_given, output_depth_scale),
                "camera_motion": camera_motion,
            },
        )


def _run_locked(
    recs: list[Recording],
    config: UPSRConfig,
    read: dict[str, Any],
    options: dict[str, Any],
    say: Callable[[str], None],
    *,
    out_fmt: str,
    depth_scale: float,
    intrinsics: str | None,
    scheduler: str | None,
    workers: int | None,
    chunk_frames: int,
    overwrite: bool,
    progress: bool,
    shrink_frames: bool,
    limits: dict[str, Any] | None = None,
) -> BatchResult:
    """:func:`run_batch` once it holds the lock of the output folder (``depth_scale``: the
    output's; ``limits``: ``max_memory``, ``keep_names``)."""
    from tqdm import tqdm

    executor: Any = None
    bar = tqdm(
        total=len(recs),
        desc="upsr batch",
        unit="rec",
        file=sys.stderr,
        disable=not progress,
        dynamic_ncols=True,
    )
    try:
        executor = (
            _DaskExecutor(scheduler)
            if scheduler
            else _LocalExecutor(workers or os.cpu_count() or 1)
        )
        run = _BatchRun(recs, config, say, bar.update, options)
        local = not scheduler
        run.limits = {
            **(limits or {}),
            "out_fmt": out_fmt,
            "workers": executor.workers if local else 0,  # Dask: memory of the cluster
        }
        pending = run.submit_all(
            executor, read, out_fmt, chunk_frames, intrinsics, overwrite, shrink_frames
        )
        run.collect(executor, pending, out_fmt, depth_scale)
    finally:
        bar.close()
        if executor is not None:
            executor.shutdown()
            for rec in recs:  # (the half-written chunks of the workers it killed: Ctrl-C)
                if rec.work is not None and rec.work.is_dir():
                    remove_stale_in(rec.work)
    for rec in recs:
        if rec.status == "failed":
            _drop_work(rec)  # chunks that were still running when it failed
    return BatchResult(recs)


def _recordings(
    inputs: Sequence[str | os.PathLike[str]], out: Path, suffix: str
) -> list[Recording]:
    """One :class:`Recording` per input, each with its own output name in ``out`` (an input
    given twice, e.g. by overlapping globs, once)."""
    recs: list[Recording] = []
    by_output: dict[Path, Path] = {}
    for inp in inputs:
        p = Path(os.path.abspath(inp))
        dest = out / (output_name(p) + suffix)
        if dest in by_output and by_output[dest].resolve() == p.resolve():
            continue
        if dest.name == WORK_DIR:
            raise InputError(
                f"{p}: its output {dest.name} would be the batch's own state: rename it"
            )
        if dest in by_output:
            raise InputError(
                f"{by_output[dest]} and {p} would both be written to {dest}: "
                f"give the recordings different names or run them separately"
            )
        by_output[dest] = p
        recs.append(Recording(p, dest))
    return recs


class _BatchRun:
    """The recordings of one :func:`run_batch` call on their way through an executor."""

    def __init__(
        self,
        recs: list[Recording],
        config: UPSRConfig,
        say: Callable[[str], None],
        tick: Callable[[int], Any],
        options: dict[str, Any] | None = None,
    ) -> None:
        self.recs, self.config, self.say, self.tick = recs, config, say, tick
        self.options = options if options is not None else {}
        self.limits: dict[str, Any] = {}

    def fail(self, rec: Recording, message: str, kind: str) -> None:
        rec.status, rec.error, rec.error_kind = "failed", message, kind
        _drop_work(rec)
        self.say(f"failed: {rec.input}: {message}")

    def submit_all(
        self,
        executor: Any,
        read: dict[str, Any],
        out_fmt: str,
        chunk_frames: int,
        intrinsics: str | None,
        overwrite: bool,
        shrink_frames: bool,
    ) -> dict[Any, tuple[Recording, int]]:
        """Skip finished outputs, plan the others and submit their chunks."""
        from upsr.io import video as io

        pending: dict[Any, tuple[Recording, int]] = {}
        for rec in self.recs:
            verdict = self._existing(rec, overwrite)
            if verdict == "skip":
                rec.status = "skipped"
                self.say(f"skipped (output exists): {rec.output}")
                self.tick(1)
                continue
            if verdict:
                self.fail(rec, verdict, "input")
                self.tick(1)
                continue
            try:
                io.check_output_path([rec.input], rec.output, True, fmt=out_fmt)
                rec.chunks = prepare_recording(
                    rec,
                    self.config,
                    read,
                    chunk_frames,
                    executor.workers,
                    intrinsics,
                    shrink_frames,
                    self.limits,
                )
            except InputError as e:
                self.fail(rec, str(e), "input")
                self.tick(1)
                continue
            for i, spec in enumerate(rec.chunks):
                pending[executor.submit(run_chunk, spec)] = (rec, i)
        return pending

    def _existing(self, rec: Recording, overwrite: bool) -> str:
        """What to do about ``rec``'s output: "" compute it, "skip", or why it is refused.

        An output with no options record (not made by a batch) is skipped, as is one made
        with the same options; one made with other options is refused without
        ``overwrite``; one whose record says "writing" (a batch died while publishing it,
        maybe before its sidecar) is recomputed.
        """
        if not os.path.lexists(rec.output) or overwrite:
            return ""
        record = _read_record(rec)
        if record is None:
            return "skip"
        if record.get("state") != "done":
            return ""
        made_from = record.get("input")
        if made_from is not None and Path(made_from).resolve() != Path(rec.input).resolve():
            return (
                f"output {rec.output.name} was made from another recording ({made_from}): "
                f"use --overwrite to replace it, or another --out"
            )
        if "source" in record and record["source"] != input_identity(rec.input):
            return (
                f"output {rec.output.name} was made before {rec.input.name} changed: use "
                f"--overwrite to recompute it"
            )
        # (whether N shrinks to a short recording is no option of its own: -n 9 given or not,
        # a recording of 9 frames or more gets N = 9, a shorter one is refused with -n 9)
        made, now = ({k: v for k, v in o.items() if k != "shrink_frames"}
                     for o in (record["options"], self.options))  # fmt: skip
        if made == now:
            return "skip"
        diff = _differences(made, now)
        shown = "; ".join(diff[:2]) + ("; ..." if len(diff) > 2 else "")
        if len(shown) > 90:
            shown = shown[:87] + "..."
        return (
            f"output {rec.output.name} was made with other options ({shown}): "
            f"use --overwrite to recompute it"
        )

    def collect(
        self,
        executor: Any,
        pending: dict[Any, tuple[Recording, int]],
        out_fmt: str,
        depth_scale: float,
    ) -> None:
        """Gather the finished chunks; assemble each recording once all its chunks are in.

        A Dask task whose worker died (``KilledWorker``: it was running, or only queued,
        on a worker that died) is submitted once more before its recording is failed: the
        scheduler cannot tell the task that killed the worker from those queued beside it.
        """
        retried: set[tuple[int, int]] = set()
        while pending:
            resubmitted = False
            for fut in executor.as_completed(list(pending)):
                rec, i = pending.pop(fut)
                if rec.status != "pending":
                    continue  # the recording failed already
                res = self._result(fut, rec, i)
                if res.get("kind") == "killed" and (id(rec), i) not in retried:
                    retried.add((id(rec), i))
                    pending[executor.submit(run_chunk, rec.chunks[i])] = (rec, i)
                    resubmitted = True
                    break
                self._chunk_done(rec, res, pending, out_fmt, depth_scale)
            if not resubmitted:
                break

    @staticmethod
    def _result(fut: Any, rec: Recording, i: int) -> dict[str, Any]:
        try:
            return dict(fut.result())
        except Exception as e:  # a Dask worker died, the cluster went away
            if type(e).__name__ == "KilledWorker":
                spec = rec.chunks[i]
                return {
                    "error": f"its worker process died (Dask KilledWorker) while computing "
                    f"output frames {spec['out_start']}-{spec['out_stop'] - 1}",
                    "kind": "killed",
                }
            return {"error": f"{type(e).__name__}: {e}", "kind": "internal"}

    def _chunk_done(
        self,
        rec: Recording,
        res: dict[str, Any],
        pending: dict[Any, tuple[Recording, int]],
        out_fmt: str,
        depth_scale: float,
    ) -> None:
        if res.get("kind") == "killed":
            res["kind"] = "internal"
        if "error" in res:
            self.fail(rec, res["error"], res["kind"])
            for other, (r2, _) in pending.items():
                if r2 is rec:
                    other.cancel()
            self.tick(1)
            return
        rec.done_chunks += 1
        rec.seconds += float(res["seconds"])
        if rec.done_chunks < len(rec.chunks):
            return
        try:
            _write_record(rec, self.options, "writing")
            keep = self.limits.get("keep_names", True)
            _assemble(rec, rec.config or self.config, out_fmt, depth_scale, keep)
            _write_record(rec, self.options, "done")
        except InputError as e:
            self.fail(rec, str(e), "input")
        except OSError as e:
            self.fail(rec, f"cannot write {rec.output}: {e}", "input")
        else:
            rec.status = "done"
            self.say(f"done: {rec.input} -> {rec.output} ({rec.n_frames} frames)")
        self.tick(1)
