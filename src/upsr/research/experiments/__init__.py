"""The paper's experiments (§7) as functions and ``upsr experiment`` commands.

* ``motion-accuracy`` — Table 2, motion error vs upsampling factor: :func:`run_motion_accuracy`
* ``cumulative`` — Fig. 2, cumulative registration: :func:`run_cumulative`
* ``noise`` — Fig. 6, MSE vs noise on Samba for every method: :func:`run_noise`
* ``factors`` — Fig. 7, MSE vs noise for r = 1, 2, 4 with the model of §6: :func:`run_factors`
* ``all`` — all of them and ``REPORT.md``: :func:`run_all`

Every run writes a CSV, plots as PNG + SVG (:mod:`upsr.viz.figures`) and ``summary.md`` into its
output folder and returns an :class:`ExperimentResult`.
"""

from __future__ import annotations

from upsr.research.experiments.common import ExperimentResult
from upsr.research.experiments.cumulative import run_cumulative
from upsr.research.experiments.factors import run_factors
from upsr.research.experiments.motion_accuracy import run_motion_accuracy
from upsr.research.experiments.noise import run_noise
from upsr.research.experiments.report import run_all

__all__ = [
    "ExperimentResult",
    "run_all",
    "run_cumulative",
    "run_factors",
    "run_motion_accuracy",
    "run_noise",
]
