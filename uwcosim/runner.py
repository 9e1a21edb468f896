"""Run one scenario with one seed: master + estimators + log + summary + figures.

This is the library behind ``uwcosim run``; the algorithm (master, filters) knows nothing of
what records it: the estimator bank and the logger are hooks on the master.
"""

from __future__ import annotations

import fnmatch
import json
import os
import platform
from dataclasses import dataclass
from importlib import metadata as importlib_metadata
from pathlib import Path

import numpy as np

from uwcosim import __version__
from uwcosim.errors import RunInterrupted, ScenarioError, UwcosimError
from uwcosim.master.master import Master
from uwcosim.master.varmap import noise_free_notes
from uwcosim.models.bathymetry import Bathymetry, load_map, synthetic_bathymetry
from uwcosim.runguard import run_guard, signal_name
from uwcosim.runlog import RunLogger
from uwcosim.scenario.load import LoadedScenario

PACKAGES = ("uwcosim", "fmpy", "numpy", "scipy", "casadi", "pyarrow")


def package_versions() -> dict[str, str]:
    out = {}
    for p in PACKAGES:
        try:
            out[p] = importlib_metadata.version(p)
        except importlib_metadata.PackageNotFoundError:
            out[p] = __version__ if p == "uwcosim" else "not installed"
    out["python"] = platform.python_version()
    return out


def scenario_map(loaded: LoadedScenario) -> Bathymetry | None:
    m = loaded.spec.map
    if m is None:
        return None
    if m.kind == "file":
        return load_map(loaded.resolve(m.file), m.variable)
    return synthetic_bathymetry(m.seed, m.extent, m.resolution, relief_std=m.relief_std)


@dataclass
class RunResult:
    out_dir: Path
    summary: dict
    log_path: Path
    status: str


class _LogHook:
    """Writes one log row per step from the master's bus and the estimator bank."""

    def __init__(self, master: Master, bank, logger: RunLogger, signal_slots, model,
                 exact_slots=()) -> None:
        self.bank, self.logger, self.model = bank, logger, model
        self.sig = signal_slots
        self.exact = list(exact_slots)
        self.width = 1 + len(signal_slots)
        if bank:
            self.width += len(master.sensors.names) + len(bank.tracks) * (2 * model.nx + 2)
        self.row = np.empty(self.width)
        self.n_flags = len(logger.bool_columns)

    def __call__(self, master: Master) -> None:
        row = self.row
        row[0] = master.t
        i = 1 + len(self.sig)
        row[1:i] = master.bus[self.sig]
        flags = []
        if self.bank:
            meas = master.measurement()
            row[i:i + meas.z.size] = meas.z
            i += meas.z.size
            flags = [bool(r) for r in meas.received]
            nx = self.model.nx
            for tr in self.bank.tracks:
                if tr.diverged_at is None:
                    row[i:i + nx] = tr.estimator.x
                    row[i + nx:i + 2 * nx] = np.diag(tr.estimator.P)
                    row[i + 2 * nx] = tr.estimator.diagnostics.get("nis", np.nan)
                    row[i + 2 * nx + 1] = tr.nees
                else:
                    row[i:i + 2 * nx + 2] = np.nan
                i += 2 * nx + 2
            flags += [tr.diverged_at is not None for tr in self.bank.tracks]
        self.logger.append(row, np.array(flags, dtype=bool),
                           [master.native.get(s) for s in self.exact])

    def final(self, master: Master, t: float) -> None:
        """The last row of a run an FMU stopped between two communication points: the signals
        at ``t`` (the stopped FMU's outputs at its termination time; the others' at the last
        communication point), no measurements or estimates."""
        row = np.full(self.width, np.nan)
        row[0] = t
        row[1:1 + len(self.sig)] = master.bus[self.sig]
        self.logger.append(row, np.zeros(self.n_flags, dtype=bool),
                           [master.native.get(s) for s in self.exact])


def _columns(master: Master, bank, model) -> tuple[list[str], list[int], list[str]]:
    patterns = master.spec.log.signals
    names = [n for n in master.slots
             if not n.startswith(("noise.", "sensornoise."))
             and any(fnmatch.fnmatch(n, p) for p in patterns)]
    if bank:
        for tname in master.spec.model.truth:
            if tname not in names:
                names.append(tname)
    slots = [master.slots[n] for n in names]
    cols = list(names)
    flags = []
    if bank:
        cols += [f"z.{n}" for n in master.sensors.names]
        flags += [f"z.{n}.received" for n in master.sensors.names]
        for tr in bank.tracks:
            cols += [f"est.{tr.name}.{s}" for s in model.state_names]
            cols += [f"est.{tr.name}.var.{s}" for s in model.state_names]
            cols += [f"est.{tr.name}.nis", f"est.{tr.name}.nees"]
        flags += [f"est.{tr.name}.diverged" for tr in bank.tracks]
    return cols, slots, flags


#: files a run writes into its directory (``--force`` clears these, and the figures)
RUN_OUTPUTS = ("log.parquet", "log.parquet.journal", "summary.json", "report.md", "map.bin")


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


