"""Campaign spec (TOML): which scenario variants, how many seeded runs, and the run seeds.

Example::

    name = "table1"
    seed = 2021
    runs = 100
    [[variants]]
    name = "without_terrain"
    scenario = "../scenarios/tan_dead_reckoning.toml"
    set = ["estimators.ekf.type=\\"ekf\\""]

Run ``i`` of every variant takes the seed :func:`run_seed` ``(campaign seed, i)``: the variants
of one run share their truth (common random numbers), and the results do not depend on how many
workers ran them.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from uwcosim.core.errors import ScenarioError
from uwcosim.core.memory import memory_problem
from uwcosim.core.tomlfile import read_toml
from uwcosim.scenario.load import load_scenario
from uwcosim.scenario.validate import format_validation_error


class Variant(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    name: str = Field(pattern=r"^[A-Za-z0-9_.-]+$")
    scenario: str
    set: list[str] = []


class CampaignBound(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    #: truth runs of the bound (default: the campaign's runs, the same seeds)
    runs: int | None = Field(default=None, ge=1)


class CampaignEvaluation(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)
    #: the PCRB of each variant over the campaign's truth runs (uwcosim.campaign.bound)
    bound: CampaignBound | None = None


class CampaignSpec(BaseModel):
    """Strict types, as scenarios: ``seed = "1"`` is refused."""

    model_config = ConfigDict(extra="forbid", strict=True)
    name: str = "campaign"
    description: str = ""
    seed: int = 0
    runs: int = Field(default=10, ge=1)
    variants: list[Variant] = Field(min_length=1)
    keep_logs: bool = False
    evaluation: CampaignEvaluation | None = None


#: what one run costs the campaign process before and after it runs (its Task: 0.7 kB
#: measured; its future in the pool, its record and table rows read back)
RUN_BYTES = 4096.0


@dataclass(frozen=True)
class Task:
    """One co-simulation run of a campaign (picklable: sent to worker processes)."""

    variant: str
    scenario: str  # absolute path
    overrides: tuple[str, ...]
    run: int
    seed: int
    log_dir: str | None  # where to keep the run directory, or None
    fail_dir: str | None = None  # where a failed run's directory is kept (when not log_dir)

    @property
    def key(self) -> str:
        return f"{self.variant}__{self.run:05d}"


def run_seed(campaign_seed: int, run: int) -> int:
    """Seed of run ``run``: a SeedSequence of (campaign seed, run), as a 32-bit integer."""
    return int(np.random.SeedSequence([int(campaign_seed) & 0xFFFFFFFF, run]).generate_state(1)[0])


@dataclass(frozen=True)
class LoadedCampaign:
    spec: CampaignSpec
    path: Path
    #: sha256 of each variant's scenario with its overrides (as in its run logs)
    scenario_hashes: dict[str, str] = field(default_factory=dict)

    def fingerprint(self) -> dict:
        """What the results depend on: the campaign seed and each variant's scenario (file,
        overrides, content hash). Not ``runs`` (more runs extend a campaign), not the labels."""
        return {"seed": self.spec.seed, "variants": {
            v.name: {"scenario": str(self.resolve(v.scenario)), "set": list(v.set),
                     "scenario_sha256": self.scenario_hashes.get(v.name, "")}
            for v in self.spec.variants}}

    @property
    def sha256(self) -> str:
        return hashlib.sha256(json.dumps(self.fingerprint(), sort_keys=True).encode()
                              ).hexdigest()

    def resolve(self, rel: str) -> Path:
        p = Path(rel)
        return p if p.is_absolute() else (self.path.parent / p).resolve()

    def tasks(self, runs: int | None, out: Path) -> list[Task]:
        n = runs if runs is not None else self.spec.runs
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ScenarioError(f"--runs {n}: expected a positive number of runs per variant")
        k = len(self.spec.variants)
        what = f"--runs {n}" if runs is not None else f"{self.path}: key 'runs' = {n}"
        why = memory_problem(float(n) * k * RUN_BYTES, f"{what} ({n * k} runs of {k} "
                             f"variant{'s' * (k > 1)}: their tasks, futures and records)",
                             "run fewer at a time (--runs, then --resume with more)")
        if why:
            raise ScenarioError(why)
        out_logs = out / "logs"
        return [
            Task(v.name, str(self.resolve(v.scenario)), tuple(v.set), i,
                 run_seed(self.spec.seed, i),
                 str(out_logs / v.name / f"run_{i:05d}") if self.spec.keep_logs else None,
                 str(out / "failed" / v.name / f"run_{i:05d}"))
            for i in range(n) for v in self.spec.variants
        ]


def load_campaign(path: str | Path) -> LoadedCampaign:
    """Read and validate a campaign spec; every variant's scenario is validated too."""
    path = Path(path)
    where = str(path)
    _, data = read_toml(path, "campaign", where)
    try:
        spec = CampaignSpec.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(format_validation_error(exc, where, CampaignSpec)) from None
    names = [v.name for v in spec.variants]
    if len(set(names)) != len(names):
        raise ScenarioError(f"{where}: key 'variants': variant names must be unique ({names})")
    loaded = LoadedCampaign(spec, path.resolve())
    for i, v in enumerate(spec.variants):
        scen = loaded.resolve(v.scenario)
        if not scen.is_file():
            raise ScenarioError(f"{where}: key 'variants[{i}].scenario': file not found: {scen}")
        loaded.scenario_hashes[v.name] = load_scenario(scen, v.set).sha256
    return loaded
