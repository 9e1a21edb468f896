"""Run one scenario with one seed, in three stages that each leave files in the run directory.

The steps come from the master (a co-simulation of the scenario's FMUs) or, for a scenario
with ``[replay]``, from the rows of a recorded file (:class:`uwcosim.run.replay.ReplaySource`,
which plays the master's role for the same observers); the stages are the same.

1. :func:`simulate` -- master + estimators + log: ``log.parquet`` (its metadata names the
   scenario, seed, versions, FMU hashes, states, truth and measurement signals, estimators and
   the map file), ``simulation.json`` (status, error, termination, wall times, the estimators'
   time per step and divergence reasons, notes), ``map.bin``, ``densities.npz``;
2. :func:`uwcosim.evaluation.evaluate` -- ``summary.json`` from those files alone;
3. :func:`uwcosim.reports.report` -- figures and ``report.md`` from those files alone.

:func:`run_scenario` (behind ``uwcosim run``) is the three in a row.

This is where a run is composed. The algorithm (master, filters) knows nothing of what records
it: :func:`simulate` converts the scenario into the master's
:class:`~uwcosim.master.system.System`, builds the filters' model, and adds the observers of
the master's steps in this order (:meth:`uwcosim.master.master.Master.notify` calls them in it,
at ``k = 0`` and after every step ``k``):

1. the estimator bank (:mod:`uwcosim.run.bank`): records step ``k`` and, at the end of a block,
   filters it and hands each step's estimates to the recorder, by step index;
2. the log recorder (:mod:`uwcosim.run.recorder`): row ``k`` of the log, written once its
   estimates have come;
3. the density snapshots (:mod:`uwcosim.run.density`): at their steps, where the bank has just
   ended a block;
4. the caller's progress observer, if any;
5. the signal guard (:mod:`uwcosim.core.runguard`): a stop request ends the run after the
   step's row was recorded.

:func:`simulate` evaluates the run as its last act on every exit path (under the run's signal
guard, so a second Ctrl-C cannot lose the summary): an interrupted, failed or terminated run
still has its ``summary.json``.
"""

from __future__ import annotations

import functools
import json
import platform
from dataclasses import dataclass
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import Protocol

import numpy as np

from uwcosim.core.errors import OutputError, RunInterrupted, UwcosimError
from uwcosim.core.jit import ENABLED as JIT_ENABLED
from uwcosim.core.numwarn import NumericalWarnings
from uwcosim.core.runguard import run_guard, signal_name
from uwcosim.core.version import __version__
from uwcosim.evaluation.summary import evaluate as evaluate_run
from uwcosim.master.master import Master
from uwcosim.master.observer import Observer
from uwcosim.master.system import System
from uwcosim.models.states import position_velocity_indices
from uwcosim.run.bank import EstimatorBank, plans
from uwcosim.run.bound import bound_runs, scenario_bound
from uwcosim.run.contained import run_contained
from uwcosim.run.density import DensitySnapshots
from uwcosim.run.divergence import DivergenceCheck, default_bound
from uwcosim.run.factory import build_model, scenario_map
from uwcosim.run.geocolumns import GeoColumns
from uwcosim.run.preflight import map_parameter_problem
from uwcosim.run.provenance import user_code
from uwcosim.run.recorder import LogRecorder, logged_signals, pattern_problems
from uwcosim.run.replay import ReplaySource, replay_source
from uwcosim.run.truth_map import TRUTH_MAP_FILE, scenario_truth_map
from uwcosim.runlog import RunLogger
from uwcosim.runlog.columns import LogLayout
from uwcosim.runlog.rundir import (
    LOG_FILE,
    MAP_FILE,
    SIMULATION_FILE,
    SUMMARY_FILE,
    prepare_out_dir,
    write_json,
)
from uwcosim.runlog.units import layout_units
from uwcosim.scenario.geo import scenario_frame
from uwcosim.scenario.load import load_scenario
from uwcosim.scenario.loaded import LoadedScenario
from uwcosim.scenario.system import to_system

__all__ = ["RunResult", "estimator_records", "package_versions", "prepare_out_dir",
           "run_scenario", "simulate", "simulation_record"]

PACKAGES = ("uwcosim", "fmpy", "numpy", "scipy", "casadi", "pyarrow")


def package_versions() -> dict[str, str]:
    """Versions of the packages a run depends on (logged in the metadata)."""
    return dict(_versions())


