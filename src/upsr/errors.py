"""Exceptions raised by :mod:`upsr`.

:class:`InputError` marks a problem with what the caller gave us (data or parameters); the
command line maps it to exit code 2 with one readable line. Anything else is an internal error.
"""

from __future__ import annotations

__all__ = ["InputError"]


class InputError(ValueError):
    """Bad input data or bad parameters (the caller's fault, not ours)."""
