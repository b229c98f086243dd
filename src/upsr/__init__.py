"""upsr: super-resolution of dynamic depth videos (UP-SR, Al Ismaeil et al.)."""

from .config import DeblurConfig, UPSRConfig
from .errors import InputError
from .pipeline import super_resolve

__all__ = ["DeblurConfig", "InputError", "UPSRConfig", "super_resolve"]
__version__ = "0.1.0"
