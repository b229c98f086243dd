"""The state ``upsr batch`` keeps in its output folder: the folder's lock, the check of the
output folder against the inputs, and the record of the options each output was made with.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from upsr.errors import InputError
from upsr.method.config import UPSRConfig

#: the hidden work folder of an output folder (chunks, options records)
WORK_DIR = ".upsr-batch"
Recording = Any  # upsr.apps.batch.Recording (input, output, ...)


#: the lock file of an output folder (beside its work folder, never inside it)
LOCK_FILE = ".upsr-batch.lock"


@contextlib.contextmanager
def _batch_folder(out: Path) -> Iterator[None]:
    """Create the output folder if needed and hold its lock (``OUT/.upsr-batch.lock``).

    The lock is an exclusive :func:`fcntl.flock` taken without waiting: a second batch on the
    same folder (which would otherwise delete the first one's chunks as stale) is refused
    with an :class:`InputError`. The lock file is removed (while still locked) at the end; a
    process that opened it meanwhile sees that the file it locked is no longer the one at
    the path and tries again. A folder this call created is removed again if it stays empty.
    """
    created = not os.path.lexists(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"--out {out}: cannot create the folder ({e.strerror or e})") from None
    try:
        with _folder_lock(out):
            yield
    finally:
        if created:
            with contextlib.suppress(OSError):
                out.rmdir()  # only if empty (everything failed)


@contextlib.contextmanager
def _folder_lock(out: Path) -> Iterator[None]:
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    path = out / LOCK_FILE
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
        except OSError as e:
            raise InputError(
                f"--out {out}: cannot create {path.name} ({e.strerror or e})"
            ) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = ""
            with contextlib.suppress(OSError, ValueError):
                holder = f" (PID {int(os.pread(fd, 20, 0).decode().strip())})"
            os.close(fd)
            raise InputError(
                f"--out {out} is in use by another upsr batch{holder}: wait for it to finish "
                f"or choose another output folder"
            ) from None
        try:
            st, now = os.fstat(fd), os.stat(path)
            current = (st.st_dev, st.st_ino) == (now.st_dev, now.st_ino)
        except OSError:
            current = False
        if current:
            break
        os.close(fd)  # its previous holder removed it after we opened it: again
    try:
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.close(fd)


def _resolved(p: Path) -> Path:
    try:
        return p.resolve()
    except (OSError, RuntimeError):
        raise InputError(f"{p}: cannot resolve the path (symbolic link loop?)") from None


def _check_out_vs_inputs(out: Path, recs: list[Recording]) -> None:
    """Refuse (before any work) an output folder inside an input folder, or an output that
    is one of the inputs (any recording's, not only its own)."""
    out_res = _resolved(out)
    ins = [(r.input, _resolved(r.input)) for r in recs]
    for inp, in_res in ins:
        if (in_res == out_res or in_res in out_res.parents) and in_res.is_dir():
            raise InputError(
                f"--out {out} is inside the input folder {inp}: choose another output folder"
            )
    for rec in recs:
        dest = _resolved(rec.output)
        for inp, in_res in ins:
            same = dest == in_res
            if not same and os.path.exists(dest) and os.path.exists(in_res):
                with contextlib.suppress(OSError):
                    same = os.path.samefile(dest, in_res)
            if same:
                raise InputError(
                    f"the output {rec.output} of {rec.input} is the input {inp}: "
                    f"choose another output folder"
                )


def _options_record(
    config: UPSRConfig,
    read: dict[str, Any],
    out_fmt: str,
    intrinsics: str | None,
    shrink_frames: bool,
) -> dict[str, Any]:
    """What an output of this batch depends on besides its input (compared on a rerun);
    not the chunking, which does not change the output."""
    rec = {
        "config": dataclasses.asdict(config),
        "read": read,
        "format": out_fmt,
        "intrinsics": intrinsics,
        "shrink_frames": shrink_frames,
    }
    return dict(json.loads(json.dumps(rec, default=str)))


def _record_path(rec: Recording) -> Path:
    """Where the options an output was made with are recorded:
    ``OUT/.upsr-batch/outputs/<output name>.json`` (no chunk folder is named without a dot
    and a fingerprint)."""
    return rec.output.parent / WORK_DIR / "outputs" / f"{rec.output.name}.json"


def _read_record(rec: Recording) -> dict[str, Any] | None:
    """The options record of an output (None: none, or unreadable)."""
    try:
        data = json.loads(_record_path(rec).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and "options" in data else None


def _write_record(rec: Recording, options: dict[str, Any], state: str) -> None:
    """Record (atomically) the options of ``rec``'s output: state "writing" before the
    output is published, "done" once it and its sidecar are complete."""
    from upsr._atomic import write_text_atomic

    path = _record_path(rec)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(
        {"state": state, "input": str(rec.input), "source": input_identity(rec.input),
         "options": options}
    )  # fmt: skip
    write_text_atomic(path, text)


def input_identity(path: Path) -> list[Any]:
    """The input's files as a record keeps them (name, size, modification and change times):
    an output is skipped only for the input it was made from, unchanged."""
    p = Path(path)
    files = [p] if p.is_file() else sorted(q for q in p.iterdir() if q.is_file())
    return [[q.name, (s := q.stat()).st_size, s.st_mtime_ns, s.st_ctime_ns] for q in files]


def _differences(old: dict[str, Any], new: dict[str, Any], prefix: str = "") -> list[str]:
    """``key: old -> new`` for the leaves of two option records that differ."""
    out = []
    for k in sorted(set(old) | set(new)):
        a, b = old.get(k), new.get(k)
        if isinstance(a, dict) and isinstance(b, dict):
            out += _differences(a, b, f"{prefix}{k}.")
        elif a != b:
            out.append(f"{prefix}{k}: {a} -> {b}")
    return out
