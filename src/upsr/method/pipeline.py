"""Two cores, one frame each: an engine's state update on the caller's thread, the frame's
finishing on a helper thread (beyond the paper).

The recursive engine (:class:`upsr.method.recursive.RecursiveUPSR`) turns a frame into its
output in two stages: the update of its state (prefilter, one flow, fusion), which the next
frame needs, and the finishing (deblurring and the rules after it), which nothing later
needs. :class:`TwoStagePipeline` runs the finishing of frame t on a helper thread
(:func:`upsr.method._parallel.window_pool`) while the caller updates the state with frame
t + 1, each stage with numba's kernels on one core: the output is the same, no frame waits
for a later one, and a frame takes the slower stage's time instead of both's.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future
from typing import Any

import numpy as np
import numpy.typing as npt

from upsr.method._parallel import kernel_threads, numba_threads, window_pool

__all__ = ["PIPELINE_BALANCE", "PIPELINE_PROBE", "TwoStagePipeline"]

#: :meth:`TwoStagePipeline.push_async` measures its two stages (each on one core) on this many
#: frames and keeps the pipeline where the slower takes under PIPELINE_BALANCE times the
#: faster: the pipeline's frame takes the slower one, one thread's frame both at about 1/1.45
#: of their one-core times (numba's kernels on two cores), so the pipeline wins below 2.2.
PIPELINE_PROBE = 3
PIPELINE_BALANCE = 2.0


class TwoStagePipeline:
    """Mixin of an engine with ``_update(frame) -> args`` (the state, on the caller's thread),
    ``_finish(*args) -> output`` (reads ``args`` only), ``push``, ``flush``, ``workers`` (0:
    no helper) and a frame counter ``_count``; ``reset`` calls :meth:`_reset_pipeline`."""

    workers: int
    _count: int
    _pending: Future | None = None  # (before the first reset)

    def _update(self, frame: npt.ArrayLike) -> tuple[Any, ...]:  # pragma: no cover
        raise NotImplementedError

    def _finish(self, *args: Any) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def push(self, frame: npt.ArrayLike) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def flush(self) -> list[np.ndarray]:  # pragma: no cover
        raise NotImplementedError

    def _reset_pipeline(self) -> None:
        """No frame in flight (one still finishing is waited for: it reads the engine's
        state); the stages to be measured anew."""
        self._settle()
        # seconds of the update and of the finishing, frames measured; pipelined or not
        self._stage_seconds = [0.0, 0.0, 0]
        self._pipelined: bool | None = None

    def push_async(
        self, frame: npt.ArrayLike, then: Callable[[np.ndarray], None] | None = None
    ) -> Future:
        """:meth:`push` with the frame's finishing on a helper thread (``workers`` ≥ 1).

        The state is updated here, on one core; the deblurring and the rules after it run on
        the helper, on the other, while the caller takes the next frame (whose update then
        overlaps this one's finishing): the future's result is :meth:`push`'s output, and
        ``then(output)`` runs on the helper first (in frame order, e.g. to write it). One
        frame at a time is finished: a call waits for the previous frame's finishing after
        its own update. Without workers everything runs here (a finished future). A frame's
        error (of its finishing or of ``then``) is raised by its own future only (and by
        :meth:`wait` for the last frame), never by a later call: that frame's output is not
        lost.
        """
        pool = window_pool(self.workers) if self._pipelined is not False else None
        start = time.perf_counter()
        with numba_threads(kernel_threads(1)) if pool is not None else contextlib.nullcontext():
            args = self._update(frame)
        update_s = time.perf_counter() - start
        # (from the third frame: the first has no flow, the second compiles or loads kernels)
        measured = pool is not None and self._count > 2

        def finish() -> np.ndarray:
            begin = time.perf_counter()
            out = self._finish(*args)
            if measured:
                self._probe(update_s, time.perf_counter() - begin)
            if then is not None:
                then(out)
            return out

        if pool is None:
            # a frame still finishing on the helper (the probe turned the pipeline off during
            # it) goes first: outputs and ``then`` in frame order
            self._settle()
            done: Future = Future()
            try:
                done.set_result(finish())
            except Exception as e:  # (in this frame's future, as on the helper)
                done.set_exception(e)
            return done
        self._settle()
        self._pending = pool.submit(finish)
        return self._pending

    def _settle(self) -> None:
        """Wait for the frame in flight, if any, without raising its error (its future holds
        it)."""
        pending, self._pending = self._pending, None
        if pending is not None:
            concurrent.futures.wait([pending])

    def _probe(self, update_s: float, finish_s: float) -> None:
        """Keep the pipeline of :meth:`push_async` only where its two stages take about the
        same time, as measured on :data:`PIPELINE_PROBE` frames from the third."""
        seconds = self._stage_seconds
        seconds[0] += update_s
        seconds[1] += finish_s
        seconds[2] += 1
        if self._pipelined is None and seconds[2] >= PIPELINE_PROBE:
            self._pipelined = max(seconds[:2]) < PIPELINE_BALANCE * min(seconds[:2])

    def wait(self) -> None:
        """Wait for the frame :meth:`push_async` is finishing, if any (its error is raised
        here)."""
        pending, self._pending = self._pending, None
        if pending is not None:
            pending.result()

    def process(self, frames: Iterable[npt.ArrayLike]) -> Iterator[np.ndarray]:
        """Super-resolve a stream of frames; yields one output per frame, in order. With
        ``workers``, through :meth:`push_async`: frame t is finished while frame t + 1
        updates the state, so its output comes once frame t + 1 has been read (a
        recording); without, through :meth:`push`, which never waits for a later frame. A
        video that fails (or is abandoned) resets the engine: the next starts afresh."""
        try:
            if window_pool(self.workers) is None:
                for frame in frames:
                    yield self.push(frame)
            else:
                last = None
                for frame in frames:
                    current = self.push_async(frame)
                    if last is not None:
                        yield last.result()
                    last = current
                if last is not None:
                    yield last.result()
        except BaseException:
            self._settle()
            self.reset()
            raise
        self.flush()
