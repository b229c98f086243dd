"""Optional dependencies of the pictures layer (the ``viz`` extra), imported only when used."""

from __future__ import annotations

import importlib
from types import ModuleType

from upsr.errors import InputError

__all__ = ["require"]

#: Module -> the pip package that provides it.
_PACKAGES = {"PIL": "pillow", "imageio_ffmpeg": "imageio-ffmpeg"}


def require(module_name: str, what: str) -> ModuleType:
    """Import an optional module of the ``viz`` extra or raise an InputError naming the extra.

    Parameters
    ----------
    module_name : str
        Module to import (``"PIL.Image"``, ``"imageio_ffmpeg"``, ``"matplotlib"``).
    what : str
        What needs it, for the message (``"writing GIF files"``).
    """
    try:
        return importlib.import_module(module_name)
    except ImportError:
        top = module_name.partition(".")[0]
        package = _PACKAGES.get(top, top)
        raise InputError(
            f"{what} needs the optional package {package!r}: pip install 'upsr[viz]'"
        ) from None
