"""Where the chunks of ``upsr batch`` run: a pool of spawned worker processes that isolates
crashes (one dying worker fails only its recording), or an existing Dask scheduler.

Both take the task to run with each chunk (:func:`upsr.apps.batch.run_chunk`).
"""

from __future__ import annotations

import collections
import contextlib
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from upsr.errors import InputError

__all__ = ["check_scheduler_address"]


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

    def submit(self, task: Callable[[dict[str, Any]], dict[str, Any]], spec: dict[str, Any]) -> Any:
        from concurrent.futures import Future

        fut: Future[dict[str, Any]] = Future()
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

    def submit(self, task: Callable[[dict[str, Any]], dict[str, Any]], spec: dict[str, Any]) -> Any:
        return self.client.submit(task, spec, pure=False)

    def as_completed(self, futures: Sequence[Any]) -> Iterator[Any]:
        from dask.distributed import as_completed

        return iter(as_completed(futures))

    def shutdown(self) -> None:
        with contextlib.suppress(Exception):
            self.client.close()
