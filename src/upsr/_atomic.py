"""Atomic creation of files and folders: the one way every layer writes its outputs.

An output is written under a hidden temporary name next to its destination
(``.NAME.~<host>-<pid>-<random>.<tag>``, created exclusively with the usual umask permissions)
and published by a rename only once complete, so a reader never sees a half-written file and an
interrupted run leaves nothing at the destination. A NAME too long for a temporary name within
the 255 bytes of a file name is shortened (its start and a hash of it). The writer's host and
PID in the name let the next writer of the same destination remove the temporaries of writers
that died (SIGKILL) on this host (:func:`remove_stale`). :func:`publish` moves a temporary into
place, without replacing an existing destination unless asked (``os.link`` for files, a
no-replace rename for folders): of two processes finishing the same output, one fails.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import hashlib
import os
import re
import secrets
import shutil
import socket
from pathlib import Path
from typing import IO, Any, TypeVar

__all__ = [
    "AtomicWriter",
    "new_temp_dir",
    "new_temp_file",
    "publish",
    "remove",
    "remove_stale",
    "remove_stale_in",
    "temp_name",
    "write_bytes_atomic",
    "write_text_atomic",
]

PathLike = str | os.PathLike[str]


#: Longest file name (bytes) of the usual file systems.
NAME_MAX = 255
#: Temporary names keep at most this many bytes of the destination's name.
_STEM_MAX = 160


def _host_tag() -> str:
    return hashlib.sha1(socket.gethostname().encode("utf-8", "replace")).hexdigest()[:6]


def _stem(dest: Path) -> str:
    """The destination's name, or, if too long, its start and a hash of it (≤ 160 bytes)."""
    name = dest.name
    raw = name.encode("utf-8", "surrogateescape")
    if len(raw) <= _STEM_MAX:
        return name
    digest = hashlib.sha1(raw).hexdigest()[:12]
    head = raw[: _STEM_MAX - 13].decode("utf-8", "ignore")  # whole characters only
    return f"{head}~{digest}"


def _temp_re(dest: Path) -> re.Pattern[str]:
    return re.compile(
        r"\." + re.escape(_stem(dest)) + r"\.~([0-9a-f]{6})-([0-9]+)-[0-9a-f]{8}\.[a-z]+"
    )


def temp_name(dest: Path, tag: str) -> Path:
    """A hidden name next to ``dest`` no other writer uses: ``.NAME.~<host>-<pid>-<hex>.<tag>``.

    At most 255 bytes, whatever the length of ``dest``'s name (see :func:`_stem`).
    """
    return dest.with_name(
        f".{_stem(dest)}.~{_host_tag()}-{os.getpid()}-{secrets.token_hex(4)}.{tag}"
    )


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, OSError):
        return True  # someone else's live process (or not ours to judge)
    return True


def remove_stale(dest: Path) -> list[Path]:
    """Remove the temporaries of ``dest`` left by dead writers of this host; return them.

    Only names of the form :func:`temp_name` writes, of this host, whose PID no longer runs
    (a live process with a reused PID keeps its files: never removed by mistake).
    """
    pattern = _temp_re(dest)
    host = _host_tag()
    removed = []
    try:
        entries = list(os.scandir(dest.parent if str(dest.parent) else "."))
    except OSError:
        return removed
    for e in entries:
        m = pattern.fullmatch(e.name)
        if m is None or m.group(1) != host or _pid_alive(int(m.group(2))):
            continue
        p = Path(e.path)
        remove(p)
        removed.append(p)
    return removed


#: Any name :func:`temp_name` writes (the destination's stem in group 1).
_ANY_TEMP = re.compile(r"\.(.+)\.~[0-9a-f]{6}-[0-9]+-[0-9a-f]{8}\.[a-z]+")


def remove_stale_in(folder: Path) -> list[Path]:
    """:func:`remove_stale` for every destination in ``folder`` that has temporaries (e.g. the
    chunks of killed workers); return what was removed."""
    try:
        names = {m.group(1) for e in os.scandir(folder) if (m := _ANY_TEMP.fullmatch(e.name))}
    except OSError:
        return []
    return [p for name in sorted(names) for p in remove_stale(folder / name)]


_RENAME_NOREPLACE = 1


def _rename_noreplace(src: Path, dst: Path) -> None:
    """rename(2) that fails with FileExistsError if ``dst`` exists (Linux renameat2)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        fn = None
    if fn is not None:
        at_fdcwd = -100
        rc = fn(at_fdcwd, os.fsencode(src), at_fdcwd, os.fsencode(dst), _RENAME_NOREPLACE)
        if rc == 0:
            return
        err = ctypes.get_errno()
        if err == errno.EEXIST:
            raise FileExistsError(errno.EEXIST, os.strerror(err), str(dst))
        if err not in (errno.EINVAL, errno.ENOSYS, errno.EPERM, errno.ENOTSUP):
            raise OSError(err, os.strerror(err), str(dst))
    # no renameat2 here: rename() never replaces a non-empty folder (a published output)
    if os.path.lexists(dst):
        raise FileExistsError(errno.EEXIST, "File exists", str(dst))
    os.rename(src, dst)


def publish(tmp: Path, dest: Path, *, replace: bool) -> None:
    """Move the complete temporary ``tmp`` to ``dest``.

    ``replace=False``: FileExistsError if ``dest`` exists, also when another process creates
    it meanwhile (files: ``os.link`` then unlink of the temporary; folders: a no-replace
    rename). ``replace=True``: ``os.replace``.
    """
    if replace:
        os.replace(tmp, dest)
        return
    if tmp.is_dir() and not tmp.is_symlink():
        _rename_noreplace(tmp, dest)
        return
    try:
        os.link(tmp, dest)
    except FileExistsError:
        raise
    except OSError as e:  # no hard links on this file system
        if e.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EMLINK, errno.EXDEV):
            raise
        _rename_noreplace(tmp, dest)
        return
    os.unlink(tmp)


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
