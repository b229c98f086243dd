"""``upsr experiment``: the paper's experiments (§7) as commands.

Each command writes a CSV, PNG plot(s) and a ``summary.md`` into ``--out`` (default
``results/<name>/``) and prints the summary. ``--data`` is the shared data folder
(default ``../shared/data``, relative to the current directory); ``--quick`` runs a reduced
version in seconds (small crops / renders, few noise levels). ``all`` runs every experiment
into ``--out/<name>/`` and writes ``--out/REPORT.md``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from enum import Enum
from pathlib import Path
from typing import Annotated, Any

import typer

__all__ = ["app"]

app = typer.Typer(
    name="experiment",
    help="Reproduce the paper's experiments (section 7): CSV, PNG plot and summary.md each.",
    add_completion=False,
    no_args_is_help=True,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"]},
)

_DATA = Path("../shared/data")


class Reference(str, Enum):
    centre = "centre"
    last = "last"


DataOpt = Annotated[
    Path,
    typer.Option(
        "--data",
        help="Shared data folder (middlebury/, samba/), relative to the current directory.",
    ),
]
QuickOpt = Annotated[
    bool, typer.Option("--quick", help="A reduced run that takes seconds (for tests / smoke).")
]
SeedOpt = Annotated[int, typer.Option("--seed", help="Noise seed (>= 0).", min=0)]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress lines on stderr.")]


OutOpt = Annotated[
    Path, typer.Option("--out", "-o", help="Output folder (created; its files are replaced).")
]


def _logger(quiet: bool, name: str) -> Any:
    from upsr.research.experiments.common import null_logger, stderr_logger

    return null_logger if quiet else stderr_logger(f"upsr experiment {name}")


def _command(name: str) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """``app.command(name)``, its output folder removed again if it fails and this run
    created it (a bad --data left an empty one)."""

    def register(fn: Callable[..., None]) -> Callable[..., None]:
        @functools.wraps(fn)
        def run(**kwargs: Any) -> None:
            from upsr.apps._preflight import removed_on_failure

            with removed_on_failure(kwargs["out"]):
                fn(**kwargs)

        return app.command(name)(run)

    return register


def _finish(result: Any) -> None:
    typer.echo(result.summary)
    typer.echo("")
    typer.echo(f"upsr: {result.name} written to {', '.join(str(p) for p in result.files.values())}")


@_command("motion-accuracy")
def motion_accuracy(
    out: OutOpt = Path("results/motion-accuracy"),
    data: DataOpt = _DATA,
    quick: QuickOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Table 2: motion error vs upsampling factor r = 1, 2, 4, 6, 8 (Middlebury Art, 1 px shift)."""
    from upsr.research.experiments.motion_accuracy import run_motion_accuracy

    _finish(run_motion_accuracy(out, data, quick=quick, log=_logger(quiet, "motion-accuracy")))


@_command("cumulative")
def cumulative(
    out: OutOpt = Path("results/cumulative"),
    data: DataOpt = _DATA,
    quick: QuickOpt = False,
    reference: Annotated[
        Reference,
        typer.Option(
            "--reference",
            case_sensitive=False,
            help="Reference frame in the middle of its window (as UP-SR) or at its end "
            "(paper section 3; the full UP-SR row is then left out).",
        ),
    ] = Reference.centre,
    seed: SeedOpt = 0,
    quiet: QuietOpt = False,
) -> None:
    """Figure 2: fused-frame error of non-cumulative vs cumulative registration."""
    from upsr.research.experiments.cumulative import run_cumulative

    _finish(
        run_cumulative(
            out,
            data,
            quick=quick,
            reference=reference.value,
            seed=seed,
            log=_logger(quiet, "cumulative"),
        )
    )


@_command("noise")
def noise(
    out: OutOpt = Path("results/noise"),
    data: DataOpt = _DATA,
    quick: QuickOpt = False,
    seed: SeedOpt = 0,
    quiet: QuietOpt = False,
) -> None:
    """Figure 6: MSE vs noise (0..100 mm) on Samba, r = 4, N = 9, for every method."""
    from upsr.research.experiments.noise import run_noise

    _finish(run_noise(out, data, quick=quick, seed=seed, log=_logger(quiet, "noise")))


@_command("factors")
def factors(
    out: OutOpt = Path("results/factors"),
    data: DataOpt = _DATA,
    quick: QuickOpt = False,
    seed: SeedOpt = 0,
    quiet: QuietOpt = False,
) -> None:
    """Figure 7: MSE of fusion and deblurring vs noise for r = 1, 2, 4, with the model."""
    from upsr.research.experiments.factors import run_factors

    _finish(run_factors(out, data, quick=quick, seed=seed, log=_logger(quiet, "factors")))


@_command("all")
def all_experiments(
    out: OutOpt = Path("results"),
    data: DataOpt = _DATA,
    quick: QuickOpt = False,
    seed: SeedOpt = 0,
    quiet: QuietOpt = False,
) -> None:
    """Run every experiment into OUT/<name>/ and write OUT/REPORT.md."""
    from upsr.research.experiments.report import run_all

    results, path = run_all(out, data, quick=quick, seed=seed, log=_logger(quiet, "all"))
    for res in results:
        typer.echo(f"{res.name}: {res.out}")
    typer.echo(f"upsr: report written to {path}")
