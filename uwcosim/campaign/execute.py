"""Execute a campaign's runs: in a supervised child process, on local worker processes, or on
Dask.

Each finished run is written at once to ``results/<variant>__<run>.json`` (atomically), so an
interruption loses nothing already finished and ``--resume`` skips those runs (a record that is
not valid JSON is taken as not done and run again). A failed run is recorded with its error
and the campaign goes on; its run directory is kept in ``failed/<variant>/run_NNNNN``.

``--workers N`` runs the tasks on N forked child processes at once, each given the next run
when it has finished one (:func:`uwcosim.core.supervise.supervised_pool`; ``--workers 1``: one
child, :func:`~uwcosim.core.supervise.supervised_map`; FMU instances are reused between the runs
of a child): an FMU that ends a child's process (``exit``, ``abort``, a segmentation fault) or
the run-wide watchdog (``run.fmu_timeout_s``) fails that run, as ``uwcosim run`` reports it (one
line: which FMU call, how; the run directory finished from its journal and kept under
``failed/``), and a new child takes the dead one's place. The children die with the campaign
(``prctl`` parent-death signal); the campaign passes SIGINT, SIGTERM and SIGHUP on to them, and
their temporary files are in folders of the campaign's, removed when each child ends.

Where the platform cannot fork, or with ``UWCOSIM_SUPERVISE=0``, ``--workers N`` is a pool of
spawned worker processes (:class:`~concurrent.futures.ProcessPoolExecutor`), which cannot
contain a crash: a worker that dies stops the campaign (finished runs are kept, ``--resume``
goes on). Pool workers die with the campaign and ignore SIGINT, SIGTERM and SIGHUP (the campaign
process decides); an interrupted campaign kills them. Their temporary files (``uwcosim_run_*``
run folders, unzipped FMUs) are in a folder of the campaign's, removed when the pool ends,
however it ends.
"""

from __future__ import annotations

import json
import logging
import os
import re
import shutil
import sys
import tempfile
import time
import traceback
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from uwcosim.campaign.aggregate import read_record
from uwcosim.campaign.spec import Task
from uwcosim.core.errors import RunInterrupted, ScenarioError, UwcosimError
from uwcosim.core.process import die_with_parent
from uwcosim.core.supervise import Death, announce, supervised_pool
from uwcosim.core.supervise import enabled as supervised
from uwcosim.master.master import Master
from uwcosim.run.aftermath import finish_death
from uwcosim.run.simulate import run_scenario
from uwcosim.scenario import load_scenario, to_system

_SCENARIOS: dict = {}  # per worker process: (path, overrides) -> LoadedScenario
_MASTERS: dict = {}  # per worker process: (path, overrides) -> Master (FMU instances reused)


def _master_for(key, loaded):
    """The worker's master of this scenario: its FMUs are instantiated once and reset between
    runs when they allow several instances (otherwise a fresh master per run)."""
    m = _MASTERS.get(key)
    if m is None:
        m = Master(to_system(loaded))
        if not all(_reusable(a) for a in m.adapters.values()):
            return None, m
        _MASTERS[key] = m
    return m, m


def _reusable(adapter) -> bool:
    kind = adapter.md.coSimulation if adapter.interface == "cs" else adapter.md.modelExchange
    return not getattr(kind, "canBeInstantiatedOnlyOncePerProcess", False)


