"""Run one scenario with one seed, in three stages that each leave files in the run directory.

1. :func:`simulate` -- master + estimators + log: ``log.parquet`` (its metadata names the
   scenario, seed, versions, FMU hashes, states, truth and measurement signals, estimators and
   the map file), ``simulation.json`` (status, error, termination, wall times, the estimators'
   time per step and divergence reasons, notes), ``map.bin``, ``densities.npz``;
2. :func:`uwcosim.evaluation.evaluate` -- ``summary.json`` from those files alone;
3. :func:`uwcosim.report.report` -- figures and ``report.md`` from those files alone.

:func:`run_scenario` (behind ``uwcosim run``) is the three in a row. The algorithm (master,
filters) knows nothing of what records it: the estimator bank and the log recorder are hooks on
the master. :func:`simulate` evaluates the run as its last act on every exit path (under the
run's signal guard, so a second Ctrl-C cannot lose the summary): an interrupted, failed or
terminated run still has its ``summary.json``.
"""

from __future__ import annotations

import platform
from collections.abc import Callable
from dataclasses import dataclass
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from uwcosim import __version__
from uwcosim.errors import RunInterrupted, ScenarioError, UwcosimError
from uwcosim.master.master import Master
from uwcosim.master.varmap import noise_free_notes
from uwcosim.models.terrain import Bathymetry, load_map, synthetic_bathymetry
from uwcosim.runguard import run_guard, signal_name
from uwcosim.runlog import RunLogger
from uwcosim.runlog.recorder import LogRecorder, log_columns
from uwcosim.scenario.load import LoadedScenario

if TYPE_CHECKING:
    from uwcosim.estimator_bank import EstimatorBank

PACKAGES = ("uwcosim", "fmpy", "numpy", "scipy", "casadi", "pyarrow")


def package_versions() -> dict[str, str]:
    """Versions of the packages a run depends on (logged in the metadata)."""
    out = {}
    for p in PACKAGES:
        try:
            out[p] = importlib_metadata.version(p)
        except importlib_metadata.PackageNotFoundError:
            out[p] = __version__ if p == "uwcosim" else "not installed"
    out["python"] = platform.python_version()
    return out


def scenario_map(loaded: LoadedScenario) -> Bathymetry | None:
    """The bathymetry of the scenario's ``[map]`` (None without one)."""
    m = loaded.spec.map
    if m is None:
        return None
    if m.kind == "file":
        return load_map(loaded.resolve(m.file), m.variable)
    return synthetic_bathymetry(m.seed, m.extent, m.resolution, relief_std=m.relief_std)


@dataclass
class RunResult:
    """What :func:`run_scenario` returns: the run directory, its summary, log and status."""

    out_dir: Path
    summary: dict
    log_path: Path
    status: str


#: files a run writes into its directory (``--force`` clears these, and the figures)
RUN_OUTPUTS = ("log.parquet", "log.parquet.journal", "simulation.json", "summary.json",
               "report.md", "report.html", "map.bin", "densities.npz")


def prepare_out_dir(out_dir: Path, force: bool = False) -> None:
    """Refuse a non-empty run directory unless ``force``; with ``force`` remove what a run
    writes there (log, journal, summary, report, figures, map, regress plots) so nothing old
    contradicts the new run. Other files are left alone."""
    import shutil

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



