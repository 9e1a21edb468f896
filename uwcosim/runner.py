"""Run one scenario with one seed: master + estimators + log + summary + figures.

This is the library behind ``uwcosim run``; the algorithm (master, filters) knows nothing of
what records it: the estimator bank and the logger are hooks on the master.
"""

from __future__ import annotations

import fnmatch
import json
import platform
from dataclasses import dataclass
from importlib import metadata as importlib_metadata
from pathlib import Path

import numpy as np

from uwcosim import __version__
from uwcosim.errors import RunInterrupted, UwcosimError
from uwcosim.master.master import Master
from uwcosim.master.varmap import noise_free_notes
from uwcosim.models.bathymetry import Bathymetry, load_map, synthetic_bathymetry
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
            self.width += len(bank.meas_slots) + len(bank.tracks) * (2 * model.nx + 2)
        self.row = np.empty(self.width)
        self.n_flags = len(logger.bool_columns)

    def __call__(self, master: Master) -> None:
        row = self.row
        row[0] = master.t
        i = 1 + len(self.sig)
        row[1:i] = master.bus[self.sig]
        flags = []
        if self.bank:
            z, rec = self.bank.measurements(master)
            row[i:i + z.size] = z
            i += z.size
            flags = [bool(r) for r in rec]
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
        cols += [f"z.{n}" for n in model.measurement_names]
        flags += [f"z.{n}.received" for n in model.measurement_names]
        for tr in bank.tracks:
            cols += [f"est.{tr.name}.{s}" for s in model.state_names]
            cols += [f"est.{tr.name}.var.{s}" for s in model.state_names]
            cols += [f"est.{tr.name}.nis", f"est.{tr.name}.nees"]
        flags += [f"est.{tr.name}.diverged" for tr in bank.tracks]
    return cols, slots, flags


def run_scenario(loaded: LoadedScenario, out_dir: Path, seed: int | None = None,
                 figures: bool | None = None, progress=None,
                 master: Master | None = None) -> RunResult:
    """Run ``loaded`` into ``out_dir`` (created). Always leaves a readable log and summary.

    ``master``: a :class:`Master` of the same scenario to reuse (reset, its FMU instances kept
    and reset); the caller then owns it and closes it. Otherwise a new one is made and closed.
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
    try:
        master.initialize(overrides)
        if spec.estimators:
            model = build_model(loaded, bathy)
            bank = EstimatorBank(master, model, str(loaded.path))
            master.hooks.append(bank)
        cols, slots, flags = _columns(master, bank, model)
        meta = {
            "scenario_text": loaded.text, "scenario_sha256": loaded.sha256,
            "scenario_path": loaded.path.name, "overrides": list(loaded.overrides),
            "seed": master.seed, "versions": package_versions(), "fmus": master.fmu_hashes(),
            "step": master.h, "start_time": master.t0,
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
            snapshots = DensitySnapshots(bank, list(spec.output.density_snapshots), tuple(pos))
            master.hooks.append(snapshots)
        if progress is not None:
            master.hooks.append(progress)
        master.run_until(master.t0 + master.n_steps * master.h)
        stop = master.terminated
        if stop is not None and stop.time > master.t + 1e-9 * master.h:
            hook.final(master, stop.time)
    except KeyboardInterrupt:
        failure = RunInterrupted(f"interrupted at t={master.t:g}")
    except UwcosimError as exc:
        failure = exc
    finally:
        if logger is not None:
            logger.close()
        if owner:
            master.close()
    status = "ok" if failure is None else (
        "interrupted" if isinstance(failure, RunInterrupted) else "failed")
    if failure is None and master.terminated is not None:
        status = "terminated"
    summary = summarize(master, bank, status, str(failure or ""), log_path)
    summary["scenario_file"] = str(loaded.path)
    if master.noise_free:
        summary["notes"] = noise_free_notes(
            master.system, master.noise_free,
            spec.model is not None and spec.model.q_psd is not None)
    if snapshots is not None:
        snapshots.save(out_dir / "densities.npz", list(model.state_names))
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2, sort_keys=True))
    result = RunResult(out_dir, summary, log_path, status)
    if failure is not None:
        if logger is not None:
            failure.args = (f"{failure} (log up to t={master.t:g} kept in {log_path})",)
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
