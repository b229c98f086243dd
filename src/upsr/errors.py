"""Exceptions raised by :mod:`upsr`.

:class:`InputError` marks a problem with what the caller gave us (data or parameters); the
command line maps it to exit code 2 with one readable line. Anything else is an internal error.
"""

from __future__ import annotations

import re

__all__ = ["MAX_MESSAGE_CHARS", "InputError", "one_line", "short_list"]

#: Longest error line the command line prints (README: one readable line).
MAX_MESSAGE_CHARS = 200


class InputError(ValueError):
    """Bad input data or bad parameters (the caller's fault, not ours)."""


#: A path in a message (a run of characters without spaces or quotes, holding a ``/``).
_PATH = re.compile(r"[^\s'\"(),;]*/[^\s'\"(),;]*")
#: Paths longer than this are cut to their last two parts in a line that is too long.
_LONG_PATH_CHARS = 40


def _short_path(match: re.Match[str]) -> str:
    path = match.group(0)
    if len(path) <= _LONG_PATH_CHARS:
        return path
    tail = [p for p in path.rstrip(":").split("/") if p][-2:]
    return "…/" + "/".join(tail) + (":" if path.endswith(":") else "")


def one_line(text: object, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``text`` on one line (whitespace runs collapsed) of at most ``limit`` characters.

    A longer text first loses the folders of its long paths (``…/last/two``: the advice
    after a path must not be cut); then it keeps its start and its end around ``" … "``
    (the end often names the cause: ``… (No space left on device)``).

    Examples
    --------
    >>> one_line("bad  \t input")
    'bad input'
    >>> len(one_line("x" * 500))
    200
    >>> one_line("/data/" + "d" * 200 + "/rec/frames: use --input-format tum", limit=60)
    '…/rec/frames: use --input-format tum'
    """
    s = " ".join(str(text).split())
    if len(s) <= limit:
        return s
    s = _PATH.sub(_short_path, s)
    if len(s) <= limit:
        return s
    tail = max(limit // 4, 1)
    head = limit - tail - 3
    return s[:head] + " … " + s[len(s) - tail :]


def short_list(items: object, limit: int = 5, width: int = 80) -> str:
    """``a, b, c …and N more``: at most ``limit`` items and about ``width`` characters."""
    names = [str(x) for x in items]  # type: ignore[attr-defined]
    shown: list[str] = []
    used = 0
    for n in names[:limit]:
        n = n if len(n) <= 40 else n[:37] + "..."
        if shown and used + len(n) + 2 > width:
            break
        shown.append(n)
        used += len(n) + 2
    more = len(names) - len(shown)
    return ", ".join(shown) + (f" …and {more} more" if more else "")
