"""What a run directory holds, read from its files only (no scenario, no FMU, no live object).

``log.parquet`` and its ``uwcosim`` metadata give the signals, the scenario text, seed, package
versions and FMU hashes; runs since the report stage also record the filters' ``states``, the
``truth`` signals, the ``measurements``, the ``estimators`` (name -> type) and the ``map`` file.
Logs of older runs lack these: they are then recovered from the column names
(``est.NAME.var.STATE``) and from ``[model] truth`` of the logged scenario text
(:func:`uwcosim.evaluation.summary.log_names`). ``summary.json`` gives the metrics (``uwcosim
report`` rebuilds it first with :func:`uwcosim.evaluation.evaluate`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from uwcosim.core.errors import UwcosimError
from uwcosim.evaluation.summary import evaluate, log_names
from uwcosim.models.terrain import read_coefficients
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


def load_run(run_dir: str | Path, summary: dict | None = None) -> RunFiles:
    """Read a run directory (``log.parquet``, ``summary.json``, ``map.bin``, ``densities.npz``).

    ``summary``: the run's summary when the caller has it; otherwise ``summary.json``, or, when
    there is none, :func:`~uwcosim.evaluation.evaluate` in memory."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise UwcosimError(f"{run_dir}: not a run directory")
    cols, meta = read_log(run_dir / "log.parquet")
    names, states, truth, notes = log_names(cols, meta)
    if not names:
        notes = []
    summary_path = run_dir / "summary.json"
    if summary is not None:
        pass
    elif summary_path.is_file():
        try:
            summary = json.loads(summary_path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise UwcosimError(f"{summary_path}: not a readable summary ({exc})") from None
    else:
        summary = evaluate(run_dir, write=False)
        notes.append("no summary.json: evaluated from the run directory's files")
    bathy = None
    map_file = run_dir / meta.get("map", "map.bin")
    if map_file.is_file():
        bathy = read_coefficients(map_file)
    dens = run_dir / "densities.npz"
    return RunFiles(run_dir, cols, meta, summary, states, truth, names, bathy,
                    dens if dens.is_file() else None, notes)