def _write_summary(out_dir: Path, summary: dict) -> None:
    path = out_dir / "summary.json"
    tmp = path.with_name("summary.json.tmp")
    tmp.write_text(json.dumps(summary, indent=2, sort_keys=True))
    os.replace(tmp, path)


def run_scenario(loaded: LoadedScenario, out_dir: Path, seed: int | None = None,
                 figures: bool | None = None, progress=None,
                 master: Master | None = None) -> RunResult:
    """Run ``loaded`` into ``out_dir`` (created). Always leaves a readable log and summary.

    ``master``: a :class:`Master` of the same scenario to reuse (reset, its FMU instances kept
    and reset); the caller then owns it and closes it. Otherwise a new one is made and closed.

    In the main thread, SIGINT, SIGTERM and SIGHUP stop the run at the next step (status
    ``interrupted``, :class:`RunInterrupted` with exit status 128 + signal), and
    ``run.fmu_timeout_s`` is enforced; an FMU that does not come back is handled by the watcher
    of :mod:`uwcosim.runguard`, which finalizes the log and summary and ends the process.
    """
    from uwcosim.estimation import EstimatorBank
    from uwcosim.evaluation.summary import summarize
    from uwcosim.models.factory import build_model

    out_dir = Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        probe = out_dir / ".write-test"
        probe.write_bytes(b"")
        probe.unlink()
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
    logger = None
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

    def finalize(status: str, message: str, code: int) -> str:
        """The signal watcher's finalization when the main thread is stuck in an FMU call."""
        if status == "interrupted":
            message = f"interrupted at t={last_time():g} by {message.rsplit(' ', 1)[-1]}"
        message = kept(message)
        if logger is not None:
            logger.close()
        try:
            summary = summarize(master, bank, status, message, log_path)
        except Exception:  # noqa: BLE001 - the main thread may be mid-step: the essentials
            summary = {"scenario": spec.name, "seed": master.seed, "status": status,
                       "error": message, "estimators": {}}
        _write_summary(out_dir, summary)
        return message

    with run_guard(spec.run.fmu_timeout_s) as guard:
        guard.master, guard.finalize = master, finalize
        try:
            master.initialize(overrides)
            if spec.estimators:
                model = build_model(loaded, bathy)
                bank = EstimatorBank(master, model, str(loaded.path),
                                     bathy.extent if bathy is not None else None)
                master.hooks.append(bank)
            cols, slots, flags = _columns(master, bank, model)
            meta = {
                "scenario_text": loaded.text, "scenario_sha256": loaded.sha256,
                "scenario_path": loaded.path.name, "overrides": list(loaded.overrides),
                "seed": master.seed, "versions": package_versions(),
                "fmus": master.fmu_hashes(), "step": master.h, "start_time": master.t0,
            }
            if bank is not None:  # what the report stage needs to read the log on its own
                meta.update(scenario_name=spec.name, truth=list(spec.model.truth),
                            states=list(model.state_names),
                            measurements=list(model.measurement_names),
                            estimators={tr.name: spec.estimators[tr.name].type
                                        for tr in bank.tracks})
            if bathy is not None:
                meta["map"] = "map.bin"
            if master.variable_maps():  # third-party FMUs: roles, variables and conversions
                meta["variable_maps"] = master.variable_maps()
            dtypes = {c: master.signal_dtype(c) for c in cols if c in master.out_vars}
            logger = RunLogger(log_path, cols, flags, meta, spec.log.chunk_steps, dtypes)
            exact = [master.slots[c] for c in logger.exact_columns]
            hook = _LogHook(master, bank, logger, np.array(slots, dtype=np.intp), model, exact)
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
            stop = master.terminated
            if stop is not None and stop.time > master.t + 1e-9 * master.h:
                hook.final(master, stop.time)
            completed = True
        except (KeyboardInterrupt, RunInterrupted):
            failure = RunInterrupted(f"interrupted at t={last_time():g}")
        except UwcosimError as exc:
            failure = exc
        finally:
            if not guard.claim():  # the watcher is finalizing and ends the process
                guard.wait_for_exit()
            if guard.signum is not None and failure is not None:
                failure = RunInterrupted(f"interrupted at t={last_time():g} by "
                                         f"{signal_name(guard.signum)}")
                failure.exit_code = guard.exit_code()
            try:
                if logger is not None:
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
                    summary = summarize(master, bank, status, error, log_path)
                    summary["scenario_file"] = str(loaded.path)
                    if master.noise_free:
                        summary["notes"] = noise_free_notes(
                            master.system, master.noise_free,
                            spec.model is not None and spec.model.q_psd is not None)
                    if snapshots is not None:
                        snapshots.save(out_dir / "densities.npz", list(model.state_names))
                    _write_summary(out_dir, summary)
                    guard.finished.set()
                finally:
                    if owner:
                        master.close()
    result = RunResult(out_dir, summary, log_path, status)
    if failure is not None:
        raise failure
    if not (spec.output.figures if figures is None else figures):
        return result
    if bank:
        from uwcosim.report import report_run

        report_run(out_dir)
    else:
        from uwcosim.plots.signals import write_signal_report

        write_signal_report(out_dir)
    return result
