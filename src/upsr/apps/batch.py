"""Super-resolve many recordings: on this machine's cores or on a Dask distributed cluster.

Each recording is split into chunks of consecutive output frames; a chunk reads the input
frames its windows need (UP-SR's window for output t is the frames [s, s + N) with
s = clip(t − (N−1)//2, 0, T − N), :func:`upsr.method.windowed.window_start`), so
neighbouring chunks overlap by N − 1 input frames. Every choice the engine fixes once per video
from its first N frames (the flow images' 8-bit depth mapping, the noise estimate, the fusion's
estimator and trust noise: :func:`upsr.method.windowed.pinned_config`) is made once per
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

import collections
import contextlib
import dataclasses
import hashlib
import json
import math
import os
import shutil
import sys
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

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

WORK_DIR = ".upsr-batch"
_OUT_SUFFIX = {"npy": ".npy", "npz": ".npz", "tiff": ".tif", "png": "", "exr": "", "rosbag": ""}


# ---------------------------------------------------------------------------------------------
# planning
# ---------------------------------------------------------------------------------------------
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

    # the cluster runs chunks side by side: one thread per chunk, no window threads
    return ChunkEngine(config=cfg, workers=0)


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


def _fingerprint(inp: Path, spec: dict[str, Any]) -> str:
    st = []
    p = Path(inp)
    files = [p] if p.is_file() else sorted(q for q in p.iterdir() if q.is_file())
    for q in files:
        s = q.stat()
        st.append((q.name, s.st_size, s.st_mtime_ns))
    blob = json.dumps([str(p.resolve()), st, spec], sort_keys=True, default=str)
    return hashlib.sha1(blob.encode()).hexdigest()[:12]


# ---------------------------------------------------------------------------------------------
# executors
# ---------------------------------------------------------------------------------------------
class _LocalExecutor:
    """Chunks in this process (1 worker) or in a pool of spawned worker processes.

    The pool is this module's own (not :class:`concurrent.futures.ProcessPoolExecutor`, which
    breaks as a whole when one worker dies): the driver hands one chunk at a time to each
    worker, so it knows which chunk a worker that dies (SIGKILL, segfault, ``os._exit``) was
    computing; that chunk's recording is reported as failed, a new worker takes the worker's
    place and the other recordings go on. Workers die with the driver (see
    :func:`_die_with_parent`).
    """

    def __init__(self, workers: int) -> None:
        import multiprocessing

        self.workers = workers
        self._pool = workers > 1
        self._ctx = multiprocessing.get_context("spawn")
        self._queue: collections.deque[tuple[Any, Any, dict[str, Any]]] = collections.deque()
        self._idle: list[_Worker] = []
        self._busy: dict[_Worker, tuple[Any, dict[str, Any]]] = {}

    def submit(self, spec: dict[str, Any]) -> Any:
        from concurrent.futures import Future

        fut: Future[dict[str, Any]] = Future()
        task = run_chunk  # looked up now: a test may replace it
        if not self._pool:
            fut.set_running_or_notify_cancel()
            fut.set_result(task(spec))
        else:
            self._queue.append((fut, task, spec))
        return fut

    def as_completed(self, futures: Sequence[Any]) -> Iterator[Any]:
        from multiprocessing.connection import wait

        want = set(futures)
        while want:
            done = [f for f in want if f.done()]
            want.difference_update(done)
            yield from (f for f in done if not f.cancelled())
            if not want:
                return
            self._dispatch()
            if not self._busy:
                if not any(not f.done() for f in want):
                    continue
                return  # nothing left to run (cancelled)
            handles: list[Any] = []
            for w in self._busy:
                handles += [w.conn, w.proc.sentinel]
            wait(handles)
            for w in list(self._busy):
                self._poll(w)

    def _dispatch(self) -> None:
        while self._queue and (self._idle or len(self._busy) < self.workers):
            fut, task, spec = self._queue.popleft()
            if not fut.set_running_or_notify_cancel():
                continue  # cancelled: its recording failed already
            for _attempt in range(2):  # an idle worker may have died meanwhile
                w = self._idle.pop() if self._idle else _Worker(self._ctx)
                try:
                    w.conn.send((task, spec))
                except (OSError, EOFError):
                    w.stop(kill=True)
                    continue
                except Exception as e:  # the task cannot be pickled
                    self._idle.append(w)
                    fut.set_result({"error": f"{type(e).__name__}: {e}", "kind": "internal"})
                    break
                self._busy[w] = (fut, spec)
                break
            else:
                fut.set_result({"error": "cannot start a worker process", "kind": "internal"})

    def _poll(self, w: _Worker) -> None:
        fut, spec = self._busy[w]
        try:
            has_result = w.conn.poll()
            res = w.conn.recv() if has_result else None
        except (OSError, EOFError):
            res = None
        if res is not None:
            del self._busy[w]
            self._idle.append(w)
            fut.set_result(res)
            return
        if w.proc.is_alive():
            return
        del self._busy[w]
        how = _exit_description(w.proc.exitcode)
        w.stop(kill=True)
        fut.set_result(
            {
                "error": f"its worker process died ({how}) while computing output frames "
                f"{spec['out_start']}-{spec['out_stop'] - 1}",
                "kind": "internal",
            }
        )

    def shutdown(self) -> None:
        for w in self._idle:
            with contextlib.suppress(OSError, ValueError):
                w.conn.send(None)
        for w in self._idle:
            w.stop(kill=False)
        for w in self._busy:  # interrupted: nothing more is wanted from them
            w.stop(kill=True)
        self._idle.clear()
        self._busy.clear()
        self._queue.clear()


def _exit_description(code: int | None) -> str:
    import signal

    if code is not None and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


class _Worker:
    """One spawned worker process and the pipe it gets its tasks through."""

    def __init__(self, ctx: Any) -> None:
        self.conn, child = ctx.Pipe(duplex=True)
        self.proc = ctx.Process(
            target=_worker_main, args=(child, os.getpid()), daemon=True, name="upsr-batch-worker"
        )
        self.proc.start()
        child.close()

    def stop(self, kill: bool) -> None:
        if not kill:
            self.proc.join(5)
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join(5)
        with contextlib.suppress(OSError):
            self.conn.close()
        with contextlib.suppress(ValueError):
            self.proc.close()


def _worker_main(conn: Any, parent_pid: int) -> None:
    """A worker process: run the tasks received on ``conn`` one by one, until ``None``."""
    import signal

    _die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the driver decides (and kills us)
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return
        except Exception as e:  # the task could not be unpickled
            conn.send({"error": f"{type(e).__name__}: {e}", "kind": "internal"})
            continue
        if job is None:
            return
        task, spec = job
        try:
            res = task(spec)
        except BaseException as e:  # run_chunk never raises; a replaced task might
            res = {"error": f"{type(e).__name__}: {e}", "kind": "internal"}
        conn.send(res)


def _die_with_parent(parent_pid: int) -> None:
    """Make this worker process end when its parent (the driver) does, even on SIGKILL.

    Linux: the parent-death signal (``prctl(PR_SET_PDEATHSIG, SIGKILL)``); everywhere: a
    watchdog thread that exits once the parent PID changes (the worker was re-parented).
    """
    import signal
    import threading

    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os._exit(1)

    def watchdog() -> None:
        while True:
            time.sleep(0.5)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watchdog, name="upsr-parent-watchdog", daemon=True).start()


def check_scheduler_address(address: str) -> str:
    """Refuse (:class:`InputError`) a ``--scheduler`` that is not ``tcp://HOST:PORT``."""
    from urllib.parse import urlsplit

    shown = address if len(address) <= 80 else address[:77] + "..."
    try:
        u = urlsplit(address)
        ok = (
            u.scheme in ("tcp", "tls")
            and bool(u.hostname)
            and u.port is not None
            and u.path in ("", "/")
            and not (u.query or u.fragment or u.username)
        )
    except ValueError:  # a port that is no number or out of range
        ok = False
    if not ok:
        raise InputError(f"--scheduler {shown!r} is not a Dask scheduler address tcp://HOST:PORT")
    return address


