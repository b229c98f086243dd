"""Output paths: what may be written where, checked before anything is written.

:func:`check_output_path` refuses an output that would overwrite or sit inside an input, an
existing output without ``overwrite`` (and, with it, a replacement of another kind: a folder by
a file, a folder holding other things than frames), special files (FIFOs, devices), symbolic
link loops and outputs whose folder cannot be written. :class:`upsr.io.VideoWriter` runs it on
creation and again just before it publishes an output.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
from collections.abc import Iterable
from pathlib import Path

from upsr.errors import InputError
from upsr.io._base import PathLike

__all__ = ["check_apart_from_inputs", "check_output_path"]


def check_output_path(
    input_paths: Iterable[PathLike] | PathLike,
    output_path: PathLike,
    overwrite: bool = False,
    *,
    fmt: str | None = None,
) -> Path:
    """Check that writing ``output_path`` is safe; return it as a :class:`~pathlib.Path`.

    Refused (:class:`~upsr.errors.InputError`):

    - an output that is one of the inputs (same path after resolving symlinks, or the same
      file through a hard link), or a folder that contains an input;
    - an existing output unless ``overwrite``; with ``overwrite``, an existing folder is only
      replaced by PNG output and only if it holds nothing but PNG files, and a folder is never
      replaced by a file or a file by a folder;
    - an output whose nearest existing ancestor is not a writable folder.

    Missing parent folders are allowed: :class:`VideoWriter` creates them.
    """
    from upsr.io.video import _folder_output, _output_format

    out = Path(output_path)
    check_apart_from_inputs(input_paths, out)
    try:
        st_out = os.lstat(out)
    except (FileNotFoundError, NotADirectoryError):  # a parent that is a file: checked below
        st_out = None
    except OSError as e:
        raise InputError(f"output {out}: cannot access ({e.strerror or e})") from None
    if st_out is not None:
        try:
            st_target = os.stat(out)
        except OSError:  # a dangling link: replaced like a file
            st_target = st_out
        mode = st_target.st_mode
        dangling = st_target is st_out and stat.S_ISLNK(mode)
        if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode) or dangling):
            from upsr.io._base import file_kind

            raise InputError(
                f"output {out} is {file_kind(mode)}: refusing to write to or replace it"
            )
    f = _output_format(out, fmt)
    if os.path.lexists(out):
        if not overwrite:
            raise InputError(
                f"output {out} already exists (use --overwrite / overwrite=True to replace it)"
            )
        is_dir = out.is_dir() and not out.is_symlink()
        if _folder_output(f, out):
            frame_suffix = f".{f}"
            if not is_dir:
                raise InputError(
                    f"output {out} exists and is not a folder: refusing to replace "
                    f"it by a folder of {f.upper()} frames"
                )
            try:
                entries = list(os.scandir(out))
            except OSError as e:
                raise InputError(f"output {out}: cannot list ({e.strerror or e})") from None
            other = [
                e.name
                for e in entries
                if not (e.is_file(follow_symlinks=False) and e.name.lower().endswith(frame_suffix))
            ]
            if other:
                raise InputError(
                    f"refusing to replace folder {out}: it holds other things "
                    f"than {f.upper()} frames (e.g. {other[0]!r})"
                )
        elif is_dir:
            raise InputError(f"output {out} is a folder: refusing to replace it by a .{f} file")
    anc = Path(os.path.abspath(out)).parent
    while not anc.exists() and anc != anc.parent:
        if os.path.lexists(anc):  # dangling symlink
            raise InputError(f"cannot create {out}: {anc} is a broken link")
        anc = anc.parent
    if not anc.is_dir():
        raise InputError(f"cannot create {out}: {anc} is not a folder")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise InputError(f"cannot create {out}: no permission to write in {anc}")
    return out


def check_apart_from_inputs(
    input_paths: Iterable[PathLike] | PathLike, output_path: PathLike, what: str = "output"
) -> None:
    """Refuse (:class:`~upsr.errors.InputError`) an output (a video, a picture, a folder of
    point clouds) that is one of the inputs (same path after resolving symbolic links, or the
    same file through a hard link), a folder that contains one, or that lies inside an input
    folder: nothing is ever written into or over an input, ``--overwrite`` or not."""
    out = Path(output_path)
    if isinstance(input_paths, (str, os.PathLike)):
        input_paths = [input_paths]
    out_res = _resolve(out, what)
    for inp in input_paths:
        inp = Path(inp)
        in_res = _resolve(inp, "input")
        same = out_res == in_res
        if not same and os.path.exists(out) and os.path.exists(inp):
            with contextlib.suppress(OSError):
                same = os.path.samefile(out, inp)
        if same:
            raise InputError(f"{what} {out} is the input {inp}: choose another path")
        if out_res in in_res.parents:
            raise InputError(f"{what} folder {out} contains the input {inp}: choose another path")
        if in_res in out_res.parents and in_res.is_dir():
            raise InputError(
                f"{what} {out} is inside the input folder {inp.name or inp}: choose another path"
            )


def _resolve(p: Path, what: str) -> Path:
    try:
        return p.resolve()
    except RuntimeError:  # Python < 3.13: "Symlink loop"
        raise InputError(f"{what} {p}: symbolic link loop") from None
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise InputError(f"{what} {p}: symbolic link loop") from None
        raise InputError(f"{what} {p}: cannot access ({e.strerror or e})") from None
