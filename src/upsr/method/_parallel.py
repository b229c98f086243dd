"""Independent pieces of work at once, on the cores of a small CPU (beyond the paper).

OpenCV runs a small image (the 64×56 → 256×224 frames of a time-of-flight camera) on one
thread, so the per-window work of UP-SR that is a chain of OpenCV calls (the two directions of
the cumulative motion, the two consecutive flows of a new frame, the bilateral filters) leaves
the second core idle. :func:`both` runs two such independent tasks side by side: one on a
helper thread, one on the caller's. They must release the GIL (OpenCV calls, ``nogil`` numba
kernels that are not ``parallel``) and write to disjoint outputs; the results are then exactly
those of running them one after the other.

:func:`window_pool` gives the threads that finish whole windows of a video side by side
(:class:`upsr.UPSR` ``workers``): the windows of a video are independent once their frames'
flows are known, so on two cores two windows at a time use both fully, where the threads of
one window's kernels leave much of the second core idle or spinning. In those threads
numba's kernels share out the cores the window threads leave (:func:`kernel_threads`: none
on two cores, so each kernel runs on its window's thread) and :func:`both` runs serially.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

import numba as nb

from upsr.errors import InputError

__all__ = [
    "WINDOWED_WORKERS",
    "both",
    "kernel_threads",
    "numba_threads",
    "resolve_workers",
    "window_pool",
]

T = TypeVar("T")
U = TypeVar("U")

_THREAD_PREFIX = "upsr-helper"
_LOCK = threading.Lock()
_POOL: ThreadPoolExecutor | None = None
_POOL_PID: int | None = None
_WINDOW_POOLS: dict[int, ThreadPoolExecutor] = {}
_WINDOW_POOLS_PID: int | None = None


def _helper() -> ThreadPoolExecutor:
    """The one helper thread of this process (made again in a forked child)."""
    global _POOL, _POOL_PID
    with _LOCK:
        if _POOL is None or _POOL_PID != os.getpid():
            _POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix=_THREAD_PREFIX)
            _POOL_PID = os.getpid()
        return _POOL


def _serial() -> bool:
    return (os.cpu_count() or 1) < 2 or threading.current_thread().name.startswith(_THREAD_PREFIX)


def both(first: Callable[[], T], second: Callable[[], U], *, enabled: bool = True) -> tuple[T, U]:
    """``(first(), second())``, with ``second`` on a helper thread while ``first`` runs here.

    Serial when ``enabled`` is false (e.g. tasks that call a flow backend that is not known to
    be thread-safe), on a one-core machine, and when called from the helper thread itself (no
    nesting). An exception of either is raised after both have finished.
    """
    if not enabled or _serial():
        return first(), second()
    future = _helper().submit(second)
    try:
        a = first()
    finally:
        b = future.result()
    return a, b


@nb.njit(cache=True, parallel=True)
def _touch(n):  # pragma: no cover - numba
    total = 0
    for i in nb.prange(n):
        total += i
    return total


#: Window threads of the windowed engine by default (on two cores or more).
WINDOWED_WORKERS = 2


def resolve_workers(workers: int | None, default: int) -> int:
    """An engine's ``workers`` checked (an integer ≥ 0); None: ``default`` on a machine with
    two cores or more, else 0.

    Raises
    ------
    InputError
        Not an integer ≥ 0.
    """
    if workers is None:
        return default if (os.cpu_count() or 1) >= 2 else 0
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise InputError(f"workers must be an integer >= 0, got {workers!r}")
    return workers


def kernel_threads(workers: int) -> int:
    """Threads of the numba kernels run by one of ``workers`` window threads: the cores left
    once each window thread and the caller have one (1 on a 2-core machine)."""
    cores = os.cpu_count() or 1
    return max(1, min(nb.config.NUMBA_NUM_THREADS, cores // (workers + 1)))


def _set_kernel_threads(count: int) -> None:
    nb.set_num_threads(count)  # per thread: the parallel kernels this thread launches


def _threads_may_share_numba() -> bool:
    """Whether several threads may run numba's parallel kernels at once: true for the "omp"
    and "tbb" threading layers, false for "workqueue" (which aborts the process)."""
    try:
        layer = nb.threading_layer()
    except ValueError:  # not started yet (a forked child inherits its parent's)
        _touch(2)
        layer = nb.threading_layer()
    return layer in ("omp", "tbb")


def window_pool(workers: int) -> ThreadPoolExecutor | None:
    """The process's pool of ``workers`` threads for whole windows, made on first use (again
    in a forked child); ``None`` when ``workers`` < 1 or numba's threading layer cannot be
    used from several threads at once."""
    global _WINDOW_POOLS_PID
    if workers < 1:
        return None
    with _LOCK:
        if _WINDOW_POOLS_PID != os.getpid():
            _WINDOW_POOLS.clear()
            _WINDOW_POOLS_PID = os.getpid()
        pool = _WINDOW_POOLS.get(workers)
        if pool is None:
            if not _threads_may_share_numba():
                return None
            pool = _WINDOW_POOLS[workers] = ThreadPoolExecutor(
                max_workers=workers,
                thread_name_prefix=_THREAD_PREFIX,
                initializer=_set_kernel_threads,
                initargs=(kernel_threads(workers),),
            )
        return pool


@contextlib.contextmanager
def numba_threads(count: int) -> Iterator[None]:
    """numba's parallel kernels launched from this thread use ``count`` threads, until the
    end (as those of a :func:`window_pool` thread)."""
    before = nb.get_num_threads()
    nb.set_num_threads(count)
    try:
        yield
    finally:
        nb.set_num_threads(before)