def execute_run(task: Task) -> dict:
    """Run one task and return its record (never raises: errors are recorded)."""
    record = {"variant": task.variant, "run": task.run, "seed": task.seed, "status": "ok",
              "error": "", "estimators": {}}
    started = (time.perf_counter(), time.process_time())
    tmp = None
    try:
        key = (task.scenario, task.overrides)
        loaded = _SCENARIOS.get(key)
        if loaded is None:
            loaded = _SCENARIOS[key] = load_scenario(task.scenario, list(task.overrides))
        if task.log_dir:
            out = Path(task.log_dir)
        else:
            tmp = tempfile.mkdtemp(prefix="uwcosim_run_")
            out = Path(tmp)
        announce(out)  # in a supervised child: where a dead run is finished
        # a replay has no FMUs to keep: its source is made by each run
        cached, master = _master_for(key, loaded) if loaded.spec.replay is None \
            else (None, None)
        try:
            res = run_scenario(loaded, out, seed=task.seed, figures=False, master=master)
        except BaseException:
            # the instances may be in an error state: drop them, the next run starts afresh
            _MASTERS.pop(key, None)
            if master is not None:
                master.close()
            raise
        if cached is None and master is not None:
            master.close()
        record["estimators"] = res.summary["estimators"]
        record["timing"] = res.summary["timing"]
        record["scenario_sha256"] = loaded.sha256
    except RunInterrupted:
        raise  # the campaign stops: this run is not done
    except UwcosimError as exc:
        record.update(status="failed", error=_kept_failed(str(exc), tmp, task))
        tmp = None if tmp and task.fail_dir else tmp
    except Exception as exc:  # noqa: BLE001 - a campaign records any run failure and goes on
        last = traceback.extract_tb(exc.__traceback__)[-1]
        record.update(status="failed", error=f"{type(exc).__name__}: {exc} "
                                             f"({Path(last.filename).name}:{last.lineno})")
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    record.update(_resources(started))
    return record


def dead_run_record(task: Task, death: Death) -> dict:
    """The record of a run whose process ended in it (:func:`supervised_pool`): failed, with the
    one line ``uwcosim run`` would print; its run directory finished and kept."""
    error = finish_death(death.out_dir, death.message(), death.error is not None)
    if death.out_dir is not None and not task.log_dir:  # a temporary one: kept under failed/
        error = _kept_failed(error, death.out_dir, task)
    return {"variant": task.variant, "run": task.run, "seed": task.seed, "status": "failed",
            "error": error, "estimators": {}}


def _kept_failed(error: str, tmp: str | None, task: Task) -> str:
    """Move a failed run's temporary directory under the campaign's ``failed/`` and name that
    path in the error (the temporary one is deleted)."""
    if not tmp or not task.fail_dir:
        return error
    dest = Path(task.fail_dir)
    try:
        if dest.exists():
            shutil.rmtree(dest)
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(tmp, dest)
    except OSError:
        return error
    return error.replace(str(Path(tmp)), str(dest))


def _worker_init(parent: int, tmp: str | None = None) -> None:
    """Pool worker: die with the campaign, leave signals to it; an estimator stopped in a run
    is in its record, not a line on the campaign's terminal; its temporary files in ``tmp``
    (the campaign's folder, removed by the campaign even when the worker is killed)."""
    import signal

    if tmp is not None:
        tempfile.tempdir = tmp
        os.environ["TMPDIR"] = tmp

    logging.getLogger("uwcosim.run.bank").addHandler(logging.NullHandler())
    logging.getLogger("uwcosim.core.numwarn").addHandler(logging.NullHandler())  # in summary

    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, signal.SIG_IGN)
    die_with_parent(parent)


def _resources(started: tuple[float, float]) -> dict:
    """Wall and CPU time of the run, the worker process's peak resident memory so far (MB).

    The CPU time is what the run costs on a core of its own (the wall time also counts waiting
    for the CPU on a loaded machine)."""
    out = {"wall_s": time.perf_counter() - started[0], "cpu_s": time.process_time() - started[1],
           "worker": os.getpid()}
    try:
        import resource

        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # kB on Linux, B on macOS
        out["peak_rss_mb"] = rss / (1024 * 1024 if sys.platform == "darwin" else 1024)
    except (ImportError, OSError):  # pragma: no cover - not on Windows
        pass
    return out


def _write(results: Path, task: Task, record: dict) -> None:
    path = results / f"{task.key}.json"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(record, sort_keys=True))
    os.replace(tmp, path)


