"""Tasks that replace :func:`upsr.apps.batch.run_chunk` in the batch tests (importable by
spawned worker processes and Dask workers)."""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any


def crashing_run_chunk(spec: dict[str, Any]) -> dict[str, Any]:
    """Kill the worker process (SIGKILL) on a recording named ``crash*``; else the real task."""
    from upsr.apps.batch import _run_chunk

    if Path(spec["input"]).name.startswith("crash"):
        os.kill(os.getpid(), signal.SIGKILL)
    return _run_chunk(spec)
