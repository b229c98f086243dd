"""Shared plumbing of the experiments: results, CSV / Markdown / PNG output, logging.

Every experiment returns an :class:`ExperimentResult` and writes, into its output folder,
``<name>.csv`` (one row per measurement), one or more ``<name>*.png`` plots (each with an
``.svg`` twin) drawn with :mod:`upsr.viz.figures`, and ``summary.md`` (what was done, the
table, the reading). Files are written atomically (:mod:`upsr._atomic`).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from upsr._atomic import write_text_atomic
from upsr.errors import InputError
from upsr.viz.figures import LinePlot, write_figure

__all__ = [
    "DEFAULT_DATA",
    "ExperimentResult",
    "Logger",
    "check_out_dir",
    "fmt_value",
    "markdown_table",
    "null_logger",
    "stderr_logger",
    "write_csv",
    "write_plot",
    "write_summary",
]

#: Default ``--data`` folder, relative to the current directory (the repository root).
DEFAULT_DATA = Path("../shared/data")

Logger = Callable[[str], None]


def stderr_logger(prefix: str) -> Logger:
    """A logger printing ``prefix: message`` lines on stderr."""

    def log(message: str) -> None:
        print(f"{prefix}: {message}", file=sys.stderr, flush=True)

    return log


def null_logger(message: str) -> None:
    """A logger that discards its messages."""


@dataclass
class ExperimentResult:
    """What one experiment measured and wrote.

    Attributes
    ----------
    name : str
        Experiment name (``motion-accuracy``, ``cumulative``, ``noise``, ``factors``).
    title : str
        One-line title (paper table / figure it reproduces).
    out : pathlib.Path
        Output folder.
    rows : list of dict
        The rows of the main CSV.
    files : dict of str to pathlib.Path
        Files written (``csv``, ``png``, ``summary`` and extras).
    summary : str
        The Markdown summary (also in ``files["summary"]``).
    extra : dict
        Experiment-specific values (e.g. the selected estimator).
    """

    name: str
    title: str
    out: Path
    rows: list[dict[str, Any]]
    files: dict[str, Path] = field(default_factory=dict)
    summary: str = ""
    extra: dict[str, Any] = field(default_factory=dict)


def check_out_dir(out: str | Path) -> Path:
    """The output folder as a Path (created); an existing non-folder is an input error."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise InputError(f"--out {path} exists and is not a folder")
    path.mkdir(parents=True, exist_ok=True)
    return path


def fmt_value(value: Any, digits: int = 6) -> str:
    """A CSV / table cell: floats with ``digits`` significant digits, NaN as ``nan``."""
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if math.isnan(v):
            return "nan"
        return f"{v:.{digits}g}"
    if value is None:
        return ""
    return str(value)


def write_csv(path: str | Path, rows: Sequence[Mapping[str, Any]], columns: Sequence[str]) -> Path:
    """Write ``rows`` (dicts) with the given column order as a CSV file (atomically).

    Missing keys give empty cells; keys not in ``columns`` are ignored.
    """
    lines = [",".join(columns)]
    for row in rows:
        cells = []
        for col in columns:
            cell = fmt_value(row.get(col))
            if any(c in cell for c in ',"\n'):
                cell = '"' + cell.replace('"', '""') + '"'
            cells.append(cell)
        lines.append(",".join(cells))
    return write_text_atomic(path, "\n".join(lines) + "\n")


def markdown_table(
    rows: Sequence[Mapping[str, Any]],
    columns: Sequence[str],
    headers: Sequence[str] | None = None,
    formats: Mapping[str, str] | None = None,
) -> str:
    """A GitHub Markdown table of ``rows``.

    Parameters
    ----------
    rows : sequence of mappings
        One dict per table row.
    columns : sequence of str
        Keys shown, in order.
    headers : sequence of str, optional
        Column titles (default: the keys).
    formats : mapping, optional
        Per-key format spec (``"{:.3f}"``); other values use :func:`fmt_value` with 4 digits.
    """
    formats = formats or {}
    heads = list(headers) if headers is not None else list(columns)
    lines = ["| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
    for row in rows:
        cells = []
        for col in columns:
            v = row.get(col)
            if col in formats and isinstance(v, (int, float, np.integer, np.floating)):
                fv = float(v)
                cells.append("nan" if math.isnan(fv) else formats[col].format(fv))
            else:
                cells.append(fmt_value(v, 4))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_plot(path: str | Path, plot: LinePlot) -> Path:
    """Write a plot as ``path`` (PNG) and its ``.svg`` twin; returns the PNG's path."""
    return write_figure(path, plot)[0]


def write_summary(path: str | Path, text: str) -> Path:
    """Write a Markdown summary (a trailing newline is added if missing)."""
    return write_text_atomic(path, text if text.endswith("\n") else text + "\n")
