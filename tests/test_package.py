"""What ``import upsr`` does to its process (upsr/__init__.py)."""

import os
import subprocess
import sys

import pytest


@pytest.mark.parametrize(("given", "expected"), [(None, "PASSIVE"), ("ACTIVE", "ACTIVE")])
def test_the_kernels_threads_wait_passively_unless_the_user_chose(given, expected):
    """numba's OpenMP threads must not spin while waiting: beside another busy process on two
    cores a spinning thread holds its core and every parallel kernel waits a scheduler slice
    (benchmarks/load_eval.py). A policy the user set is kept."""
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    if given is not None:
        env["OMP_WAIT_POLICY"] = given
    code = "import os, upsr; print(os.environ['OMP_WAIT_POLICY'])"
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == expected


def test_open3d_imported_first_does_not_make_numba_warn():
    """Open3D loads an older libtbb; numba tried TBB first and warned ("The TBB threading
    layer requires TBB version 2021 update 6 ...") on the first kernel: OpenMP first."""
    pytest.importorskip("open3d")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER_PRIORITY"}
    code = (
        "import warnings; warnings.simplefilter('error')\n"
        "import open3d, upsr\n"
        "import numba, numpy as np\n"
        "@numba.njit(parallel=True)\n"
        "def f(a):\n"
        "    for i in numba.prange(a.size):\n"
        "        a[i] += 1\n"
        "f(np.zeros(4)); print(numba.threading_layer())"
    )
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout.strip() == "omp", done.stderr