def simulation_record(master: Master, bank: EstimatorBank | None, loaded: LoadedScenario,
                      status: str, error: str) -> dict:
    """What the simulate stage measured and how the run ended (``simulation.json``): status,
    error, termination, the time grid reached, wall times of the FMUs and the master, the
    estimators' time per step and divergence reasons, notes."""
    rec = {
        "scenario": master.system.name, "scenario_file": str(loaded.path), "seed": master.seed,
        "status": status, "error": error, "steps": master.k, "step_s": master.h,
        "start_time_s": master.t0, "end_time_s": master.t,
        "timing": {k: round(v, 6) for k, v in master.timing().items()}, "estimators": {},
    }
    solvers = master.me_solvers()
    rec["fmus"] = {
        n.adapter.name: {"interface": n.adapter.interface, "fmi_version": n.adapter.md.fmiVersion,
                         "solver": solvers.get(n.adapter.name),
                         "period_steps": n.period, "time_s": round(n.time_s, 6)}
        for n in master.nodes}
    stop = master.terminated
    if stop is not None:
        rec["termination"] = {"fmu": stop.fmu, "time_s": stop.time, "reason": stop.reason}
        rec["end_time_s"] = max(master.t, stop.time)
    k = max(master.k, 1)
    rec["timing"]["master_overhead_per_step_s"] = master.master_time_s / k
    rec["timing"]["fmus_per_step_s"] = sum(n.time_s for n in master.nodes) / k
    for tr in (bank.tracks if bank is not None else []):
        times = np.asarray(tr.step_times)
        m = {"time_per_step_s": float(np.median(times)) if times.size else float("nan"),
             "time_per_step_p95_s":
                 float(np.percentile(times, 95)) if times.size else float("nan"),
             "total_time_s": float(times.sum())}
        if tr.error:
            m["error"] = tr.error
        rec["estimators"][tr.name] = m
    if master.noise_free:
        spec = loaded.spec
        rec["notes"] = noise_free_notes(master.system, master.noise_free,
                                        spec.model is not None and spec.model.q_psd is not None,
                                        spec.model.control_noise if spec.model else None)
    return rec


def _flush_steps(bank, recorder) -> None:
    """At the end of a run that stopped early (interrupted, failed): filter the steps the bank
    recorded and write their rows (with NaN estimates if filtering them fails too)."""
    if recorder is None:
        return
    if bank is not None:
        try:
            bank.flush()
        except BaseException:  # noqa: BLE001 - the run already failed: keep the truth rows
            bank.outputs.clear()
    recorder.flush()


def _as_loaded(scenario: LoadedScenario | str | Path) -> LoadedScenario:
    if isinstance(scenario, LoadedScenario):
        return scenario
    from uwcosim.scenario import load_scenario

    return load_scenario(scenario)