@functools.cache
def _versions() -> dict[str, str]:
    # read once per process (importlib.metadata parses every package's METADATA: 8 ms)
    out = {}
    for p in PACKAGES:
        try:
            out[p] = importlib_metadata.version(p)
        except importlib_metadata.PackageNotFoundError:
            out[p] = __version__ if p == "uwcosim" else "not installed"
    out["python"] = platform.python_version()
    return out


class ReportStage(Protocol):
    """The report stage :func:`run_scenario` calls after the run (figures, ``report.md``):
    :func:`uwcosim.reports.report_run`, passed by the layers above."""

    def __call__(self, out_dir: Path, *, summary: dict) -> object: ...


@dataclass
class RunResult:
    """What :func:`run_scenario` returns: the run directory, its summary, log and status."""

    out_dir: Path
    summary: dict
    log_path: Path
    status: str


def simulation_record(master: Master | ReplaySource, bank: EstimatorBank | None,
                      loaded: LoadedScenario, status: str, error: str) -> dict:
    """What the simulate stage measured and how the run ended (``simulation.json``): status,
    error, termination, the time grid reached, wall times of the FMUs and the master, the
    estimators' time per step and divergence reasons, notes."""
    if isinstance(master, ReplaySource):
        rec = master.record(status, error)
        rec["scenario_file"] = str(loaded.path)
        rec["estimators"] = estimator_records(bank)
        if master.recording.notes:
            rec["notes"] = list(master.recording.notes)
        return rec
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
    rec["estimators"] = estimator_records(bank)
    if master.noise_free:
        spec = loaded.spec
        rec["notes"] = noise_free_notes(master.system, master.noise_free,
                                        spec.model is not None and spec.model.q_psd is not None,
                                        spec.model.control_noise if spec.model else None)
    return rec


def estimator_records(bank: EstimatorBank | None) -> dict[str, dict]:
    """Each estimator's time per step (median, 95th percentile, total) and divergence reason."""
    out = {}
    for tr in (bank.tracks if bank is not None else []):
        times = np.asarray(tr.step_times)
        m = {"time_per_step_s": float(np.median(times)) if times.size else float("nan"),
             "time_per_step_p95_s":
                 float(np.percentile(times, 95)) if times.size else float("nan"),
             "total_time_s": float(times.sum())}
        if tr.error:
            m["error"] = tr.error
        if tr.stopped_step is not None:
            m["stopped_step"] = tr.stopped_step
        out[tr.name] = m
    return out


def noise_free_notes(system: System, noise_free: dict[str, str], q_psd_given: bool,
                     control_noise: str | None = None) -> list[str]:
    """One line per noise source the truth ran without (see :func:`noise_free_sources`);
    ``control_noise``: the source the filters' model takes as control noise."""
    q = "model.q_psd" if q_psd_given else "model.q_psd, which defaults to these PSDs"
    cn = "the filters' model still adds it as control noise (model.control_noise)"
    return [f"the truth ran noise-free: FMU {fmu!r} has no inputs "
            f"{', '.join(t.partition('.')[2] for t in system.noise[n].targets)} for "
            f"noise {n!r}; " + (cn if n == control_noise else f"the filters' process noise is {q}")
            for n, fmu in noise_free.items()]


def _flush_steps(bank, recorder) -> None:
    """At the end of a run that stopped early (interrupted, failed): filter the steps the bank
    recorded and write their rows (with NaN estimates if filtering them fails too)."""
    if recorder is None:
        return
    if bank is not None:
        try:
            bank.flush()
        except BaseException:  # noqa: BLE001 - the run already failed: keep the truth rows
            bank.discard()
    recorder.flush()


def as_loaded(scenario: LoadedScenario | str | Path) -> LoadedScenario:
    """``scenario`` as loaded (a file's path is loaded with no override)."""
    if isinstance(scenario, LoadedScenario):
        return scenario
    return load_scenario(scenario)


def out_dir_of(loaded: LoadedScenario, out_dir: str | Path | None = None) -> Path:
    """The run directory of a run of ``loaded``: ``out_dir``, or if it is not given
    ``runs/<scenario file stem>``, as ``uwcosim run``."""
    return Path(out_dir) if out_dir else Path("runs") / loaded.path.stem


def _density_steps(master: Master, times: list[float]) -> set[int]:
    """The steps of the density snapshots: each time's first step at or after it."""
    return {master.step_at(t) for t in times}


