"""Evaluation of runs: metrics (:mod:`uwcosim.evaluation.metrics`), densities and distances for
the reference-posterior study (``density``, ``distance``), the lost-track criterion
(``trackloss``) and the evaluate stage,
:func:`evaluate` (``summary.json`` of a run directory from its files alone)."""

from uwcosim.evaluation.metrics import (
    anees,
    chi2_band,
    mean_over_runs,
    nees,
    nis_consistency,
    position_velocity_indices,
    rmse,
    rmse_combined,
    rmse_per_step,
    run_rmse,
    step_time_stats,
)
from uwcosim.evaluation.summary import evaluate

__all__ = [
    "anees",
    "chi2_band",
    "evaluate",
    "mean_over_runs",
    "nees",
    "nis_consistency",
    "position_velocity_indices",
    "rmse",
    "rmse_combined",
    "rmse_per_step",
    "run_rmse",
    "step_time_stats",
]
