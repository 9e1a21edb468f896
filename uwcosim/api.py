"""The public facade: the functions ``import uwcosim`` offers that span the layers.

:func:`run_scenario` is the run layer's (:func:`uwcosim.run.simulate.run_scenario`) with the
report stage of :mod:`uwcosim.reports`; :func:`report` reports a run directory or a campaign
directory, whichever the folder holds. ``uwcosim run`` and ``uwcosim report`` call these.
"""

from __future__ import annotations

from pathlib import Path

from uwcosim.campaign.report import report_campaign
from uwcosim.core.errors import UwcosimError
from uwcosim.evaluation.summary import evaluate
from uwcosim.master.master import Master
from uwcosim.master.observer import Observer
from uwcosim.reports.run_report import report_run
from uwcosim.run import simulate as _simulate
from uwcosim.run.simulate import RunResult
from uwcosim.runlog.rundir import LOG_FILE
from uwcosim.scenario.loaded import LoadedScenario

__all__ = ["report", "run_scenario"]


def run_scenario(scenario: LoadedScenario | str | Path, out_dir: str | Path | None = None,
                 seed: int | None = None, figures: bool | None = None,
                 progress: Observer | None = None, master: Master | None = None,
                 contained: bool = False) -> RunResult:
    """:func:`~uwcosim.run.simulate.simulate`, :func:`~uwcosim.evaluation.evaluate` and
    (unless ``figures`` is false, or ``[output] figures`` when None)
    :func:`~uwcosim.reports.run_report.report_run` of ``scenario`` into ``out_dir`` (default
    ``runs/<scenario file stem>``). A failed or interrupted run raises after its log and
    summary are written.

    ``contained=True``: the run in a supervised child process, as ``uwcosim run`` does
    (:mod:`uwcosim.run.contained`), so that an FMU that ends its process (a crash, ``exit``)
    or the watchdog of ``run.fmu_timeout_s`` ends the child, not the caller: that run raises
    :class:`~uwcosim.core.errors.FMUError` with the line ``uwcosim run`` prints, its log kept.
    ``progress`` and ``master`` are then used in the child."""
    return _simulate.run_scenario(scenario, out_dir, seed=seed, figures=figures,
                                  progress=progress, master=master, report=report_run,
                                  contained=contained)


def report(path: str | Path, out: str | Path | None = None, html: bool = False) -> Path:
    """Report of a run directory (``log.parquet``) or a campaign directory (``results/``).

    A run's ``summary.json`` is rebuilt first (:func:`uwcosim.evaluation.evaluate`, into
    ``out`` when given), so any run -- interrupted, or made by an older version -- gets its
    summary, figures and report from its files alone. Returns the report's path."""
    path = Path(path)
    if (path / LOG_FILE).is_file():
        return report_run(path, out, html, summary=evaluate(path, out))
    if (path / "results").is_dir():
        return report_campaign(path, out, html)
    raise UwcosimError(f"{path}: neither a run directory (no log.parquet) nor a campaign "
                       f"directory (no results/)")
