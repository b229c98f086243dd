"""upsr: super-resolution of dynamic depth videos (UP-SR, Al Ismaeil et al.).

Quick use::

    import upsr
    hi = upsr.super_resolve(frames_mm, scale=4, n_frames=9)   # (T, 4h, 4w) float32 mm

The steps of the paper's Table 1 live in their own modules: :mod:`upsr.upsampling`,
:mod:`upsr.motion`, :mod:`upsr.registration`, :mod:`upsr.fusion`, :mod:`upsr.deblurring`,
assembled by :mod:`upsr.pipeline`. Metrics (SPEC §6) are in :mod:`upsr.metrics`, baselines in
:mod:`upsr.baselines`, synthetic data in :mod:`upsr.synth`, file formats in :mod:`upsr.io`.
"""

from . import baselines, metrics, synth
from .config import DeblurConfig, UPSRConfig
from .deblurring import deblur
from .errors import InputError
from .fusion import temporal_median
from .outliers import remove_speckles
from .pipeline import UPSR, super_resolve
from .upsampling import decimate, upsample_nearest

__all__ = [
    "UPSR",
    "DeblurConfig",
    "InputError",
    "UPSRConfig",
    "baselines",
    "deblur",
    "decimate",
    "metrics",
    "remove_speckles",
    "super_resolve",
    "synth",
    "temporal_median",
    "upsample_nearest",
]
__version__ = "0.1.0"
