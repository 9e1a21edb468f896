"""What a run directory holds, read from its files only (no scenario, no FMU, no live object).

``log.parquet`` and its ``uwcosim`` metadata give the signals, the scenario text, seed, package
versions and FMU hashes; runs since the report stage also record the filters' ``states``, the
``truth`` signals, the ``measurements``, the ``estimators`` (name -> type) and the ``map`` file.
Logs of older runs lack these: they are then recovered from the column names
(``est.NAME.var.STATE``) and from ``[model] truth`` of the logged scenario text.
``summary.json`` gives the metrics; when it is missing (a run killed hard), the accuracy
metrics are recomputed from the log and the timing is unknown.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from uwcosim.errors import UwcosimError
from uwcosim.runlog import read_log


@dataclass
class RunFiles:
    """The content of one run directory."""

    run_dir: Path
    cols: dict[str, np.ndarray]
    meta: dict
    summary: dict
    states: list[str]
    truth: list[str]
    estimators: list[str]
    bathymetry: object | None = None
    density_file: Path | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def has_estimates(self) -> bool:
        return bool(self.estimators and self.states and self.truth)


def _model_truth_from_text(meta: dict) -> list[str]:
    """``[model] truth`` of the logged scenario text with the logged overrides applied."""
    from uwcosim.scenario.load import _apply, parse_overrides

    try:
        data = tomllib.loads(meta.get("scenario_text", ""))
        for keys, value in parse_overrides(meta.get("overrides", []), "log"):
            _apply(data, keys, value, "log")
    except (tomllib.TOMLDecodeError, UwcosimError):
        return []
    truth = (data.get("model") or {}).get("truth") or []
    return [str(t) for t in truth]


def _estimators_from_columns(cols: dict) -> tuple[list[str], list[str]]:
    names = [c[4:-4] for c in cols if c.startswith("est.") and c.endswith(".nis")]
    states: list[str] = []
    if names:
        prefix = f"est.{names[0]}.var."
        states = [c[len(prefix):] for c in cols if c.startswith(prefix)]
    return names, states


def _summary_from_log(cols: dict, meta: dict, truth, states, names) -> dict:
    from uwcosim.evaluation.summary import estimator_metrics

    t = cols.get("time", np.zeros(0))
    step = float(meta.get("step", np.diff(t[:2])[0] if t.size > 1 else float("nan")))
    summary = {"scenario": meta.get("scenario_name", Path(meta.get("scenario_path", "?")).stem),
               "seed": meta.get("seed"), "status": "unknown (no summary.json: recomputed from "
               "the log)", "error": "", "steps": max(int(t.size) - 1, 0), "step_s": step,
               "estimators": {}, "timing": {}}
    if t.size >= 2 and truth and states:
        for name in names:
            summary["estimators"][name] = estimator_metrics(cols, name, truth, states)
    return summary


def load_run(run_dir: str | Path) -> RunFiles:
    """Read a run directory (``log.parquet``, ``summary.json``, ``map.bin``, ``densities.npz``)."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise UwcosimError(f"{run_dir}: not a run directory")
    cols, meta = read_log(run_dir / "log.parquet")
    notes = []
    names, states = _estimators_from_columns(cols)
    if "estimators" in meta:
        names = list(meta["estimators"])
    states = list(meta.get("states", states))
    truth = list(meta.get("truth", [])) or _model_truth_from_text(meta)
    if names and "truth" not in meta:
        notes.append("names of states and truth signals recovered from an older log's columns "
                     "and scenario text")
    missing = [c for c in truth if c not in cols]
    if missing:
        notes.append(f"truth signals not in the log: {', '.join(missing)}")
        truth = []
    summary_path = run_dir / "summary.json"
    if summary_path.is_file():
        try:
            summary = json.loads(summary_path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise UwcosimError(f"{summary_path}: not a readable summary ({exc})") from None
    else:
        summary = _summary_from_log(cols, meta, truth, states, names)
        notes.append("no summary.json: metrics recomputed from the log, timing unknown")
    bathy = None
    map_file = run_dir / meta.get("map", "map.bin")
    if map_file.is_file():
        from uwcosim.models.bathymetry import read_coefficients

        bathy = read_coefficients(map_file)
    dens = run_dir / "densities.npz"
    return RunFiles(run_dir, cols, meta, summary, states, truth, names, bathy,
                    dens if dens.is_file() else None, notes)
