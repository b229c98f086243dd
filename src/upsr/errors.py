"""Exceptions raised by :mod:`upsr`.

:class:`InputError` marks a problem with what the caller gave us (data or parameters); the
command line maps it to exit code 2 with one readable line. Anything else is an internal error.
"""

from __future__ import annotations

__all__ = ["MAX_MESSAGE_CHARS", "InputError", "one_line", "short_list"]

#: Longest error line the command line prints (README: one readable line).
MAX_MESSAGE_CHARS = 200


class InputError(ValueError):
    """Bad input data or bad parameters (the caller's fault, not ours)."""


def one_line(text: object, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``text`` on one line (whitespace runs collapsed) of at most ``limit`` characters.

    A longer text keeps its start and its end around ``" … "`` (the end often names the
    cause: ``… (No space left on device)``).

    Examples
    --------
    >>> one_line("bad  \t input")
    'bad input'
    >>> len(one_line("x" * 500))
    200
    """
    s = " ".join(str(text).split())
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
