"""upsr.method.pipeline: the update on the caller's thread, the finishing on a helper thread,
kept only where the two stages take about the same time."""

import threading
import time

import numpy as np
import pytest

from upsr.method._parallel import window_pool
from upsr.method.pipeline import PIPELINE_PROBE, TwoStagePipeline


class _Engine(TwoStagePipeline):
    """A state that sums the frames; update and finishing sleep the given seconds."""

    def __init__(self, update_s, finish_s, workers=1):
        self.update_s, self.finish_s, self.workers = update_s, finish_s, workers
        self.reset()

    def reset(self):
        self._count = 0
        self._total = 0.0
        self._reset_pipeline()

    def _update(self, frame):
        time.sleep(self.update_s)
        self._total += float(frame)
        self._count += 1
        return (self._total,)

    def _finish(self, total):
        time.sleep(self.finish_s)
        return np.array([total, threading.current_thread().name], dtype=object)

    def push(self, frame):
        return self._finish(*self._update(frame))

    def flush(self):
        self.wait()
        self.reset()
        return []


@pytest.fixture(autouse=True)
def _needs_a_pool():
    if window_pool(1) is None:
        pytest.skip("numba's threading layer cannot be shared by threads")


def test_outputs_in_order_and_finished_on_the_helper_while_balanced():
    engine = _Engine(0.004, 0.004)
    outs = list(engine.process(range(10)))
    assert [float(o[0]) for o in outs] == [sum(range(k + 1)) for k in range(10)]
    assert {o[1] for o in outs} != {threading.current_thread().name}
    assert engine._pipelined is None  # (flush resets: measured anew for the next video)


@pytest.mark.parametrize(
    ("update_s", "finish_s", "kept"), [(0.01, 0.01, True), (0.001, 0.05, False)]
)
def test_the_pipeline_is_kept_only_for_stages_of_about_the_same_time(update_s, finish_s, kept):
    engine = _Engine(update_s, finish_s)
    futures = [engine.push_async(k) for k in range(3 + PIPELINE_PROBE)]
    engine.wait()
    assert engine._pipelined is kept
    later = engine.push_async(100)
    name = later.result()[1]
    assert (name != threading.current_thread().name) is kept
    assert float(later.result()[0]) == sum(range(3 + PIPELINE_PROBE)) + 100
    assert all(f.done() for f in futures)


def test_without_workers_everything_runs_here():
    engine = _Engine(0.0, 0.0, workers=0)
    future = engine.push_async(1.0)
    assert future.done() and future.result()[1] == threading.current_thread().name
    engine.flush()
    assert [float(o[0]) for o in engine.process([1, 2])] == [1.0, 3.0]


def test_frames_stay_in_order_when_the_pipeline_is_turned_off_with_a_frame_in_flight():
    """The probe turns the pipeline off inside a frame's finishing on the helper; the next
    frame, finished here, must wait for it: ``then`` (which writes the output) runs in frame
    order (before the fix, ``upsr live`` wrote two frames swapped in a loaded CI run)."""

    class SlowHelper(_Engine):  # the helper's finishing slower than the caller's
        def _finish(self, total):
            on_helper = threading.current_thread() is not threading.main_thread()
            time.sleep(0.05 if on_helper else 0.001)
            return np.array([total, threading.current_thread().name], dtype=object)

    engine = SlowHelper(0.001, 0.0)
    seen = []
    futures = [engine.push_async(k, then=lambda out: seen.append(float(out[0]))) for k in range(9)]
    engine.wait()
    assert engine._pipelined is False
    assert seen == [float(sum(range(k + 1))) for k in range(9)]
    assert [float(f.result()[0]) for f in futures] == seen