def _add_estimation(master: Master, loaded: LoadedScenario, bathy, model) -> EstimatorBank:
    """The estimator bank of a scenario, wired to the master's truth, controls and sensors."""
    spec = loaded.spec
    est_common = spec.estimation
    bound = est_common.position_bound if est_common is not None else None
    if bound is None and bathy is not None:
        bound = default_bound(bathy.extent)
    pos = position_velocity_indices(model.state_names)[0]
    check = DivergenceCheck(tuple(pos), tuple(bound) if bound is not None else None)
    truth = [master.slot(s, "model.truth") for s in spec.model.truth]
    controls = [master.slots[f"controls.{c}"] for c in spec.model.controls]
    return EstimatorBank(
        model, plans(spec.estimators, spec.model.sensors, master.sensors.sensor_of),
        truth_slots=truth, control_slots=controls, seed=master.seed, where=str(loaded.path),
        check=check, estimation=est_common, block=spec.run.filter_block,
        sync_steps=_density_steps(master, spec.output.density_snapshots),
        row_group=spec.log.chunk_steps)


def simulate(scenario: LoadedScenario | str | Path, out_dir: str | Path | None = None,
             seed: int | None = None, progress: Observer | None = None,
             master: Master | None = None, evaluate: bool = True,
             contained: bool = False) -> Path:
    """Run ``scenario`` (loaded, or a file) into ``out_dir`` (created): ``log.parquet``,
    ``simulation.json``, ``map.bin``, ``densities.npz`` (default ``out_dir``:
    ``runs/<scenario file stem>``, as ``uwcosim run``); with ``evaluate`` also
    ``summary.json`` (:func:`uwcosim.evaluation.evaluate`), on every exit path. Returns the run
    directory. Always leaves a readable log.

    ``master``: a :class:`Master` of the same scenario's system to reuse (reset, its FMU
    instances kept and reset); the caller then owns it and closes it. Otherwise a new one is
    made and closed. ``progress``: an observer of the master (``on_step(k, view)``) called
    after the log row of each step.

    In the main thread, SIGINT, SIGTERM and SIGHUP stop the run at the next step (status
    ``interrupted``, :class:`RunInterrupted` with exit status 128 + signal), and
    ``run.fmu_timeout_s`` is enforced; an FMU that does not come back is handled by the watcher
    of :mod:`uwcosim.core.runguard`, which finalizes the log and summary and ends the process.
    A failure is raised (:class:`~uwcosim.core.errors.UwcosimError`) after the files are
    written.

    ``contained=True``: the run in a supervised child process, as ``uwcosim run`` does
    (:mod:`uwcosim.run.contained`): an FMU that ends its process (a crash, ``exit``) or the
    watchdog of ``run.fmu_timeout_s`` ends the child, not the caller, which gets
    :class:`~uwcosim.core.errors.FMUError` with the line ``uwcosim run`` prints, the log kept;
    ``progress`` and ``master`` are then used in the child.
    """
    loaded = as_loaded(scenario)
    out_dir = out_dir_of(loaded, out_dir)
    if contained:
        run_contained(functools.partial(simulate, loaded, out_dir, seed=seed, progress=progress,
                                        master=master, evaluate=evaluate), out_dir)
        return out_dir
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        probe = out_dir / ".write-test"
        probe.write_bytes(b"")
        probe.unlink()
        (out_dir / SIMULATION_FILE).unlink(missing_ok=True)  # never a stale one
    except OSError as exc:
        raise OutputError(f"{out_dir}: output directory is not writable "
                          f"({exc.strerror or exc})") from None
    spec = loaded.spec
    bathy = scenario_map(loaded)
    overrides: dict[str, dict] = {}
    # [map.truth]: the truth's sounder reads its own seafloor (run.truth_map)
    truth_map = scenario_truth_map(loaded, bathy, spec.run.seed if seed is None else seed) \
        if bathy is not None else None
    try:
        if bathy is not None and spec.map.fmu_parameter:
            fmu, _, par = spec.map.fmu_parameter.partition(".")
            if fmu in spec.fmus:
                truth_file = bathy.write_coefficients(out_dir / MAP_FILE) if truth_map is None \
                    else truth_map.write_coefficients(out_dir / TRUTH_MAP_FILE)
                overrides[fmu] = {par: str(truth_file)}
        if bathy is not None and (not overrides or truth_map is not None):  # the report's map
            bathy.write_coefficients(out_dir / MAP_FILE)
    except OSError as exc:  # a full disk before the run starts: no half map, a summary
        (out_dir / MAP_FILE).unlink(missing_ok=True)
        (out_dir / TRUTH_MAP_FILE).unlink(missing_ok=True)
        raise failed_output(out_dir, exc, "the map file; the run did not start") from None
    owner = master is None
    model = None
    if spec.replay is not None:  # the steps are the rows of a recorded file
        if not owner:
            raise UwcosimError(f"{loaded.path}: a replay scenario takes no master")
        model = build_model(loaded, bathy)
        master = replay_source(loaded, seed, tuple(model.measurement_names))
    elif owner:
        master = Master(to_system(loaded), seed=seed)
    else:
        master.reset(seed)
    pcrb = None
    if spec.estimators and bound_runs(loaded) is not None:  # truth runs of their own master
        try:
            pcrb = scenario_bound(loaded, bound_runs(loaded), seed=master.seed,
                                  work_dir=out_dir)
        except BaseException:
            if owner:
                master.close()
            raise
    problems = pattern_problems(master, spec.log.signals, str(loaded.path))
    if isinstance(master, Master) and overrides:  # the map file's parameter: its key named
        problem = map_parameter_problem(loaded, master)
        problems += [problem] if problem is not None else []
    if problems:  # a bad [log] signals pattern: a scenario error before anything runs
        if owner:
            master.close()
        if len(problems) > 1:
            problems[0].args = (f"{problems[0]} (and {len(problems) - 1} more; see uwcosim "
                                f"check)",)
        raise problems[0]
    log_path = out_dir / LOG_FILE
    logger = recorder = None
    failure: UwcosimError | None = None
    bank = snapshots = None
    completed = False

    def last_time() -> float:
        t = logger.last_time if logger is not None else float("nan")
        return t if np.isfinite(t) else master.t

    def kept(message: str) -> str:
        if logger is None or not np.isfinite(logger.last_time):  # no row written yet
            return message
        return f"{message} (log up to t={last_time():g} kept in {log_path})"

    numerics = NumericalWarnings()  # numpy's RuntimeWarnings: one line each, recorded

    def finish(status: str, error: str) -> None:
        """``simulation.json`` and (with ``evaluate``) ``summary.json``."""
        record = simulation_record(master, bank, loaded, status, error)
        if numerics.entries():
            record["warnings"] = numerics.entries()
        write_json(out_dir / SIMULATION_FILE, record)
        if evaluate:
            try:
                evaluate_run(out_dir)
            except Exception as exc:  # noqa: BLE001 - a summary on every exit path: say why
                note = f"evaluation failed ({type(exc).__name__}: {exc}): no metrics"
                write_json(out_dir / SUMMARY_FILE, {
                    **record, "estimators": {}, "notes": [*record.get("notes", []), note]})

    def finalize(status: str, message: str, code: int) -> str:
        """The signal watcher's finalization when the main thread is stuck in an FMU call."""
        if logger is not None:
            # the steps the bank has not filtered yet: the main thread is stuck in an FMU
            # call, not in the bank (if it is, their rows are written with NaN estimates);
            # first, so that the message names the log's last row
            if bank is not None and bank.busy:
                recorder.flush()
            else:
                _flush_steps(bank, recorder)
        if status == "interrupted":
            message = f"interrupted at t={last_time():g} by {message.rsplit(' ', 1)[-1]}"
        message = kept(message)
        if logger is not None:
            logger.close()
        try:
            finish(status, message)
        except Exception:  # noqa: BLE001 - the main thread may be mid-step: the essentials
            essentials = {"scenario": spec.name, "seed": master.seed, "status": status,
                          "error": message, "estimators": {}}
            write_json(out_dir / SIMULATION_FILE, essentials)
            write_json(out_dir / SUMMARY_FILE, essentials)
        return message

    with run_guard(spec.run.fmu_timeout_s) as guard, numerics:
        guard.master, guard.finalize = master, finalize
        try:
            truth: list[str] = []
            if spec.estimators:
                model = model if model is not None else build_model(loaded, bathy)
                bank = _add_estimation(master, loaded, bathy, model)
                truth = list(spec.model.truth)
            signals = logged_signals(master.slots, spec.log.signals, truth, master.shapes)
            frame = scenario_frame(loaded) if bank is not None else None
            geo = frame is not None and \
                len(position_velocity_indices(model.state_names)[0]) == 2
            layout = LogLayout(
                tuple(signals),
                tuple(master.sensors.names) if bank is not None else (),
                tuple(p.name for p in bank.plans) if bank is not None else (),
                tuple(model.state_names) if bank is not None else (), geo=geo,
                bound=pcrb is not None)
            meta = {
                "scenario_text": loaded.text, "scenario_sha256": loaded.sha256,
                "scenario_path": loaded.path.name, "overrides": list(loaded.overrides),
                "seed": master.seed, "versions": package_versions(),
                "fmus": master.fmu_hashes(), "step": master.h, "start_time": master.t0,
            }
            if bank is not None:  # what the evaluate and report stages need to read the log
                meta.update(scenario_name=spec.name, truth=truth,
                            states=list(model.state_names),
                            measurements=list(master.sensors.names),
                            estimators={p.name: p.type for p in bank.plans})
                code = user_code(spec)
                if code:  # a user's filters and model: where they came from (run.provenance)
                    meta["user_code"] = code
            if pcrb is not None:
                meta["bound"] = pcrb.summary()
            if bathy is not None:
                meta["map"] = MAP_FILE
            if not JIT_ENABLED:  # the numpy forms of the kernels: other last bits than numba's
                meta["kernels"] = "numpy"
            if truth_map is not None:  # only then: earlier logs' metadata unchanged
                meta["map_truth"] = TRUTH_MAP_FILE
            if master.variable_maps():  # third-party FMUs: roles, variables and conversions
                meta["variable_maps"] = master.variable_maps()
            if isinstance(master, ReplaySource):
                meta["replay"] = master.recording.metadata()
            if geo:
                meta["geo"] = {**frame.metadata(),
                               "trajectory_axes": spec.output.trajectory_axes}
            slots = {c: master.slot(c, "log.signals") for c in signals}
            dtypes = {c: master.signal_dtype(c) for c in signals}
            # field metadata "unit" (a replay's recording declares none)
            units = layout_units(layout, getattr(master, "signal_unit", lambda _: None), truth)
            logger = RunLogger(log_path, layout.columns, layout.flags, meta,
                               spec.log.chunk_steps, dtypes, units,
                               pending=spec.run.filter_block)
            recorder = LogRecorder(
                layout, logger, [slots[c] for c in signals],
                [slots[c] for c in logger.exact_columns], master.exact,
                ["string" if dtypes[c] == np.dtype(object) else "int"
                 for c in logger.exact_columns],
                derive=GeoColumns(layout, frame, truth) if geo else None,
                bound=pcrb.std if pcrb is not None else None)
            # the observers, in the order the master calls them (module docstring)
            if bank is not None:
                bank.sink = recorder.estimates
                master.observers.append(bank)
            master.observers.append(recorder)
            if bank is not None and spec.output.density_snapshots:
                pos = position_velocity_indices(model.state_names)[0]
                snapshots = DensitySnapshots(
                    bank.live, _density_steps(master, spec.output.density_snapshots),
                    [bank.truth_slots[i] for i in pos], tuple(pos))
                master.observers.append(snapshots)
            if progress is not None:
                master.observers.append(progress)
            master.observers.append(guard)  # after the log row of the step
            guard.check()
            master.initialize(overrides)
            if isinstance(master, ReplaySource):
                master.run_until()  # every row
            else:
                master.run_until(master.t0 + master.n_steps * master.h)
            if bank is not None:  # the last block
                bank.flush()
                recorder.flush()
            stop = master.terminated
            if stop is not None and master.stopped_between_steps():
                recorder.final(master.view(), stop.time)
            completed = True
        except (KeyboardInterrupt, RunInterrupted):
            _flush_steps(bank, recorder)  # the message names the last row written
            failure = RunInterrupted(f"interrupted at t={last_time():g}")
        except UwcosimError as exc:
            failure = exc
        except OSError as exc:  # the log cannot be written (a full disk): one line
            failure = output_error(out_dir, exc, "the log")
        finally:
            if not guard.claim():  # the watcher is finalizing and ends the process
                guard.wait_for_exit()
            if logger is not None and failure is not None:
                _flush_steps(bank, recorder)
                stop = master.terminated
                if stop is not None and master.stopped_between_steps():
                    # stop_on_terminate = "error": the same last row as "stop" writes
                    recorder.final(master.view(), stop.time)
            if guard.signum is not None and failure is not None:
                failure = RunInterrupted(f"interrupted at t={last_time():g} by "
                                         f"{signal_name(guard.signum)}")
                failure.exit_code = guard.exit_code()
            try:
                if logger is not None:
                    _flush_steps(bank, recorder)  # (an unexpected error: what was recorded)
                    logger.close()
            except OSError as exc:  # the last rows cannot be written: not ok
                failure = failure or output_error(out_dir, exc, "the log")
            finally:
                try:
                    status = "ok" if failure is None else (
                        "interrupted" if isinstance(failure, RunInterrupted) else "failed")
                    error = str(failure or "")
                    if failure is not None:
                        # a log that could not be written is not "kept"
                        error = error if isinstance(failure, OutputError) else kept(error)
                        failure.args = (error,)
                    elif not completed:  # an unexpected error propagates: say so
                        status, error = "failed", kept("internal error (see the traceback)")
                    elif master.terminated is not None:
                        status = "terminated"
                    try:
                        if snapshots is not None:
                            try:
                                snapshots.save(out_dir / "densities.npz",
                                               list(model.state_names))
                            except OSError:  # no half-written snapshots
                                (out_dir / "densities.npz").unlink(missing_ok=True)
                                raise
                        finish(status, error)
                    except OSError as exc:  # a full disk: say failed if a summary fits
                        failure = failure or output_error(out_dir, exc, "the run's records")
                        failed_output(out_dir, exc, "the run's records", failure)
                    guard.finished.set()
                finally:
                    if owner:
                        master.close()
    if failure is not None:
        raise failure
    return out_dir


