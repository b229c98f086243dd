"""upsr.method._parallel: two tasks side by side, same results as in sequence; numba's
threads per thread."""

import multiprocessing
import os
import threading

import numpy as np
import pytest

from upsr.method._parallel import both, numba_threads


def test_results_in_order_and_on_two_threads():
    names = []

    def task(value):
        names.append(threading.current_thread().name)
        return value

    assert both(lambda: task(1), lambda: task(2)) == (1, 2)
    assert len(set(names)) == 2  # the second ran on the helper thread


def test_an_exception_is_raised_after_both_finished():
    done = []

    def slow():
        done.append(True)
        return 0

    def fail():
        raise ValueError("boom")

    with pytest.raises(ValueError, match="boom"):
        both(fail, slow)
    assert done == [True]
    with pytest.raises(ValueError, match="boom"):
        both(slow, fail)


def test_nested_calls_run_serially_instead_of_deadlocking():
    inner = both(lambda: 0, lambda: both(lambda: 1, lambda: 2))
    assert inner == (0, (1, 2))


def _child(queue):
    from upsr.method._parallel import window_pool

    pool = window_pool(2)
    window = pool.submit(lambda: 5).result(timeout=30) if pool is not None else 5
    queue.put((*both(lambda: 3, lambda: 4), window))


@pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="needs fork")
def test_a_forked_child_gets_its_own_helper():
    from upsr.method._parallel import window_pool

    both(lambda: None, lambda: None)  # the parent's helper thread exists
    pool = window_pool(2)  # and its window threads
    if pool is not None:
        pool.submit(lambda: None).result()
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    proc = ctx.Process(target=_child, args=(queue,))
    proc.start()
    proc.join(timeout=60)
    if proc.is_alive():  # a deadlocked helper: fail, do not hang the suite
        proc.kill()
    assert proc.exitcode == 0
    assert queue.get(timeout=5) == (3, 4, 5)


def test_cumulative_motion_is_the_same_with_one_or_two_threads(monkeypatch):
    import upsr.method._parallel
    from upsr.research.synth import dynamic_scene

    scene = dynamic_scene(n_frames=11, lowres_shape=(20, 24), scale=2, noise_sigma_mm=10, seed=1)
    two = upsr.super_resolve(scene.lowres, 2, 5)
    monkeypatch.setattr(upsr.method._parallel, "_serial", lambda: True)
    one = upsr.super_resolve(scene.lowres, 2, 5)
    np.testing.assert_array_equal(one, two)


def test_a_registered_backend_is_never_called_from_two_threads(monkeypatch):
    """Registered backends may keep state between calls: the engine calls them in sequence."""
    import time

    import upsr
    from upsr.method import motion
    from upsr.research.synth import dynamic_scene

    active, most = [0], [0]
    dis = motion.make_flow_backend("dis", "medium")

    def factory(preset="medium"):
        def flow(a, b):
            active[0] += 1
            most[0] = max(most[0], active[0])
            time.sleep(0.002)  # long enough for a second thread to overlap
            try:
                return dis(a, b)
            finally:
                active[0] -= 1

        return flow

    monkeypatch.setitem(motion._BACKENDS, "stateful", factory)
    assert motion.flow_backend_is_thread_safe("dis")
    assert not motion.flow_backend_is_thread_safe("stateful")
    scene = dynamic_scene(n_frames=7, lowres_shape=(16, 20), scale=2, noise_sigma_mm=10, seed=2)
    upsr.super_resolve(scene.lowres, 2, 5, flow="stateful")
    assert most[0] == 1


def test_window_pool_threads_run_numba_and_both_serially():
    import numba

    from upsr.method._parallel import kernel_threads, window_pool

    assert window_pool(0) is None
    pool = window_pool(2)
    if pool is None:  # numba's "workqueue" layer: windows are finished one at a time
        pytest.skip("numba threading layer cannot be shared by threads")
    assert window_pool(2) is pool  # one pool per process and size

    def inside():
        name = threading.current_thread().name
        order = []
        both(lambda: order.append("a"), lambda: order.append(threading.current_thread().name))
        return name, numba.get_num_threads(), order

    name, threads, order = pool.submit(inside).result()
    assert name.startswith("upsr-helper")
    assert threads == kernel_threads(2)
    if (os.cpu_count() or 1) <= 3:
        assert threads == 1  # two cores: each kernel on its window's thread
    assert order == ["a", name]  # nested: on the same thread, in sequence


def test_numba_threads_sets_and_restores_this_threads_count():
    import numba as nb

    before = nb.get_num_threads()
    with numba_threads(1):
        assert nb.get_num_threads() == 1
    assert nb.get_num_threads() == before
