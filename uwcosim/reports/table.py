"""The result table of a run (``report.md``, ``uwcosim run``'s output): Markdown, one row per
estimator, from its ``summary.json``."""

from __future__ import annotations


def results_table(summary: dict) -> str:
    """The Markdown table of the estimators of ``summary``."""
    head = ("| estimator | pos. RMSE (m) | x RMSE (m) | y RMSE (m) | vel. RMSE (m/s) | ANEES "
            "| time/step (ms) | diverged |\n|---|---|---|---|---|---|---|---|\n")
    rows = []
    for name, m in summary["estimators"].items():
        rows.append(
            f"| {name} | {m['rmse_position_m']:.2f} | {m['rmse_x_m']:.2f} | {m['rmse_y_m']:.2f} "
            f"| {m.get('rmse_velocity_mps', float('nan')):.4f} | {m['anees']:.2f} "
            f"| {1e3 * m.get('time_per_step_s', float('nan')):.3f} "
            f"| {'yes' if m['diverged'] else 'no'} |"
        )
    return head + "\n".join(rows) + "\n"