def pending_tasks(tasks: list[Task], results: Path, resume: bool,
                  scenario_hashes: dict[str, str] | None = None) -> list[Task]:
    """The tasks still to run. Finished records must match the task's seed and the variant's
    scenario hash (else ScenarioError: the results belong to another campaign)."""
    files = {p.stem: p for p in results.glob("*.json")}
    if files and not resume:
        raise ScenarioError(f"{results.parent}: campaign output already has {len(files)} "
                            f"finished runs (use --resume, or another --out)")
    by_key = {t.key: t for t in tasks}
    done = set()
    for key, p in files.items():
        record = read_record(p)
        if record is None:
            continue  # truncated: run it again
        t = by_key.get(key)
        if t is None:
            continue
        if record["seed"] != t.seed:
            raise ScenarioError(f"{p}: recorded seed {record['seed']} differs from this "
                                f"campaign's seed for run {t.run} ({t.seed}): another campaign "
                                f"(use another --out)")
        want = (scenario_hashes or {}).get(t.variant)
        got = record.get("scenario_sha256")
        if want and got and got != want and record["status"] == "ok":
            raise ScenarioError(f"{p}: the run's scenario (sha256 {got[:12]}) differs from "
                                f"variant {t.variant!r}'s ({want[:12]}): the scenario changed "
                                f"(use another --out)")
        done.add(key)
    return [t for t in tasks if t.key not in done]


def _progress(total: int, initial: int):
    try:
        from tqdm import tqdm

        # smoothing 0: tqdm's own rate and remaining time are this session's average
        return tqdm(total=total, initial=initial, unit="run", file=sys.stderr,
                    dynamic_ncols=True, smoothing=0.0)
    except ImportError:  # pragma: no cover - tqdm is a dependency
        return None


class SessionStats:
    """Cost of the runs finished in this session: per-run wall time, filter time, peak RSS.

    The ETA is the remaining run count times the measured per-run cost divided by the measured
    parallelism (sum of run wall times over elapsed time: the number of runs in flight, which
    also holds on a Dask cluster of unknown size)."""

    def __init__(self, remaining: int) -> None:
        self.start = time.perf_counter()
        self.remaining = remaining
        self.runs = 0
        self.run_wall_s = 0.0
        self.filter_s = 0.0
        self.peak_rss_mb = 0.0

    def add(self, record: dict) -> None:
        self.runs += 1
        self.remaining -= 1
        self.run_wall_s += float(record.get("wall_s", 0.0))
        self.filter_s += sum(float(m.get("total_time_s", 0.0))
                             for m in record.get("estimators", {}).values())
        self.peak_rss_mb = max(self.peak_rss_mb, float(record.get("peak_rss_mb", 0.0)))

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def eta_s(self) -> float | None:
        if not self.runs or self.elapsed <= 0:
            return None
        per_run = self.run_wall_s / self.runs
        parallel = max(self.run_wall_s / self.elapsed, 1e-9)
        return self.remaining * per_run / parallel

    def summary(self) -> dict:
        wall = self.elapsed
        return {
            "runs_this_session": self.runs, "wall_time_s": wall,
            "runs_per_s": self.runs / wall if wall > 0 else float("nan"),
            "mean_run_wall_s": self.run_wall_s / self.runs if self.runs else float("nan"),
            "filter_share": self.filter_s / self.run_wall_s if self.run_wall_s else float("nan"),
            "peak_rss_mb": self.peak_rss_mb,
        }


def _eta_text(seconds: float | None) -> str:
    if seconds is None:
        return "?"
    m, s = divmod(int(round(seconds)), 60)
    return f"{m // 60}:{m % 60:02d}:{s:02d}" if m >= 60 else f"{m}:{s:02d}"


def run_tasks(tasks: list[Task], results: Path, workers: int, scheduler: str | None,
              total: int, on_record: Callable[[dict], None] | None = None) -> int:
    """Run ``tasks``, writing each record as it completes; returns the number of failures."""
    results.mkdir(parents=True, exist_ok=True)
    bar = _progress(total, total - len(tasks))
    failures = 0
    stats = SessionStats(len(tasks))

    def done(task: Task, record: dict) -> None:
        nonlocal failures
        _write(results, task, record)
        failures += record["status"] != "ok"
        stats.add(record)
        if on_record:
            on_record(record)
        if bar is not None:
            bar.update(1)
            bar.set_postfix(failed=failures, eta=_eta_text(stats.eta_s()),
                            per_run=f"{stats.run_wall_s / stats.runs:.1f}s")

    try:
        for task, record in _iterate(tasks, workers, scheduler):
            done(task, record)
    finally:
        if bar is not None:
            bar.close()
        write_session(results.parent, stats)
    return failures


