"""The PCRB of each variant of a campaign, over the campaign's own truth runs.

``uwcosim bound CAMPAIGN.toml [--runs N]``: for every variant (its scenario with its ``set``
overrides) :func:`uwcosim.run.bound.scenario_bound` with the campaign's seed, so the truth runs
of the bound are the campaign's runs ``0..N-1`` (:func:`uwcosim.campaign.spec.run_seed`; the
same seeds as :func:`uwcosim.run.bound.truth_seeds`). Each variant's ``bound.parquet`` and
``bound.json`` go to ``OUT/VARIANT/``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from uwcosim.campaign.spec import LoadedCampaign
from uwcosim.run.bound import ScenarioBound, scenario_bound, write_bound
from uwcosim.scenario.load import load_scenario

__all__ = ["campaign_bounds"]


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
