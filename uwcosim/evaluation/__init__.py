"""Evaluation of runs: metrics (:mod:`uwcosim.evaluation.metrics`) and the run summary."""

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

__all__ = [
    "anees",
    "chi2_band",
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
