"""Two independent pieces of work at once, on the two cores of a small CPU (beyond the paper).

OpenCV runs a small image (the 64×56 → 256×224 frames of a time-of-flight camera) on one
thread, so the per-window work of UP-SR that is a chain of OpenCV calls (the two directions of
the cumulative motion, the two consecutive flows of a new frame, the bilateral filters) leaves
the second core idle. :func:`both` runs two such independent tasks side by side: one on a
helper thread, one on the caller's. They must release the GIL (OpenCV calls, ``nogil`` numba
kernels that are not ``parallel``) and write to disjoint outputs; the results are then exactly
those of running them one after the other.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

__all__ = ["both"]

T = TypeVar("T")
U = TypeVar("U")

_THREAD_PREFIX = "upsr-helper"
_LOCK = threading.Lock()
_POOL: ThreadPoolExecutor | None = None
_POOL_PID: int | None = None


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
