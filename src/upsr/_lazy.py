"""Lazy public namespaces (PEP 562), in the manner of scikit-image's ``lazy_loader``.

A package lists its public submodules and the public names it re-exports from them; nothing
is imported until first used, so ``import upsr`` stays cheap and a command that needs only
the I/O layer never loads the research code.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterable, Mapping
from typing import Any


def attach(
    package: str,
    submodules: Iterable[str] = (),
    names: Mapping[str, str] | None = None,
) -> tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]:
    """``__getattr__``, ``__dir__`` and ``__all__`` for a lazily loaded package.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    submodules : iterable of str
        Submodules importable as attributes (``upsr.method.fusion``).
    names : mapping of str to str
        Public name -> submodule (relative to ``package``) that defines it.
    """
    subs = set(submodules)
    where = dict(names or {})
    public = sorted(subs | set(where))

    def __getattr__(name: str) -> Any:
        if name in where:
            return getattr(importlib.import_module(f"{package}.{where[name]}"), name)
        if name in subs:
            return importlib.import_module(f"{package}.{name}")
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return list(public)

    return __getattr__, __dir__, list(public)


def by_module(**exports: Iterable[str]) -> dict[str, str]:
    """The ``names`` table of :func:`attach` written per submodule.

    Examples
    --------
    >>> by_module(camera=["PinholeCamera"], rendering=["look_at", "render_depth"])
    {'PinholeCamera': 'camera', 'look_at': 'rendering', 'render_depth': 'rendering'}
    """
    return {name: module for module, names in exports.items() for name in names}
