"""Atomic creation of files and folders: the one way every layer writes its outputs.

An output is written under a hidden temporary name next to its destination
(``.NAME.<random>.<tag>``, created exclusively with the usual umask permissions) and published
by a rename only once complete, so a reader never sees a half-written file and an interrupted
run leaves nothing at the destination.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
from pathlib import Path
from typing import IO, Any, TypeVar

__all__ = [
    "AtomicWriter",
    "new_temp_dir",
    "new_temp_file",
    "remove",
    "temp_name",
    "write_bytes_atomic",
    "write_text_atomic",
]

PathLike = str | os.PathLike[str]


def temp_name(dest: Path, tag: str) -> Path:
    """A hidden name next to ``dest`` that no other writer uses: ``.NAME.<8 hex>.<tag>``."""
    return dest.with_name(f".{dest.name}.{secrets.token_hex(4)}.{tag}")


def new_temp_file(dest: Path, tag: str = "part") -> tuple[Path, IO[bytes]]:
    """Create a new temporary file next to ``dest`` (exclusively; umask permissions).

    Returns
    -------
    (pathlib.Path, file)
        Its path and a binary file object open for reading and writing.
    """
    for _ in range(100):
        p = temp_name(dest, tag)
        try:  # plain os.open: the umask applies, as for any other file the user creates
            fd = os.open(p, os.O_RDWR | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
        except FileExistsError:
            continue
        return p, os.fdopen(fd, "w+b")
    raise FileExistsError(f"cannot create a temporary file next to {dest}")


def new_temp_dir(dest: Path, tag: str = "part") -> Path:
    """Create a new temporary folder next to ``dest`` (exclusively)."""
    for _ in range(100):
        p = temp_name(dest, tag)
        try:
            os.mkdir(p)
        except FileExistsError:
            continue
        return p
    raise FileExistsError(f"cannot create a temporary folder next to {dest}")


def remove(path: Path) -> None:
    """Remove a file, link or folder tree if it exists; errors are ignored."""
    with contextlib.suppress(OSError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        elif os.path.lexists(path):
            path.unlink()


def write_bytes_atomic(path: PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically, replacing what was there.

    The parent folder is created if needed; the file gets the usual permissions (umask).

    Returns
    -------
    pathlib.Path
        The path written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp, f = new_temp_file(path, "tmp")
    try:
        with f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        remove(tmp)
        raise
    return path


def write_text_atomic(path: PathLike, text: str) -> Path:
    """:func:`write_bytes_atomic` for UTF-8 text."""
    return write_bytes_atomic(path, text.encode("utf-8"))


_Writer = TypeVar("_Writer", bound="AtomicWriter")


class AtomicWriter:
    """Context-manager protocol of the writers that publish their output only when complete:
    ``close()`` on success, ``abort()`` (nothing left at the output path) on any exception."""

    def close(self) -> Any:  # pragma: no cover - overridden
        raise NotImplementedError

    def abort(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def __enter__(self: _Writer) -> _Writer:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
