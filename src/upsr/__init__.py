"""upsr: super-resolution of dynamic depth videos (UP-SR, Al Ismaeil et al.).

Quick use::

    import upsr
    hi = upsr.super_resolve(frames_mm, scale=4, n_frames=9)   # (T, 4h, 4w) float32 mm

The package has five layers, each a subpackage (an arrow means "may import"; see the README's
architecture section):

* :mod:`upsr.method` — the paper's Table 1, one module per step, and the engines;
* :mod:`upsr.geometry` — pinhole camera, intrinsics, mesh rendering;
* :mod:`upsr.io` — depth video formats; :mod:`upsr.viz` — pictures;
* :mod:`upsr.research` — metrics, baselines, synthetic data, experiments, analysis;
* :mod:`upsr.apps` — the command line, demo and batch.

Everything here is loaded on first use (PEP 562).
"""

import os
from typing import Any

from upsr._lazy import attach

# The compiled kernels' OpenMP threads (numba's default threading layer on Linux) wait for
# work passively instead of spinning: where another process takes a core, a spinning thread
# holds it while the thread it waits for is descheduled, and every parallel kernel waits a
# scheduler slice (the recursive ToF stream fell from 92 to 3.6 frames/s with one busy
# process beside it on two cores, 68 with this; alone, the same rate at less CPU). Read by
# the OpenMP runtime when numba first loads it; a value the user set is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
# OpenMP first, as above: numba tries TBB first, and an older libtbb already loaded (Open3D's)
# made it warn on every process's first kernel (read when numba is first imported).
os.environ.setdefault("NUMBA_THREADING_LAYER_PRIORITY", "omp tbb workqueue")

_lazy_getattr, __dir__, __all__ = attach(
    __name__,
    submodules=["apps", "errors", "geometry", "io", "method", "research", "viz"],
    names={
        "UPSR": "method.windowed",
        "super_resolve": "method.windowed",
        "UPSRConfig": "method.config",
        "DeblurConfig": "method.config",
        "InputError": "errors",
        "deblur": "method.deblurring",
        "temporal_median": "method.fusion",
        "remove_speckles": "method.outliers",
        "upsample_nearest": "method.upsampling",
        "decimate": "method.upsampling",
        "metrics": "research",
        "baselines": "research",
        "synth": "research",
    },
)


def __getattr__(name: str) -> Any:
    if name == "__version__":  # from the package metadata, read on first use (not on import)
        from importlib.metadata import PackageNotFoundError, version

        try:
            value = version("upsr")
        except PackageNotFoundError:  # pragma: no cover - running from a source tree
            value = "0+unknown"
        globals()["__version__"] = value
        return value
    return _lazy_getattr(name)
