"""``upsr demo`` and ``upsr analyze``: the commands that need no input data.

``upsr demo``
    The built-in demonstration (:func:`upsr.apps.demo.run_demo`).
``upsr analyze``
    The statistical analysis of the median fusion, paper §6
    (:func:`upsr.research.analysis.run_analysis`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from upsr.apps.cli.options import QuietOpt

__all__ = ["analyze", "demo", "register"]


def demo(
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            "-o",
            help="Folder for the demo's videos, figures and metrics (created if needed; those "
            "files are replaced).",
        ),
    ] = Path("results/demo"),
    seed: Annotated[
        int, typer.Option("--seed", help="Random seed of the synthetic scene and noise.")
    ] = 0,
    quiet: QuietOpt = False,
) -> None:
    """Run the built-in demo: a synthetic moving scene, UP-SR vs baselines, metrics table."""
    from upsr.apps import demo as demo_module
    from upsr.apps._preflight import kernel_note, removed_on_failure

    kernel_note(quiet)
    with removed_on_failure(out):
        result = demo_module.run_demo(out, seed=seed, progress=not quiet)
    typer.echo(demo_module.format_metrics_table(result))
    files = result.get("files") if isinstance(result, dict) else None
    if isinstance(files, dict) and files:
        typer.echo(f"upsr: demo results written to {', '.join(map(str, files.values()))}")
    else:
        typer.echo(f"upsr: demo results written to {out}")


def analyze(
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            "-o",
            help="Folder for analysis_vs_n.csv/.png and analysis_vs_sigma.csv/.png "
            "(created if needed; those files are replaced).",
        ),
    ] = Path("results/analysis"),
    sigma: Annotated[
        float, typer.Option("--sigma", help="Noise std (mm) of the sweep over N, > 0.")
    ] = 30.0,
    max_frames: Annotated[
        int, typer.Option("--max-frames", help="Largest number of frames N, 1..1000.")
    ] = 25,
    trials: Annotated[
        int, typer.Option("--trials", help="Monte-Carlo medians per point, 1..10^7.")
    ] = 20_000,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the Monte-Carlo draws, >= 0.")] = 0,
) -> None:
    """Statistical analysis (paper §6): variance of the median fusion, theory vs Monte-Carlo.

    Exact variance of the median of N Laplace samples, the Cramér–Rao bound and a
    Monte-Carlo estimate, vs N = 1..max-frames (at --sigma) and vs sigma = 0..100 mm (N = 9).
    """
    from upsr.apps._preflight import removed_on_failure
    from upsr.research import analysis

    with removed_on_failure(out):
        result = analysis.run_analysis(
            out, sigma=sigma, max_frames=max_frames, trials=trials, seed=seed
        )
    typer.echo(analysis.format_analysis_table(result))
    typer.echo(f"upsr: analysis written to {', '.join(result['files'].values())}")


def register(app: typer.Typer) -> None:
    """Add ``demo`` and ``analyze`` to the ``upsr`` app."""
    app.command("demo", epilog="\b\nExample:\n  upsr demo --out results/demo --seed 1")(demo)
    app.command(
        "analyze",
        epilog="\b\nExample:\n  upsr analyze --out results/analysis --sigma 20 --trials 50000",
    )(analyze)