def session_line(out: Path) -> str:
    """One line from ``session.json`` (printed at the end of ``uwcosim campaign``)."""
    try:
        s = json.loads((Path(out) / "session.json").read_text())
    except (OSError, ValueError):
        return "no run finished in this session"
    if not s.get("runs_this_session"):
        return "no run finished in this session"
    return (f"this session: {s['runs_this_session']} runs in {s['wall_time_s']:.1f} s = "
            f"{s['runs_per_s']:.3f} runs/s ({s['mean_run_wall_s']:.2f} s per run and worker); "
            f"filters {100 * s['filter_share']:.0f}% of the run time; peak RSS "
            f"{s['peak_rss_mb']:.0f} MB per worker")


def write_session(out: Path, stats: SessionStats) -> Path:
    """``session.json``: runs/s, filter share and peak RSS of this session's runs."""
    path = out / "session.json"
    path.write_text(json.dumps(stats.summary(), indent=2, sort_keys=True))
    return path


def _iterate(tasks: list[Task], workers: int, scheduler: str | None) -> Iterable:
    if not tasks:
        return
    if scheduler:
        yield from _dask(tasks, scheduler)
        return
    # one BLAS/OpenMP thread per worker process: K processes on K cores, no oversubscription
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    if workers <= 1 or supervised():
        for i, record in supervised_pool(execute_run, tasks, workers):
            yield tasks[i], dead_run_record(tasks[i], record) \
                if isinstance(record, Death) else record
    else:  # a platform that cannot fork, or UWCOSIM_SUPERVISE=0: spawned pool workers
        import multiprocessing as mp

        # the workers' temporary files (runs, unzipped FMUs): a killed worker leaves them
        tmp = tempfile.mkdtemp(prefix="uwcosim_campaign_")
        try:
            yield from _pool(tasks, workers, mp, tmp)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


def _pool(tasks: list[Task], workers: int, mp, tmp: str) -> Iterable:
    with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                             initializer=_worker_init, initargs=(os.getpid(), tmp)) as ex:
        futures = {ex.submit(execute_run, t): t for t in tasks}
        try:
            for f in as_completed(futures):
                try:
                    record = f.result()
                except BrokenProcessPool:
                    t = futures[f]
                    raise UwcosimError(
                        f"a campaign worker process died during run {t.run} of variant "
                        f"{t.variant!r} (crashed FMU, watchdog, or killed); finished runs "
                        f"are kept, --resume continues") from None
                yield futures[f], record
        except BaseException:
            # in-flight runs are abandoned (not recorded: --resume runs them again). The
            # pool then fails every pending future itself (cancelling them first races
            # with that in Python 3.11: InvalidStateError in the pool's thread)
            for proc in list((getattr(ex, "_processes", None) or {}).values()):
                proc.kill()
            raise


def check_scheduler(scheduler: str) -> None:
    """Refuse a ``--scheduler`` that is not a dask scheduler address (``tcp://HOST:PORT``)
    before anything is written."""
    if not re.fullmatch(r"(?:[a-z][a-z0-9+.-]*://)?[^\s/:]+:\d+/?", scheduler):
        raise ScenarioError(f"--scheduler {scheduler!r}: not a scheduler address (expected "
                            f"tcp://HOST:PORT, as dask-scheduler prints it)")


def _dask(tasks: list[Task], scheduler: str) -> Iterable:
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError:
        raise ScenarioError("--scheduler needs dask.distributed: pip install 'dask[distributed]'"
                            ) from None
    try:
        client = Client(scheduler, timeout="10s")
    except (OSError, ValueError) as exc:
        raise ScenarioError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
    try:
        futures = client.map(execute_run, tasks, pure=False)
        index = dict(zip(futures, tasks))
        for f in dask_completed(futures):
            yield index[f], f.result()
    finally:
        client.close()