def simulate(scenario: LoadedScenario | str | Path, out_dir: str | Path | None = None,
             seed: int | None = None, progress: Callable | None = None,
             master: Master | None = None, evaluate: bool = True) -> Path:
    """Run ``scenario`` (loaded, or a file) into ``out_dir`` (created): ``log.parquet``,
    ``simulation.json``, ``map.bin``, ``densities.npz`` (default ``out_dir``:
    ``runs/<scenario file stem>``, as ``uwcosim run``); with ``evaluate`` also
    ``summary.json`` (:func:`uwcosim.evaluation.evaluate`), on every exit path. Returns the run
    directory. Always leaves a readable log.

    ``master``: a :class:`Master` of the same scenario to reuse (reset, its FMU instances kept
    and reset); the caller then owns it and closes it. Otherwise a new one is made and closed.
    ``progress``: a master hook called after each step.

    In the main thread, SIGINT, SIGTERM and SIGHUP stop the run at the next step (status
    ``interrupted``, :class:`RunInterrupted` with exit status 128 + signal), and
    ``run.fmu_timeout_s`` is enforced; an FMU that does not come back is handled by the watcher
    of :mod:`uwcosim.runguard`, which finalizes the log and summary and ends the process.
    A failure is raised (:class:`~uwcosim.errors.UwcosimError`) after the files are written.
    """
    from uwcosim.estimator_bank import EstimatorBank
    from uwcosim.evaluation.summary import SIMULATION_FILE, write_json
    from uwcosim.evaluation.summary import evaluate as evaluate_run
    from uwcosim.models.factory import build_model

    loaded = _as_loaded(scenario)
    out_dir = Path(out_dir) if out_dir is not None else Path("runs") / loaded.path.stem
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        probe = out_dir / ".write-test"
        probe.write_bytes(b"")
        probe.unlink()
        (out_dir / SIMULATION_FILE).unlink(missing_ok=True)  # never a stale one
    except OSError as exc:
        raise UwcosimError(f"{out_dir}: output directory is not writable "
                           f"({exc.strerror or exc})") from None
    spec = loaded.spec
    bathy = scenario_map(loaded)
    overrides: dict[str, dict] = {}
    if bathy is not None and spec.map.fmu_parameter:
        fmu, _, par = spec.map.fmu_parameter.partition(".")
        if fmu in spec.fmus:
            overrides[fmu] = {par: str(bathy.write_coefficients(out_dir / "map.bin"))}
    if bathy is not None and not overrides:  # the report stage reads the map from here
        bathy.write_coefficients(out_dir / "map.bin")
    owner = master is None
    if owner:
        master = Master(loaded, seed=seed)
    else:
        master.reset(seed)
    log_path = out_dir / "log.parquet"
    logger = hook = None
    failure: UwcosimError | None = None
    bank = model = snapshots = None
    completed = False

    def last_time() -> float:
        t = logger.last_time if logger is not None else float("nan")
        return t if np.isfinite(t) else master.t

    def kept(message: str) -> str:
        if logger is None:
            return message
        return f"{message} (log up to t={last_time():g} kept in {log_path})"

    def finish(status: str, error: str) -> None:
        """``simulation.json`` and (with ``evaluate``) ``summary.json``."""
        record = simulation_record(master, bank, loaded, status, error)
        write_json(out_dir / SIMULATION_FILE, record)
        if evaluate:
            try:
                evaluate_run(out_dir)
            except Exception as exc:  # noqa: BLE001 - a summary on every exit path: say why
                note = f"evaluation failed ({type(exc).__name__}: {exc}): no metrics"
                write_json(out_dir / "summary.json", {
                    **record, "estimators": {}, "notes": [*record.get("notes", []), note]})

    def finalize(status: str, message: str, code: int) -> str:
        """The signal watcher's finalization when the main thread is stuck in an FMU call."""
        if status == "interrupted":
            message = f"interrupted at t={last_time():g} by {message.rsplit(' ', 1)[-1]}"
        message = kept(message)
        if logger is not None:
            # the steps the bank has not filtered yet: the main thread is stuck in an FMU
            # call, not in the bank (if it is, their rows are written with NaN estimates)
            if bank is not None and bank.busy:
                hook.flush()
            else:
                _flush_steps(bank, hook)
            logger.close()
        try:
            finish(status, message)
        except Exception:  # noqa: BLE001 - the main thread may be mid-step: the essentials
            essentials = {"scenario": spec.name, "seed": master.seed, "status": status,
                          "error": message, "estimators": {}}
            write_json(out_dir / SIMULATION_FILE, essentials)
            write_json(out_dir / "summary.json", essentials)
        return message

    with run_guard(spec.run.fmu_timeout_s) as guard:
        guard.master, guard.finalize = master, finalize
        try:
            master.initialize(overrides)
            if spec.estimators:
                model = build_model(loaded, bathy)
                bank = EstimatorBank(master, model, str(loaded.path),
                                     bathy.extent if bathy is not None else None,
                                     block=spec.run.filter_block,
                                     sync_times=spec.output.density_snapshots,
                                     row_group=spec.log.chunk_steps)
                master.hooks.append(bank)
            cols, slots, flags = log_columns(master, bank, model)
            meta = {
                "scenario_text": loaded.text, "scenario_sha256": loaded.sha256,
                "scenario_path": loaded.path.name, "overrides": list(loaded.overrides),
                "seed": master.seed, "versions": package_versions(),
                "fmus": master.fmu_hashes(), "step": master.h, "start_time": master.t0,
            }
            if bank is not None:  # what the evaluate and report stages need to read the log
                meta.update(scenario_name=spec.name, truth=list(spec.model.truth),
                            states=list(model.state_names),
                            measurements=list(master.sensors.names),
                            estimators={tr.name: spec.estimators[tr.name].type
                                        for tr in bank.tracks})
            if bathy is not None:
                meta["map"] = "map.bin"
            if master.variable_maps():  # third-party FMUs: roles, variables and conversions
                meta["variable_maps"] = master.variable_maps()
            dtypes = {c: master.signal_dtype(c) for c in cols if c in master.out_vars}
            logger = RunLogger(log_path, cols, flags, meta, spec.log.chunk_steps, dtypes)
            exact = [master.slots[c] for c in logger.exact_columns]
            hook = LogRecorder(master, bank, logger, np.array(slots, dtype=np.intp), model,
                               exact)
            hook(master)
            master.hooks.append(hook)
            if bank is not None and spec.output.density_snapshots:
                from uwcosim.evaluation.metrics import position_velocity_indices
                from uwcosim.plots.density_figures import DensitySnapshots

                pos = position_velocity_indices(model.state_names)[0]
                snapshots = DensitySnapshots(bank, list(spec.output.density_snapshots),
                                             tuple(pos))
                master.hooks.append(snapshots)
            if progress is not None:
                master.hooks.append(progress)
            master.hooks.append(guard.check)  # after the log row of the step
            guard.check()
            master.run_until(master.t0 + master.n_steps * master.h)
            if bank is not None:  # the last block
                bank.flush()
                hook.flush()
            stop = master.terminated
            if stop is not None and stop.time > master.t + 1e-9 * master.h:
                hook.final(master, stop.time)
            completed = True
        except (KeyboardInterrupt, RunInterrupted):
            _flush_steps(bank, hook)  # the message names the last row written
            failure = RunInterrupted(f"interrupted at t={last_time():g}")
        except UwcosimError as exc:
            failure = exc
        finally:
            if not guard.claim():  # the watcher is finalizing and ends the process
                guard.wait_for_exit()
            if logger is not None and failure is not None:
                _flush_steps(bank, hook)
            if guard.signum is not None and failure is not None:
                failure = RunInterrupted(f"interrupted at t={last_time():g} by "
                                         f"{signal_name(guard.signum)}")
                failure.exit_code = guard.exit_code()
            try:
                if logger is not None:
                    _flush_steps(bank, hook)  # (an unexpected error: what was recorded)
                    logger.close()
            finally:
                try:
                    status = "ok" if failure is None else (
                        "interrupted" if isinstance(failure, RunInterrupted) else "failed")
                    error = str(failure or "")
                    if failure is not None:
                        error = kept(error)
                        failure.args = (error,)
                    elif not completed:  # an unexpected error propagates: say so
                        status, error = "failed", kept("internal error (see the traceback)")
                    elif master.terminated is not None:
                        status = "terminated"
                    if snapshots is not None:
                        snapshots.save(out_dir / "densities.npz", list(model.state_names))
                    finish(status, error)
                    guard.finished.set()
                finally:
                    if owner:
                        master.close()
    if failure is not None:
        raise failure
    return out_dir


def run_scenario(scenario: LoadedScenario | str | Path, out_dir: str | Path | None = None,
                 seed: int | None = None, figures: bool | None = None,
                 progress: Callable | None = None, master: Master | None = None) -> RunResult:
    """:func:`simulate`, :func:`~uwcosim.evaluation.evaluate` and (unless ``figures`` is
    false, or ``[output] figures`` when None) :func:`~uwcosim.report.report` of ``scenario``
    into ``out_dir``. A failed or interrupted run raises after its log and summary are written.
    """
    import json

    loaded = _as_loaded(scenario)
    out_dir = simulate(loaded, out_dir, seed=seed, progress=progress, master=master)
    summary = json.loads((out_dir / "summary.json").read_text())
    result = RunResult(out_dir, summary, out_dir / "log.parquet", summary["status"])
    if not (loaded.spec.output.figures if figures is None else figures):
        return result
    from uwcosim.report import report_run

    report_run(out_dir, summary=summary)
    return result