def run_scenario(scenario: LoadedScenario | str | Path, out_dir: str | Path | None = None,
                 seed: int | None = None, figures: bool | None = None,
                 progress: Observer | None = None, master: Master | None = None,
                 report: ReportStage | None = None, contained: bool = False) -> RunResult:
    """:func:`simulate` and :func:`~uwcosim.evaluation.evaluate` of ``scenario`` into
    ``out_dir``, then (unless ``figures`` is false, or ``[output] figures`` when None) the
    report stage ``report(out_dir, summary=...)`` (the caller's: the run layer draws no
    figure; :func:`uwcosim.api.run_scenario` passes :func:`uwcosim.reports.report_run`).
    A failed or interrupted run raises after its log and summary are written.
    ``contained``: as :func:`simulate`'s, the report stage too in the child.
    """
    loaded = as_loaded(scenario)
    if contained:
        out_dir = out_dir_of(loaded, out_dir)
        run_contained(functools.partial(run_scenario, loaded, out_dir, seed=seed,
                                        figures=figures, progress=progress, master=master,
                                        report=report), out_dir)
        return read_result(out_dir)
    out_dir = simulate(loaded, out_dir, seed=seed, progress=progress, master=master)
    result = read_result(out_dir)
    summary = result.summary
    if report is None or not (loaded.spec.output.figures if figures is None else figures):
        return result
    try:
        report(out_dir, summary=summary)
    except OSError as exc:  # a full disk after the run: its summary no longer says ok
        raise failed_output(out_dir, exc, "the report and figures (the run itself finished)",
                            summary=summary) from None
    return result


