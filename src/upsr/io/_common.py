"""Helpers shared by the format modules (not public)."""

from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

from upsr.errors import InputError
from upsr.io._base import MAX_FRAME_PIXELS, check_frame_budget, natural_key, reading

__all__ = [
    "c_output_captured",
    "check_frame_size",
    "frame_files",
    "mixed_size",
]


#: Suffixes of files that each hold a whole recording (a folder of them is no video).
_RECORDINGS = (".npy", ".npz", ".bag", ".db3", ".mcap")


def frame_files(path: Path, suffixes: tuple[str, ...], what: str) -> list[Path]:
    """A single file as a one-frame list, or the files of a folder with one of ``suffixes``.

    Hidden files are skipped; natural name order (``f2`` before ``f10``).

    Raises
    ------
    InputError
        A folder without such files, or with one that is a broken link, a pipe, a device or
        a folder (it was skipped: the video lost a frame in its middle).
    """
    if not path.is_dir():
        return [path]
    with reading(str(path)):
        entries = list(os.scandir(path))
    named = [
        e
        for e in entries
        if not e.name.startswith(".") and os.path.splitext(e.name)[1].lower() in suffixes
    ]
    for e in named:  # (a frame skipped would shift every later one in time)
        if not e.is_file():
            what_it_is = "a broken link" if not os.path.exists(e.path) else "not a regular file"
            raise InputError(f"{e.path}: a frame of this folder is {what_it_is}")
    files = [Path(e.path) for e in named]
    if not files:
        subdirs = sorted(e.name for e in entries if e.is_dir() and not e.name.startswith("."))
        videos = sorted(e.name for e in entries if e.is_file() and not e.name.startswith(".")
                        and os.path.splitext(e.name)[1].lower() in _RECORDINGS)  # fmt: skip
        hint = ""
        if videos:
            kinds = sorted({os.path.splitext(v)[1].lower() for v in videos})
            glob = f"*{kinds[0]}" if len(kinds) == 1 else "*"
            hint = f": it holds recordings ({', '.join(videos[:3])}): give one, or all to upsr "
            hint += f"batch {path}/{glob}"
        elif subdirs:
            hint = f": give a subfolder ({', '.join(subdirs[:5])}), or all to upsr batch {path}/*"
        raise InputError(f"{path}: no {what} frames in this folder{hint}")
    files.sort(key=lambda p: natural_key(p.name))
    return files


def check_frame_size(name: str, h: int, w: int) -> None:
    """Refuse empty or absurdly large frames (decompression bombs, corrupt headers)."""
    if h < 1 or w < 1:
        raise InputError(f"{name}: empty {w}x{h} image")
    if h * w > MAX_FRAME_PIXELS:
        raise InputError(f"{name}: frames of {w}x{h} pixels are too large")
    check_frame_budget(name, h, w, 16)  # stored sample (<= 8 B), float32 frame and a copy


def mixed_size(name: str, hw: tuple[int, int], first: str, first_hw: tuple[int, int]) -> InputError:
    """The error for a frame whose size differs from the first frame's."""
    return InputError(
        f"{name}: frame size {hw[1]}x{hw[0]} differs from the first frame's "
        f"{first_hw[1]}x{first_hw[0]} ({first})"
    )


def _flush_c_stdio() -> None:
    """fflush(NULL): C stdio buffers (and C++ streams synced with them) reach the descriptors."""
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def c_output_captured() -> Iterator[list[str]]:
    """Capture what C/C++ libraries print on file descriptors 1 and 2 (OpenEXR does).

    Yields a list that receives the captured text (one string) when the block ends, so that a
    library's complaint can become part of one readable error instead of stray output.
    """
    out: list[str] = []
    fds = (1, 2)  # what C code writes to, whatever sys.stdout / sys.stderr are now
    with contextlib.suppress(Exception):
        sys.stdout.flush()
        sys.stderr.flush()
    try:
        saved = [os.dup(fd) for fd in fds]
    except OSError:
        yield out
        return
    _flush_c_stdio()
    py_text = io.StringIO()  # bindings may print through Python's sys.stdout / sys.stderr
    with tempfile.TemporaryFile() as tmp:
        try:
            for fd in fds:
                os.dup2(tmp.fileno(), fd)
            with contextlib.redirect_stdout(py_text), contextlib.redirect_stderr(py_text):
                yield out
        finally:
            _flush_c_stdio()
            for fd, s in zip(fds, saved, strict=True):
                os.dup2(s, fd)
                os.close(s)
            tmp.seek(0)
            out.append(tmp.read().decode("utf-8", "replace") + " " + py_text.getvalue())
