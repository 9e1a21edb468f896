"""The PCRB of each variant of a campaign, over the campaign's own truth runs.

``uwcosim bound CAMPAIGN.toml [--runs N]``: for every variant (its scenario with its ``set``
overrides) :func:`uwcosim.run.bound.scenario_bound` with the campaign's seed, so the truth runs
of the bound are the campaign's runs ``0..N-1`` (:func:`uwcosim.campaign.spec.run_seed`; the
same seeds as :func:`uwcosim.run.bound.truth_seeds`). Each variant's ``bound.parquet`` and
``bound.json`` go to ``OUT/VARIANT/``.

A campaign spec with ``[evaluation] bound = { runs = N }`` (``N`` default: the campaign's runs)
computes them after its runs into ``CAMPAIGN/bound/VARIANT/`` (:func:`run_bounds`; kept when
they are over the same runs and seed, as with ``--resume``), and its ``report.md`` gains the
section :func:`bound_section`: each variant's PCRB and each estimator's position RMSE over it
(the mean of the runs' RMSEs, and their root mean square, which cannot be below the bound beyond
its Monte Carlo error).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from uwcosim.campaign.spec import LoadedCampaign
from uwcosim.run.bound import BOUND_SUMMARY_FILE, ScenarioBound, scenario_bound, write_bound
from uwcosim.scenario.load import load_scenario

__all__ = ["BOUND_DIR", "bound_section", "campaign_bounds", "run_bounds"]

BOUND_DIR = "bound"


def campaign_bounds(campaign: LoadedCampaign, out: Path, runs: int | None = None,
                    progress: Callable[[str, int], None] | None = None,
                    per_run: bool = False) -> dict[str, ScenarioBound]:
    """The bound of every variant over ``runs`` (default: the spec's) of the campaign's runs,
    written to ``out/VARIANT`` (``per_run``: :func:`~uwcosim.run.bound.scenario_bound`'s)."""
    n = runs if runs is not None else campaign.spec.runs
    out_bounds = {}
    for v in campaign.spec.variants:
        loaded = load_scenario(campaign.resolve(v.scenario), v.set)
        b = scenario_bound(loaded, n, seed=campaign.spec.seed,
                           progress=(lambda i, name=v.name: progress(name, i)) if progress
                           else None, per_run=per_run)
        write_bound(b, out / v.name)
        out_bounds[v.name] = b
    return out_bounds


def run_bounds(campaign: LoadedCampaign, out: Path, runs: int) -> None:
    """``[evaluation] bound`` of the spec (nothing without it): each variant's bound over
    ``bound.runs`` (default ``runs``, the campaign's) into ``out/bound/VARIANT``; a variant whose
    ``bound.json`` is over the same runs and seed is kept."""
    ev = campaign.spec.evaluation
    if ev is None or ev.bound is None:
        return
    n = ev.bound.runs if ev.bound.runs is not None else runs
    for v in campaign.spec.variants:
        old = _read(out / BOUND_DIR / v.name / BOUND_SUMMARY_FILE)
        if old is not None and old.get("runs") == n and old.get("seed") == campaign.spec.seed:
            continue
        loaded = load_scenario(campaign.resolve(v.scenario), v.set)
        write_bound(scenario_bound(loaded, n, seed=campaign.spec.seed), out / BOUND_DIR / v.name)


def _read(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def bound_section(rows: list[dict], campaign_dir: Path) -> str:
    """The report's PCRB section from ``campaign_dir/bound/*/bound.json`` and the runs' rows
    (empty when the campaign has no bound)."""
    bounds = {p.parent.name: b for p in sorted((campaign_dir / BOUND_DIR).glob(
        f"*/{BOUND_SUMMARY_FILE}")) if (b := _read(p)) is not None}
    if not bounds:
        return ""
    lines = ["## The posterior Cramér-Rao bound", "",
             "PCRB on the position RMSE (root mean square over steps 1..K) over the truth runs "
             "of the campaign's seed; each estimator's mean of the runs' position RMSEs and "
             "their root mean square (RMS, which cannot be below the bound beyond its Monte "
             "Carlo error) over it (docs/bound.md).", "",
             "| variant | PCRB (m) | truth runs | estimator | mean / PCRB | RMS / PCRB |",
             "|---|---|---|---|---|---|"]
    for variant, b in bounds.items():
        per: dict[str, list[float]] = {}
        for r in rows:
            if r["variant"] == variant and r["estimator"] and r["status"] == "ok":
                per.setdefault(r["estimator"], []).append(float(r["rmse_position_m"]))
        pb = float(b["position_m"])
        for e, vals in sorted(per.items()):
            v = np.asarray(vals)
            v = v[np.isfinite(v)]
            mean = float(v.mean()) / pb if v.size else float("nan")
            rms = float(np.sqrt(np.mean(v**2))) / pb if v.size else float("nan")
            lines.append(f"| {variant} | {pb:.3f} | {b['runs']} | {e} | {mean:.2f} | "
                         f"{rms:.2f} |")
    return "\n".join(lines) + "\n\n"