class _DaskExecutor:
    """Chunks as tasks on an existing Dask distributed scheduler."""

    def __init__(self, address: str) -> None:
        check_scheduler_address(address)
        try:
            from dask.distributed import Client
        except ImportError:
            raise InputError(
                "--scheduler needs the optional package 'dask[distributed]': "
                "pip install 'upsr[dask]'"
            ) from None
        try:
            self.client = Client(address, timeout="10s")
        except (OSError, TimeoutError, ValueError) as e:
            raise InputError(f"cannot connect to the Dask scheduler {address}: {e}") from None
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))

    def submit(self, spec: dict[str, Any]) -> Any:
        return self.client.submit(run_chunk, spec, pure=False)

    def as_completed(self, futures: Sequence[Any]) -> Iterator[Any]:
        from dask.distributed import as_completed

        return iter(as_completed(futures))

    def shutdown(self) -> None:
        with contextlib.suppress(Exception):
            self.client.close()


# ---------------------------------------------------------------------------------------------
# the driver
# ---------------------------------------------------------------------------------------------
def _prepare(
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
    recording (``limits``: ``out_fmt``, ``max_memory``, ``workers`` of the memory check)."""
    from upsr.apps._preflight import check_run_resources
    from upsr.io import identity
    from upsr.io import video as io

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
    lim = limits or {}
    check_run_resources(
        info.shape,
        cfg,
        workers=lim.get("workers", workers),
        out_fmt=lim.get("out_fmt", "npy"),
        output=rec.output,
        max_memory=lim.get("max_memory"),
    )
    rec.camera = _camera(rec.input, info, read, intrinsics)
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
    from upsr.method.windowed import pinned_config

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


def _camera(inp: Path, info: Any, read: dict[str, Any], intrinsics: str | None) -> Any:
    """The camera of a recording: :func:`upsr.apps._camera.input_camera`."""
    from upsr.apps._camera import input_camera

    return input_camera(inp, info, intrinsics, fmt=read["fmt"], topic=read["topic"])


def _assemble(
    rec: Recording,
    cfg: UPSRConfig,
    out_fmt: str | None,
    depth_scale: float,
    keep_names: bool = True,
) -> None:
    """Write the output of ``rec`` from its chunks, with its intrinsics sidecar (published
    with the video: a failing sidecar leaves no complete-looking output)."""
    from upsr.geometry.intrinsics import intrinsics_text
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
        if out_cam is not None:
            text = intrinsics_text(
                out_cam,
                source=rec.camera,
                scale=cfg.scale,
                timestamps_ns=rec.timestamps,
                frame_names=rec.frame_names,
            )
            writer.add_sidecar(io.intrinsics_path(rec.output), text)
        for spec in rec.chunks:
            part = np.load(spec["part"], mmap_mode="r", allow_pickle=False)
            for frame in part:
                writer.write(np.asarray(frame))
            del part
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

    Returns
    -------
    BatchResult
    """
    # absolute paths: the tasks run in workers with other working directories
    out = Path(os.path.abspath(out_dir))
    if not inputs:
        raise InputError("no input recordings given")
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
            limits={"max_memory": max_memory, "keep_names": keep_names},
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
    for rec in recs:
        if rec.status == "failed":
            _drop_work(rec)  # chunks that were still running when it failed
    return BatchResult(recs)


#: the lock file of an output folder (beside its work folder, never inside it)
LOCK_FILE = ".upsr-batch.lock"


@contextlib.contextmanager
def _batch_folder(out: Path) -> Iterator[None]:
    """Create the output folder if needed and hold its lock (``OUT/.upsr-batch.lock``).

    The lock is an exclusive :func:`fcntl.flock` taken without waiting: a second batch on the
    same folder (which would otherwise delete the first one's chunks as stale) is refused
    with an :class:`InputError`. The lock file is removed (while still locked) at the end; a
    process that opened it meanwhile sees that the file it locked is no longer the one at
    the path and tries again. A folder this call created is removed again if it stays empty.
    """
    created = not os.path.lexists(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"--out {out}: cannot create the folder ({e.strerror or e})") from None
    try:
        with _folder_lock(out):
            yield
    finally:
        if created:
            with contextlib.suppress(OSError):
                out.rmdir()  # only if empty (everything failed)


@contextlib.contextmanager
def _folder_lock(out: Path) -> Iterator[None]:
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    path = out / LOCK_FILE
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
        except OSError as e:
            raise InputError(
                f"--out {out}: cannot create {path.name} ({e.strerror or e})"
            ) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = ""
            with contextlib.suppress(OSError, ValueError):
                holder = f" (PID {int(os.pread(fd, 20, 0).decode().strip())})"
            os.close(fd)
            raise InputError(
                f"--out {out} is in use by another upsr batch{holder}: wait for it to finish "
                f"or choose another output folder"
            ) from None
        try:
            st, now = os.fstat(fd), os.stat(path)
            current = (st.st_dev, st.st_ino) == (now.st_dev, now.st_ino)
        except OSError:
            current = False
        if current:
            break
        os.close(fd)  # its previous holder removed it after we opened it: again
    try:
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.close(fd)


def _resolved(p: Path) -> Path:
    try:
        return p.resolve()
    except (OSError, RuntimeError):
        raise InputError(f"{p}: cannot resolve the path (symbolic link loop?)") from None


def _check_out_vs_inputs(out: Path, recs: list[Recording]) -> None:
    """Refuse (before any work) an output folder inside an input folder, or an output that
    is one of the inputs (any recording's, not only its own)."""
    out_res = _resolved(out)
    ins = [(r.input, _resolved(r.input)) for r in recs]
    for inp, in_res in ins:
        if (in_res == out_res or in_res in out_res.parents) and in_res.is_dir():
            raise InputError(
                f"--out {out} is inside the input folder {inp}: choose another output folder"
            )
    for rec in recs:
        dest = _resolved(rec.output)
        for inp, in_res in ins:
            same = dest == in_res
            if not same and os.path.exists(dest) and os.path.exists(in_res):
                with contextlib.suppress(OSError):
                    same = os.path.samefile(dest, in_res)
            if same:
                raise InputError(
                    f"the output {rec.output} of {rec.input} is the input {inp}: "
                    f"choose another output folder"
                )


def _options_record(
    config: UPSRConfig,
    read: dict[str, Any],
    out_fmt: str,
    intrinsics: str | None,
    shrink_frames: bool,
) -> dict[str, Any]:
    """What an output of this batch depends on besides its input (compared on a rerun);
    not the chunking, which does not change the output."""
    rec = {
        "config": dataclasses.asdict(config),
        "read": read,
        "format": out_fmt,
        "intrinsics": intrinsics,
        "shrink_frames": shrink_frames,
    }
    return dict(json.loads(json.dumps(rec, default=str)))


def _record_path(rec: Recording) -> Path:
    """Where the options an output was made with are recorded:
    ``OUT/.upsr-batch/outputs/<output name>.json`` (no chunk folder is named without a dot
    and a fingerprint)."""
    return rec.output.parent / WORK_DIR / "outputs" / f"{rec.output.name}.json"


def _read_record(rec: Recording) -> dict[str, Any] | None:
    """The options record of an output (None: none, or unreadable)."""
    try:
        data = json.loads(_record_path(rec).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and "options" in data else None


def _write_record(rec: Recording, options: dict[str, Any], state: str) -> None:
    """Record (atomically) the options of ``rec``'s output: state "writing" before the
    output is published, "done" once it and its sidecar are complete."""
    from upsr._atomic import write_text_atomic

    path = _record_path(rec)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps({"state": state, "input": str(rec.input), "options": options})
    write_text_atomic(path, text)


def _drop_record(rec: Recording) -> None:
    with contextlib.suppress(OSError):
        _record_path(rec).unlink()


def _differences(old: dict[str, Any], new: dict[str, Any], prefix: str = "") -> list[str]:
    """``key: old -> new`` for the leaves of two option records that differ."""
    out = []
    for k in sorted(set(old) | set(new)):
        a, b = old.get(k), new.get(k)
        if isinstance(a, dict) and isinstance(b, dict):
            out += _differences(a, b, f"{prefix}{k}.")
        elif a != b:
            out.append(f"{prefix}{k}: {a} -> {b}")
    return out


def _check_batch_options(
    out: Path, output_format: str | None, workers: int | None, chunk_frames: int
) -> str:
    """Check the options of :func:`run_batch` (before any work); return the output format."""
    most = max(64, 2 * (os.cpu_count() or 1))  # each a process with its own memory
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


def _recordings(
    inputs: Sequence[str | os.PathLike[str]], out: Path, suffix: str
) -> list[Recording]:
    """One :class:`Recording` per input, each with its own output name in ``out``."""
    recs: list[Recording] = []
    by_output: dict[Path, Path] = {}
    for inp in inputs:
        p = Path(os.path.abspath(inp))
        dest = out / (output_name(p) + suffix)
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
                rec.chunks = _prepare(
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
                pending[executor.submit(spec)] = (rec, i)
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
        if record["options"] == self.options:
            return "skip"
        diff = _differences(record["options"], self.options)
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
                    pending[executor.submit(rec.chunks[i])] = (rec, i)
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
