"""The files of a run directory: their names, the JSON records, and preparing ``--out``.

A run directory holds ``log.parquet`` (:mod:`uwcosim.runlog.parquet`), ``simulation.json``
(what the simulate stage measured and how the run ended), ``summary.json`` (the evaluate
stage), ``report.md``/``report.html`` and the figures (the report stage), ``map.bin`` and
``densities.npz``. JSON records are written atomically (:func:`write_json`) and read with a
one-line error (:func:`read_json`).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from uwcosim.core.errors import ScenarioError, UwcosimError

LOG_FILE = "log.parquet"
#: what the simulate stage writes next to the log (status, timing, ...)
SIMULATION_FILE = "simulation.json"
SUMMARY_FILE = "summary.json"
#: the bathymetry coefficients the DepthSounder FMU read (the report stage reads them too)
MAP_FILE = "map.bin"
DENSITIES_FILE = "densities.npz"
#: files a run writes into its directory (``--force`` clears these, and the figures)
RUN_OUTPUTS = (LOG_FILE, LOG_FILE + ".journal", LOG_FILE + ".tail", SIMULATION_FILE,
               SUMMARY_FILE, "report.md", "report.html", MAP_FILE, DENSITIES_FILE)


def write_json(path: Path, data: dict) -> None:
    """Write ``data`` to ``path`` atomically (a reader never sees half a file)."""
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(data, indent=2, sort_keys=True))
        os.replace(tmp, path)
    except OSError:  # a full disk: no half-written .tmp left behind
        tmp.unlink(missing_ok=True)
        raise


def read_json(path: Path) -> dict | None:
    """The JSON object in ``path`` (None when there is no such file)."""
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UwcosimError(f"{path}: not a readable JSON file ({exc})") from None
    if not isinstance(data, dict):
        raise UwcosimError(f"{path}: expected a JSON object")
    return data


def prepare_out_dir(out_dir: Path, force: bool = False) -> None:
    """Refuse a non-empty run directory unless ``force``; with ``force`` remove what a run
    writes there (log, journal, summary, report, figures, map, regress plots) so nothing old
    contradicts the new run. Other files are left alone."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ScenarioError(f"{out_dir}: --out exists and is not a directory")
    if not out_dir.is_dir():
        return
    try:
        entries = list(out_dir.iterdir())
        if entries and not force:
            raise ScenarioError(f"{out_dir}: run directory is not empty ({len(entries)} "
                                f"entries; use --force to replace its run files, or another "
                                f"--out)")
        for p in entries:
            if p.name == "regress" and p.is_dir():
                shutil.rmtree(p)
            elif p.name in RUN_OUTPUTS or (p.suffix == ".png" and p.is_file()):
                p.unlink()
    except OSError as exc:
        raise UwcosimError(f"{out_dir}: cannot prepare the run directory "
                           f"({exc.strerror or exc})") from None
