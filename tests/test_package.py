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