def read_result(out_dir: Path) -> RunResult:
    """The :class:`RunResult` of the run directory ``out_dir`` (its ``summary.json``)."""
    summary = json.loads((out_dir / SUMMARY_FILE).read_text())
    return RunResult(out_dir, summary, out_dir / LOG_FILE, summary["status"])


def output_error(out_dir: Path, exc: OSError, what: str) -> OutputError:
    """The one-line error of an output the system refused (a full disk, a read-only folder),
    naming the run directory and what could not be written."""
    name = f" ({exc.filename})" if exc.filename else ""
    return OutputError(f"{out_dir}: cannot write {what}: {exc.strerror or exc}{name}"
                       + (" (the log may be incomplete)" if what == "the log" else ""))


def failed_output(out_dir: Path, exc: OSError, what: str, error: OutputError | None = None,
                  summary: dict | None = None) -> OutputError:
    """:func:`output_error`, after writing (when it fits) ``summary.json`` with status
    ``failed``: no summary says ok that is not (the summary's other keys are kept)."""
    error = error or output_error(out_dir, exc, what)
    record = {**(summary or {}), "status": "failed", "error": str(error)}
    record.setdefault("estimators", {})
    for path in (out_dir / SUMMARY_FILE, out_dir / SIMULATION_FILE):
        try:
            write_json(path, record)
        except OSError:
            path.unlink(missing_ok=True)  # better no summary than one that says ok
    return error
