"""The ``upsr`` command line: the typer app, the root options and the entry point :func:`main`.

One module per command group registers its commands here: :mod:`~upsr.apps.cli.run`
(``run``), :mod:`~upsr.apps.cli.live` (``live``), :mod:`~upsr.apps.cli.demo` (``demo``,
``analyze``), :mod:`~upsr.apps.cli.pictures`
(``compare``, ``view``), :mod:`~upsr.apps.cli.pointcloud` (``export-ply``),
:mod:`~upsr.apps.cli.batch` (``batch``) and :mod:`~upsr.apps.cli.experiment`
(``experiment ...``); the options they share are defined once in :mod:`~upsr.apps.cli.options`.
Importing them loads neither NumPy nor the method: each command imports what it needs.

Errors in what the user gave (bad files, bad options) print one
line ``upsr: error: …`` on stderr and exit with status 2; anything else is an internal error
(status 1, ``--debug`` shows the traceback); Ctrl-C exits with 130. No partial output is ever
left behind.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import signal
import sys
import threading
import traceback
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import typer

from upsr.apps.cli import batch, demo, experiment, live, pictures, pointcloud, run
from upsr.errors import InputError, one_line

try:  # typer >= 0.24 vendors click
    from typer._click.exceptions import ClickException, UsageError
except ImportError:  # pragma: no cover
    from click.exceptions import ClickException, UsageError  # type: ignore[no-redef]
try:
    from typer._click.exceptions import NoArgsIsHelpError
except ImportError:  # pragma: no cover
    try:
        from click.exceptions import NoArgsIsHelpError  # type: ignore[no-redef]
    except ImportError:

        class NoArgsIsHelpError(UsageError):  # type: ignore[no-redef]
            """Never raised by this click version."""


__all__ = ["app", "main"]


class _State:
    debug = False
    terminated: int | None = None  # the signal (SIGTERM, SIGHUP) that ended the run


app = typer.Typer(
    name="upsr",
    help="UP-SR: super-resolution of dynamic depth videos (Al Ismaeil et al.). "
    "Depth is in millimetres; 0 or NaN means 'no measurement'.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
    rich_markup_mode=None,
)


def _version_callback(value: bool) -> None:
    if value:
        from upsr import __version__

        typer.echo(f"upsr {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_version_callback,
            is_eager=True,
            help="Print the version and exit.",
        ),
    ] = False,
    debug: Annotated[
        bool,
        typer.Option("--debug", help="Debug logging, and full tracebacks on errors."),
    ] = False,
) -> None:
    """UP-SR: super-resolution of dynamic depth videos (Al Ismaeil et al.).

    Depth is in millimetres; 0 or NaN means 'no measurement'.
    """
    _State.debug = _State.debug or debug
    if debug:
        logging.basicConfig(level=logging.DEBUG, format="upsr: %(name)s: %(message)s")


for _module in (run, live, demo, pictures, pointcloud, batch):
    _module.register(app)
app.add_typer(experiment.app, name="experiment")


# -------------------------------------------------------------------------------------------------
# entry point
# -------------------------------------------------------------------------------------------------
_USER_ERRORS = (
    InputError,
    FileNotFoundError,
    PermissionError,
    IsADirectoryError,
    NotADirectoryError,
    FileExistsError,
)
#: OSErrors of the place written to, not of upsr: a full or read-only disk, a quota, a name
#: too long (exit 2, one line, as a bad input: "internal error" said the opposite).
_WHERE_ERRNOS = frozenset(
    getattr(errno, n) for n in ("ENOSPC", "EROFS", "EDQUOT", "ENAMETOOLONG", "EFBIG")
    if hasattr(errno, n)
)  # fmt: skip


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def _print_error(message: str) -> None:
    """``upsr: error: …`` on one line of at most 200 characters (:func:`upsr.errors.one_line`)."""
    print(one_line(f"upsr: error: {message}"), file=sys.stderr, flush=True)


@contextlib.contextmanager
def _cli_environment() -> Iterator[None]:
    """Warnings as one ``upsr: warning:`` line; SIGTERM and SIGHUP (a closed terminal, a
    dropped ssh session) unwind like Ctrl-C (cleanup runs); SIGINT's handler as it was on
    return (``upsr live`` changes it after a first Ctrl-C)."""

    def show(
        message: Any, category: Any, filename: Any, lineno: Any, file: Any = None, line: Any = None
    ) -> None:
        print(one_line(f"upsr: warning: {message}"), file=sys.stderr, flush=True)

    def on_signal(signum: int, frame: Any) -> None:
        _State.terminated = signum
        raise KeyboardInterrupt

    ending = [s for s in (signal.SIGTERM, getattr(signal, "SIGHUP", None)) if s is not None]
    old: dict[int, Any] = {}
    main_thread = threading.current_thread() is threading.main_thread()
    with warnings.catch_warnings():
        warnings.showwarning = show
        if main_thread:
            old = {s: signal.signal(s, on_signal) for s in ending}
            old[signal.SIGINT] = signal.getsignal(signal.SIGINT)
        try:
            yield
        finally:
            for s, handler in old.items():
                signal.signal(s, handler)


def main(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); return the exit status."""
    args = list(sys.argv[1:] if argv is None else argv)
    _State.debug = "--debug" in args
    _State.terminated = None
    command = typer.main.get_command(app)
    try:
        with _cli_environment():
            rv = command.main(args=args, prog_name="upsr", standalone_mode=False)
    except NoArgsIsHelpError as e:
        typer.echo(e.ctx.get_help() if e.ctx is not None else str(e))
        return 0
    except UsageError as e:
        hint = f" (see '{e.ctx.command_path} --help')" if e.ctx is not None else ""
        _print_error(e.format_message() + hint)
        return 2
    except ClickException as e:
        _print_error(e.format_message())
        return 2
    except (typer.Abort, KeyboardInterrupt):
        return _interrupted()
    except Exception as e:
        if _State.debug:
            traceback.print_exc()
        if isinstance(e, _USER_ERRORS) or (isinstance(e, OSError) and e.errno in _WHERE_ERRNOS):
            if isinstance(e, OSError) and e.strerror and e.filename:
                _print_error(f"{_shown(str(e.filename))}: {e.strerror}")
            else:
                _print_error(str(e))
            return 2
        print(
            f"upsr: internal error: {type(e).__name__}: {_one_line(e)} "
            f"(rerun with --debug for a traceback)",
            file=sys.stderr,
            flush=True,
        )
        return 1
    if rv == 130:  # click turned a KeyboardInterrupt into Exit(130); the output was cleaned up
        return _interrupted()
    return rv if isinstance(rv, int) else 0


def _shown(filename: str) -> str:
    """A path for an error: the folder of one of upsr's temporaries (``.NAME.~…``), which the
    user never named."""
    path = Path(filename)
    return str(path.parent) if path.name.startswith(".") and ".~" in path.name else filename


def _interrupted() -> int:
    if _State.terminated is not None:
        name = signal.Signals(_State.terminated).name
        print(f"upsr: terminated ({name}), no output written", file=sys.stderr)
        return 128 + _State.terminated
    print("upsr: interrupted, no output written", file=sys.stderr)
    return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
