"""Command-line interface: a thin layer over the library.

``uwcosim run SCENARIO [--seed N] [--out DIR] [--set key=value ...]`` (a shipped scenario also
by name: ``uwcosim run tan_terrain``),
``uwcosim check SCENARIO [--set key=value ...]``, ``uwcosim schema [--out FILE]``,
``uwcosim report RUN``,
``uwcosim export RUN --csv|--mat``, ``uwcosim list estimators|models|scenarios|fmus``,
``uwcosim demo``, ``uwcosim docs``,
``uwcosim fmu build|info|validate|check ...``, ``uwcosim regress RUN BASELINE``,
``uwcosim baseline update|check``, ``uwcosim campaign SPEC``, ``uwcosim verify example1``,
``uwcosim ssp export SCENARIO [--out FILE] [--ssp-version 1.0|2.0]``,
``uwcosim bound SCENARIO|CAMPAIGN [--runs N]``, ``uwcosim completion bash|zsh|tcsh``.
Every ``--help`` shows the defaults.
User errors are caught once here: one line on stderr, a non-zero exit status, no traceback.

Each command imports its modules inside its function, when it runs: start-up laziness (``uwcosim
--help`` and a command load only what that command needs). This is the one module of the
package that imports uwcosim modules inside functions (``tests/test_architecture.py``).
After ``run``, ``demo`` and ``campaign`` the process ends once every file is closed, without the
interpreter's slow teardown (:func:`_leave`; ``UWCOSIM_FAST_EXIT=0`` keeps it).
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Iterator
from pathlib import Path

from uwcosim.core.errors import FMUError, UwcosimError, os_error_line
from uwcosim.core.version import __version__

ANEES_NOTE = ("ANEES: average normalized estimation error squared, per state; 1 = consistent "
              "(covariance matches the errors), < 1 pessimistic, > 1 overconfident")

#: what a run directory holds that a person opens, in this order (``report.html``: ``uwcosim
#: report RUN --html``)
OPEN_FILES = ("report.md", "report.html", "trajectory.png", "position_error.png",
              "position_error_norm.png", "signals.png", "density_t*.png", "summary.json",
              "log.parquet")


def _print_result(result) -> None:
    from uwcosim.reports.table import results_table

    s = result.summary
    if s["estimators"]:
        print(results_table(s), end="")
        print(ANEES_NOTE)
        b = s.get("bound")
        if b:
            print(f"PCRB position {b['position_m']:.3f} m over {b.get('runs', '?')} truth runs "
                  f"(each estimator's rmse_position_to_bound in summary.json)")
    else:
        print(f"status {s['status']}: {s['steps']} steps of {s['step_s']:g} s, "
              f"t = {s['start_time_s']:g} .. {s['end_time_s']:g} s")
    stop = s.get("termination")
    if stop is not None:
        reason = f": {stop['reason']}" if stop["reason"] else ""
        print(f"uwcosim: FMU '{stop['fmu']}' requested termination at t={stop['time_s']:g}"
              f"{reason} (run ended, log kept)", file=sys.stderr)
    t = s["timing"]
    rp = s.get("replay")
    if rp:
        print(f"replayed {rp['rows']} rows of {rp['file']} (steps {rp['dt_min_s']:g} .. "
              f"{rp['dt_max_s']:g} s), replay overhead "
              f"{1e6 * t['master_overhead_per_step_s']:.1f} us/step")
    else:
        print(f"master overhead {1e6 * t['master_overhead_per_step_s']:.1f} us/step, "
              f"FMUs {1e6 * t['fmus_per_step_s']:.1f} us/step")
    out = Path(result.out_dir).resolve()
    print(f"run directory: {out}")
    files = [p.name for pattern in OPEN_FILES for p in sorted(out.glob(pattern))]
    if files:
        print(f"open: {', '.join(files)}")
    if not (out / "report.md").is_file() and s["estimators"]:
        print(f"figures and report: uwcosim report {out} [--html]")


def _scenario_path(arg: str, campaign: bool = False) -> Path:
    """A scenario (or campaign spec) argument: a file, or the name of a shipped one
    (``tan_terrain``, ``smoke``); a shipped file of an installed wheel is run from its copy in
    the cache folder, where its FMUs are built on first use."""
    from uwcosim.core.paths import shipped_names, shipped_scenario

    path = Path(arg)
    if not path.exists():
        found = shipped_scenario(arg)
        if found is None:
            if path.suffix in ("", ".toml") and "/" not in arg:
                names = ", ".join(shipped_names(campaign))
                raise UwcosimError(f"{arg}: {'campaign spec' if campaign else 'scenario'} "
                                   f"file not found, nor a shipped one by that name "
                                   f"(shipped: {names}; see uwcosim list scenarios)")
            return path  # the loader's own message
        path = found
    from uwcosim.scenario.shipped import runnable

    return runnable(path)


def _provide_fmus(paths) -> None:
    """Build the project FMUs among ``paths`` that are missing (first use of a wheel's shipped
    scenario, or a checkout without ``make fmus``); nothing imported when none is."""
    from uwcosim.scenario.shipped import missing_fmus

    paths = list(paths)
    if missing_fmus(paths):
        from uwcosim.demo import provide_fmus

        provide_fmus(paths)


class _Progress:
    """The progress of ``run``/``demo`` (:class:`uwcosim.run.progress.RunProgress`), hooked to
    the first compile of the Numba kernels, and the report stage announced as a stage."""

    def __init__(self, loaded, args) -> None:
        from uwcosim.core import jit
        from uwcosim.run.progress import RunProgress

        run = loaded.spec.run
        step = getattr(run, "step", None)
        duration = getattr(run, "duration", None)
        steps = (round(duration / step) if step and duration is not None
                 and loaded.spec.replay is None else None)
        self.observer = RunProgress(steps, step, float(getattr(run, "start_time", 0.0) or 0.0),
                                    enabled=args.quiet == 0)
        self._jit = jit
        jit.on_compile = self.observer.compiling

    def report(self, out_dir: Path, *, summary: dict):
        from uwcosim.reports.run_report import report_run  # matplotlib: only for figures

        self.observer.stage("figures and report (report.md)")
        return report_run(out_dir, summary=summary)

    def close(self) -> None:
        self.observer.close()
        self._jit.on_compile = None


def _cmd_run(args) -> int:
    from uwcosim.core.supervise import announce
    from uwcosim.run.simulate import out_dir_of, run_scenario
    from uwcosim.runlog.rundir import prepare_out_dir
    from uwcosim.scenario.load import load_scenario
    from uwcosim.scenario.shipped import scenario_fmus

    loaded = load_scenario(_scenario_path(args.scenario), args.set or [],
                           overrides_base=Path.cwd())
    _provide_fmus(scenario_fmus(loaded))
    out = out_dir_of(loaded, args.out)
    prepare_out_dir(out, args.force)
    announce(out)  # a supervised run: where its parent finishes it if an FMU ends the process
    progress = _Progress(loaded, args)
    try:
        result = run_scenario(loaded, out, seed=args.seed, figures=not args.no_figures,
                              progress=progress.observer, report=progress.report)
    finally:
        progress.close()
    _print_result(result)
    return 0


def _cmd_check(args) -> int:
    from uwcosim.run.preflight import check_scenario

    report = check_scenario(args.scenario, args.set or [], overrides_base=Path.cwd())
    for p in report.problems:
        print(p.message, file=sys.stderr)
    n = len(report.problems)
    print(f"{args.scenario}: " + (f"{n} problem{'s' * (n != 1)}" if n else "ok") +
          f" (checked: {', '.join(report.checked) or 'nothing'})")
    return report.exit_code


def _cmd_schema(args) -> int:
    from uwcosim.scenario.json_schema import scenario_estimator_types, scenario_json_schema_text

    extra = scenario_estimator_types(args.scenario) if args.scenario else []
    text = scenario_json_schema_text(extra)
    if args.out is None:
        print(text, end="")
        return 0
    try:
        Path(args.out).write_text(text, encoding="utf-8")
    except OSError as exc:
        raise UwcosimError(f"{args.out}: cannot write the schema ({exc.strerror or exc})"
                           ) from None
    print(args.out)
    return 0


def _cmd_demo(args) -> int:
    from uwcosim.core.supervise import announce
    from uwcosim.demo import prepare_cache
    from uwcosim.scenario.load import load_scenario

    loaded = load_scenario(prepare_cache(), args.set or [], overrides_base=Path.cwd())
    announce(args.out)  # supervised as a run is
    progress = _Progress(loaded, args)
    try:
        from uwcosim.run.simulate import run_scenario

        result = run_scenario(loaded, Path(args.out), seed=args.seed,
                              progress=progress.observer, report=progress.report)
    finally:
        progress.close()
    _print_result(result)
    return 0


def _cmd_export(args) -> int:
    from uwcosim.export import export_csv, export_mat

    if args.format == "csv":
        print(export_csv(args.run, args.out, units=not args.no_units))
    else:
        print(export_mat(args.run, args.out))
    return 0


def _cmd_list(args) -> int:
    from uwcosim import catalog

    if args.scenario and args.what != "estimators":
        raise UwcosimError("--scenario: only with 'uwcosim list estimators'")
    if args.what == "estimators":
        print(catalog.list_estimators(args.scenario))
        return 0
    print({"models": catalog.list_models, "scenarios": catalog.list_scenarios,
           "fmus": catalog.list_fmus}[args.what]())
    return 0


def _cmd_docs(args) -> int:
    from uwcosim.core.paths import docs_dir

    where = docs_dir()
    if not where.is_dir():
        raise UwcosimError(f"{where}: docs folder not found (a broken installation: reinstall "
                           f"uwcosim)")
    print(f"docs: {where}")
    for p in sorted(where.rglob("*.md")):
        print(f"  {p.relative_to(where)}")
    return 0


def _cmd_completion(args) -> int:
    import shtab

    print(shtab.complete(build_parser(), shell=args.shell))
    return 0


def _cmd_report(args) -> int:
    from uwcosim.api import report

    print(report(args.run, args.out, html=args.html))
    return 0


def _cmd_fmu_build(args) -> int:
    from uwcosim.fmu.build import build_fmus, register_specs

    names = list(args.names or [])
    if args.spec:
        names += register_specs(args.spec)
    for p in build_fmus(args.out, names=names or None, force=args.force):
        print(p)
    return 0


def _cmd_fmu_info(args) -> int:
    from uwcosim.fmu.info import fmu_info

    print(fmu_info(args.fmu))
    return 0


def _cmd_fmu_validate(args) -> int:
    from uwcosim.fmu.info import validate

    problems = validate(args.fmu)
    for p in problems:
        print(f"{args.fmu}: {p}", file=sys.stderr)
    if not problems:
        print(f"{args.fmu}: valid")
    else:
        print(f"{args.fmu}: not valid: {len(problems)} problem{'s' * (len(problems) != 1)} "
              f"(a conformance check, exit 1 on any finding; 'uwcosim fmu check' lists the "
              f"findings of the FMI standard's rules as warnings, as the master does not rely "
              f"on them, and may still call the FMU compatible)", file=sys.stderr)
    return 1 if problems else 0


def _cmd_fmu_check(args) -> int:
    from uwcosim.fmu.check import check_fmu

    report = check_fmu(args.fmu, role=args.role, map_file=args.map, interface=args.interface,
                       duration=args.duration, step=args.step, timeout_s=args.timeout)
    print(report.text())
    return 0 if report.ok else 1


def _cmd_regress(args) -> int:
    from uwcosim.regress.compare import compare_logs, log_file

    plots = None
    if not args.no_plots:
        run = Path(args.run)
        plots = Path(args.plots) if args.plots else (
            run / "regress" if run.is_dir() else log_file(run).with_name(f"{run.stem}_regress"))
    report = compare_logs(args.run, args.baseline, args.rtol, args.atol, args.ttol,
                          args.signals, plot_dir=plots, allow_shorter=args.allow_shorter)
    print(report.text())
    return 0 if report.ok else 1


def _cmd_baseline(args) -> int:
    from uwcosim.regress.baselines import (
        DEFAULT_OVERRIDES,
        check_baseline,
        shipped_scenarios,
        update_baseline,
    )

    if args.baseline_command == "check":
        from uwcosim.regress.compare import check_tolerances

        check_tolerances(args.rtol, args.atol, args.ttol)
    from uwcosim.scenario.load import load_scenario
    from uwcosim.scenario.shipped import scenario_fmus

    scenarios = [_scenario_path(s) for s in args.scenarios] or [
        _scenario_path(str(p)) for p in shipped_scenarios(args.scenario_dir)]
    if args.baseline_command == "check" and not any(Path(args.dir).glob("*.parquet")):
        raise UwcosimError(f"{args.dir}: no baseline logs (*.parquet) to check against; write "
                           f"them with 'uwcosim baseline update' or give --dir")
    _provide_fmus(p for sc in scenarios if sc.is_file()
                  for p in scenario_fmus(load_scenario(sc, getattr(args, "set", None) or [])))
    print(f"baselines: {args.dir}", file=sys.stderr)
    bad = 0
    for sc in scenarios:
        if args.baseline_command == "update":
            res = update_baseline(sc, Path(args.dir), [*DEFAULT_OVERRIDES, *(args.set or [])])
            print(f"{res.baseline}: {res.status}")
            if res.status == "changed" and res.report is not None:
                print("\n".join("  " + line for line in res.report.text().splitlines()[1:]))
        else:
            plots = Path(args.plots) / sc.stem if args.plots else None
            res = check_baseline(sc, Path(args.dir), args.rtol, args.atol, args.ttol, plots)
            print(res.report.text())
            bad += res.status != "ok"
    return 1 if bad else 0


def _cmd_verify(args) -> int:
    from uwcosim.verify.example1 import run_example1

    run_example1(Path(args.out) if args.out else None)
    return 0


def _cmd_ssp_export(args) -> int:
    from uwcosim.scenario import load_scenario
    from uwcosim.ssp.export import export_ssp

    loaded = load_scenario(args.scenario, args.set or [], overrides_base=Path.cwd())
    out = Path(args.out) if args.out else Path(f"{loaded.path.stem}.ssp")
    path, notes = export_ssp(loaded, out, version=args.ssp_version)
    for note in notes:
        print(f"note: {note}")
    print(path)
    return 0


def _cmd_bound(args) -> int:
    import tomllib

    from uwcosim.run.bound import scenario_bound, write_bound

    path = Path(args.spec)
    try:
        is_campaign = "variants" in tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        is_campaign = False  # the loaders say what is wrong with the file
    if is_campaign:
        from uwcosim.campaign import load_campaign
        from uwcosim.campaign.bound import campaign_bounds

        campaign = load_campaign(path)
        if args.set or args.seed is not None:
            raise UwcosimError(f"{path}: --set and --seed are for a scenario (a campaign's "
                               f"variants and seed are in its spec)")
        out = Path(args.out) if args.out else Path("runs") / f"bound_{campaign.spec.name}"
        bounds = campaign_bounds(campaign, out, args.runs, per_run=args.per_run)
    else:
        from uwcosim.scenario import load_scenario

        loaded = load_scenario(path, args.set or [], overrides_base=Path.cwd())
        out = Path(args.out) if args.out else Path("runs") / f"bound_{loaded.path.stem}"
        b = scenario_bound(loaded, args.runs if args.runs is not None else 100, seed=args.seed,
                           per_run=args.per_run)
        write_bound(b, out)
        bounds = {loaded.path.stem: b}
    for name, b in bounds.items():
        forms = ", ".join(f"{n} {f}" for f, n in b.forms.items())
        print(f"{name}: PCRB position {b.position_m():.3f} m (RMS over steps 1..{b.t.size - 1}; "
              f"{b.runs} truth runs, seed {b.seed}; recursion: {forms})")
    print(f"bound directory: {out}")
    return 0


def _cmd_campaign(args) -> int:
    from uwcosim.campaign import load_campaign
    from uwcosim.campaign.driver import run_campaign
    from uwcosim.scenario.load import load_scenario
    from uwcosim.scenario.shipped import scenario_fmus

    campaign = load_campaign(_scenario_path(args.spec, campaign=True))
    # every variant's FMUs: built if missing, checked present before any worker starts
    fmus = {p for v in campaign.spec.variants
            for p in scenario_fmus(load_scenario(campaign.resolve(v.scenario), v.set))}
    _provide_fmus(sorted(fmus))
    absent = sorted(p for p in fmus if not p.exists())
    if absent:
        raise FMUError(f"{absent[0]}: FMU not found (variant scenarios of {campaign.path} need "
                       f"{len(absent)} missing FMU{'s' * (len(absent) != 1)}; nothing was run)")
    out = Path(args.out) if args.out else Path("runs") / f"campaign_{campaign.path.stem}"
    summary = run_campaign(campaign, out, runs=args.runs, workers=args.workers,
                           scheduler=args.scheduler, resume=args.resume,
                           oversubscribe=args.oversubscribe)
    print((out / "table.md").read_text() if (out / "table.md").exists() else "no results")
    for f in summary.get("failed", []):
        print(f"failed: {f['variant']} run {f['run']}: {f['error']}", file=sys.stderr)
    for f in summary.get("nan", []):
        print(f"NaN: {f['variant']} run {f['run']}: estimator {f['estimator']} has a NaN "
              f"position RMSE", file=sys.stderr)
    print(f"{summary['runs']} runs in {out} ({summary['wall_time_s']:.1f} s)")
    from uwcosim.campaign.execute import session_line

    print(session_line(out))
    return 1 if summary.get("failed") or summary.get("nan") else 0


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (as every other user error): no usage block."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} -h)\n")


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows ``(default: X)`` after every help text, except for flags and unset (None)."""

    def _get_help_string(self, action) -> str:
        text = action.help or ""
        if ("default" in text or action.default in (None, False, argparse.SUPPRESS)
                or isinstance(action, argparse._VersionAction)):
            return text
        return super()._get_help_string(action)


def walk_parsers(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    """The parser and every sub-parser under it (for the formatter and the tests)."""
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):
                yield from walk_parsers(sub)


#: the default tolerances of ``regress`` and ``baseline check``: those of
#: :mod:`uwcosim.regress.compare` (``tests/test_cli_everyday.py`` keeps them equal), written here
#: so that building the parser imports no comparison code (numpy, matplotlib)
DEFAULT_RTOL, DEFAULT_ATOL, DEFAULT_TTOL = 1e-6, 1e-9, 0.0

SET_HELP = ("override any scenario key with a TOML value, e.g. --set run.duration=100 "
            "(repeatable); a relative file path given here is relative to the current folder, "
            "paths written in the scenario file are relative to that file")


def build_parser() -> argparse.ArgumentParser:
    from uwcosim.core.paths import baselines_dir, scenarios_dir

    p = _Parser(prog="uwcosim", description=__doc__.splitlines()[0])
    p.add_argument("--version", action="version", version=f"uwcosim {__version__}",
                   help="print the version and exit")
    p.add_argument("-v", "--verbose", action="count", default=0,
                   help="more log messages (-v info, -vv debug)")
    p.add_argument("-q", "--quiet", action="count", default=0,
                   help="fewer log messages (errors only)")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    r = sub.add_parser("run", help="run a scenario (a TOML file, or an .ssp alone: a plain "
                       "co-simulation)")
    r.add_argument("scenario", help="scenario .toml, or an SSP file .ssp")
    r.add_argument("--seed", type=int, default=None, help="override run.seed")
    r.add_argument("--out", default=None, help="run directory (default runs/<scenario name>)")
    r.add_argument("--set", action="append", metavar="KEY=VALUE", help=SET_HELP)
    r.add_argument("--no-figures", action="store_true", help="skip figures and report")
    r.add_argument("--force", action="store_true",
                   help="run into a non-empty run directory, replacing its run files")
    r.set_defaults(func=_cmd_run)

    ck = sub.add_parser("check", help="validate a scenario without running it: every problem "
                        "of its keys, the FMUs' variables and types, the map and the filters, "
                        "one line each (exit 0 ok, 2 scenario problems, 3 FMU problems only)")
    ck.add_argument("scenario", help="scenario .toml, or an SSP file .ssp")
    ck.add_argument("--set", action="append", metavar="KEY=VALUE", help=SET_HELP)
    ck.set_defaults(func=_cmd_check)

    sc = sub.add_parser("schema", help="print the JSON Schema of the scenario format (for "
                        "editors: '#:schema ./scenario.schema.json' in a TOML file)")
    sc.add_argument("--out", default=None, help="write to this file (default: standard output)")
    sc.add_argument("--scenario", default=None, metavar="SCENARIO",
                    help="also give the filters of yours this scenario names by "
                    "'package.module:ClassName' their own variants (settings, types)")
    sc.set_defaults(func=_cmd_schema)

    rp = sub.add_parser("report", help="rebuild the figures and report.md of an existing run "
                        "or campaign directory from its files alone")
    rp.add_argument("run", help="run directory (log.parquet, summary.json, map.bin) or "
                    "campaign directory (results/)")
    rp.add_argument("--out", default=None, help="output folder (default: the directory itself)")
    rp.add_argument("--html", action="store_true",
                    help="also write report.html: one self-contained page, interactive plots")
    rp.set_defaults(func=_cmd_report)

    e = sub.add_parser("export", help="export a run's log to CSV or MATLAB .mat")
    e.add_argument("run", help="run directory or .parquet log")
    fmt = e.add_mutually_exclusive_group(required=True)
    fmt.add_argument("--csv", dest="format", action="store_const", const="csv",
                     help="CSV, one row per step (pyarrow's writer)")
    fmt.add_argument("--mat", dest="format", action="store_const", const="mat",
                     help="MATLAB v5 .mat: data, columns, log struct, metadata")
    e.add_argument("--out", default=None,
                   help="output file (default: the log's path with .csv or .mat)")
    e.add_argument("--no-units", action="store_true",
                   help="CSV: the bare column names as header (default: 'name [unit]' for "
                   "every column with a unit)")
    e.set_defaults(func=_cmd_export)

    ls = sub.add_parser("list", help="list estimators (where each comes from, settings and "
                        "defaults), filter models, the shipped scenarios or the project's FMUs")
    ls.add_argument("what", choices=["estimators", "models", "scenarios", "fmus"],
                    help="what to list")
    ls.add_argument("--scenario", default=None, metavar="SCENARIO",
                    help="estimators: also the filters of yours this scenario names by "
                    "'package.module:ClassName'")
    ls.set_defaults(func=_cmd_list)

    dc = sub.add_parser("docs", help="print where the docs are (a checkout's docs/, or the "
                        "copy an installed wheel carries) and list them")
    dc.set_defaults(func=_cmd_docs)

    d = sub.add_parser("demo", help="build the FMUs into the user cache folder "
                       "($XDG_CACHE_HOME/uwcosim) and run the TAN scenario")
    d.add_argument("--out", default="runs/demo", help="run directory")
    d.add_argument("--seed", type=int, default=None, help="override run.seed")
    d.add_argument("--set", action="append", metavar="KEY=VALUE", help=SET_HELP)
    d.set_defaults(func=_cmd_demo)

    f = sub.add_parser("fmu", help="build and inspect FMUs")
    fs = f.add_subparsers(dest="fmu_command", required=True, metavar="COMMAND")
    b = fs.add_parser("build", help="build the project's FMUs into fmus/")
    b.add_argument("names", nargs="*", help="models or archive stems (default: all), "
                   "see 'uwcosim list fmus'")
    b.add_argument("--out", default="fmus", help="output folder")
    b.add_argument("--force", action="store_true", help="rebuild even if up to date")
    b.add_argument("--spec", action="append", metavar="MODULE:NAME",
                   help="also build your own models through the same tooling: "
                   "'package.module:NAME' (imported from the current folder) is a "
                   "uwcosim.fmu.specs.ModelSpec, a list of them or a function returning either; "
                   "with --spec, only those are built unless names are given too")
    b.set_defaults(func=_cmd_fmu_build)
    i = fs.add_parser("info", help="variables and capabilities of an FMU")
    i.add_argument("fmu", help="FMU archive (.fmu)")
    i.set_defaults(func=_cmd_fmu_info)
    v = fs.add_parser("validate", help="FMI conformance of an FMU: archive, fmpy's validation of "
                      "the standard's rules, a binary for this platform (exit 1 on any finding; "
                      "'fmu check' says whether uwcosim can run it)")
    v.add_argument("fmu", help="FMU archive (.fmu)")
    v.set_defaults(func=_cmd_fmu_validate)
    k = fs.add_parser("check", help="can this FMU play a role? validation, capabilities, "
                      "variable map, smoke run (exit 1 if incompatible; findings of the FMI "
                      "standard's rules are warnings)")
    k.add_argument("fmu", help="FMU archive (.fmu)")
    k.add_argument("--role", choices=["vehicle"], default=None,
                   help="check the roles of this part (and smoke-run a vehicle)")
    k.add_argument("--map", default=None, help="variable map (TOML: role = {var=..., unit=...})")
    k.add_argument("--interface", choices=["cs", "me"], default=None,
                   help="interface of the smoke run (default: co-simulation if available)")
    k.add_argument("--duration", type=float, default=10.0, help="smoke run length (s)")
    k.add_argument("--step", type=float, default=0.5, help="smoke run step (s)")
    k.add_argument("--timeout", type=float, default=30.0, help="time limit per FMU call (s)")
    k.set_defaults(func=_cmd_fmu_check)

    s = sub.add_parser("ssp", help="SSP (System Structure and Parameterization) files")
    ss = s.add_subparsers(dest="ssp_command", required=True)
    e = ss.add_parser("export", help="write the scenario's truth side (FMUs, connections, "
                      "parameters, default experiment) as an .ssp")
    e.add_argument("scenario", help="scenario .toml (or .ssp)")
    e.add_argument("--out", default=None, help="output file (default: ./<scenario name>.ssp)")
    e.add_argument("--ssp-version", choices=("1.0", "2.0"), default="1.0",
                   help="SSP version written: 1.0, or 2.0 (FMI 3 type names on connectors and "
                        "parameters; default: %(default)s)")
    e.add_argument("--set", action="append", metavar="KEY=VALUE", help=SET_HELP)
    e.set_defaults(func=_cmd_ssp_export)

    c = sub.add_parser("campaign", help="Monte Carlo campaign (local processes or Dask)")
    c.add_argument("spec", help="campaign spec (TOML)")
    c.add_argument("--runs", type=int, default=None, help="runs per variant (default: spec)")
    c.add_argument("--workers", type=int, default=None,
                   help="local processes (default: cores; more than the cores are capped)")
    c.add_argument("--oversubscribe", action="store_true",
                   help="start --workers processes even above the number of cores")
    c.add_argument("--scheduler", default=None, help="Dask scheduler, e.g. tcp://host:8786")
    c.add_argument("--out", default=None,
                   help="campaign directory (default: runs/campaign_<spec name>)")
    c.add_argument("--resume", action="store_true", help="skip runs already finished")
    c.set_defaults(func=_cmd_campaign)

    bd = sub.add_parser("bound", help="the posterior Cramér-Rao bound of a scenario (or of "
                        "each variant of a campaign) over N truth runs")
    bd.add_argument("spec", help="scenario .toml, or a campaign spec (.toml with [[variants]])")
    bd.add_argument("--runs", type=int, default=None,
                    help="truth runs (default: 100; a campaign's runs)")
    bd.add_argument("--seed", type=int, default=None,
                    help="seed of the truth runs' seeds (default: run.seed; a campaign's seed)")
    bd.add_argument("--set", action="append", metavar="KEY=VALUE", help=SET_HELP)
    bd.add_argument("--per-run", action="store_true",
                    help="the recursion on each truth run alone, averaged: the bound given each "
                    "run's loss pattern (linear models)")
    bd.add_argument("--out", default=None,
                    help="where bound.parquet and bound.json go (default runs/bound_<name>)")
    bd.set_defaults(func=_cmd_bound)

    def tolerances(parser) -> None:
        parser.add_argument("--rtol", type=float, default=DEFAULT_RTOL,
                            help="value tolerance relative to max|baseline| of each signal")
        parser.add_argument("--atol", type=float, default=DEFAULT_ATOL,
                            help="absolute value tolerance")
        parser.add_argument("--ttol", type=float, default=DEFAULT_TTOL,
                            help="time tolerance (s): width of the tube in time")

    g = sub.add_parser("regress", help="compare a run's log with a baseline log (exit 1 if a "
                       "signal leaves its tolerance tube, 2 on bad input)")
    g.add_argument("run", help="run directory or log.parquet")
    g.add_argument("baseline", help="baseline run directory or .parquet log")
    tolerances(g)
    g.add_argument("--signals", action="append", metavar="GLOB",
                   help="compare only these signals (fnmatch globs; repeatable)")
    g.add_argument("--plots", default=None,
                   help="folder of the diff plots (default: RUN/regress)")
    g.add_argument("--no-plots", action="store_true", help="no diff plots")
    g.add_argument("--allow-shorter", action="store_true",
                   help="pass a baseline that covers less time than the run (compares the "
                   "common span, with a warning line); by default different spans fail")
    g.set_defaults(func=_cmd_regress)

    bl = sub.add_parser("baseline", help="golden baselines of the shipped scenarios")
    bls = bl.add_subparsers(dest="baseline_command", required=True, metavar="COMMAND")
    for name, text in (("update", "regenerate the baselines (a deliberate change)"),
                       ("check", "run the scenarios and compare with their baselines")):
        q = bls.add_parser(name, help=text)
        q.add_argument("scenarios", nargs="*", help="scenario files (default: every *.toml "
                       "of --scenario-dir)")
        q.add_argument("--dir", default=str(baselines_dir(for_update=name == "update")),
                       help="baseline folder")
        q.add_argument("--scenario-dir", default=str(scenarios_dir()),
                       help="folder of the shipped scenarios")
        if name == "update":
            q.add_argument("--set", action="append", metavar="KEY=VALUE",
                           help="extra override (after run.duration=300)")
        else:
            tolerances(q)
            q.add_argument("--plots", default=None, help="folder for diff plots of failures")
        q.set_defaults(func=_cmd_baseline)

    ver = sub.add_parser("verify", help="verification examples")
    ver.add_argument("example", choices=["example1"], help="which example")
    ver.add_argument("--out", default=None, help="output folder (default: runs/verify_example1)")
    ver.set_defaults(func=_cmd_verify)

    comp = sub.add_parser("completion", help="print a shell completion script, e.g. "
                          "'uwcosim completion bash > ~/.local/share/bash-completion/"
                          "completions/uwcosim'")
    comp.add_argument("shell", choices=["bash", "zsh", "tcsh"], help="the shell")
    comp.set_defaults(func=_cmd_completion)
    for parser in walk_parsers(p):
        parser.formatter_class = _HelpFormatter
    return p


def _supervised(args) -> int:
    """``run`` or ``demo`` in a child process whose death in an FMU call is reported (exit 3);
    a campaign supervises its runs itself (:func:`uwcosim.core.supervise.supervised_map`)."""
    from uwcosim.core.supervise import Death, supervise

    result = supervise(lambda: _dispatch(args))
    if not isinstance(result, Death):
        return result
    from uwcosim.core.runguard import signal_name

    if result.forwarded is not None and result.call is None:  # stopped before any FMU ran
        status, code = "interrupted", 128 + result.forwarded
        message = f"interrupted by {signal_name(result.forwarded)}"
    else:
        status, code, message = "failed", 3, result.message()
    if result.out_dir is not None:
        from uwcosim.run.aftermath import finish_dead_run

        message = finish_dead_run(result.out_dir, message, status)
    print(f"uwcosim: error: {message}", file=sys.stderr)
    return code


def _leave(code: int) -> None:
    """The command line's exit once every file is closed: flush, run the exit handlers
    (temporary folders, logging), then end the process without the interpreter's teardown
    (the garbage collection of every module: 0.3-0.9 s after a run). ``UWCOSIM_FAST_EXIT=0``
    keeps the normal exit (a profiler's or coverage's own exit handlers still run either way)."""
    import atexit
    import os

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    if os.environ.get("UWCOSIM_FAST_EXIT", "1") == "0":
        sys.exit(code)
    atexit._run_exitfuncs()
    os._exit(code)


def main(argv: list[str] | None = None, supervise: bool | None = None) -> int:
    """The command line: ``argv`` (default ``sys.argv[1:]``); the exit status. Called without
    ``argv`` (the ``uwcosim`` script, ``python -m uwcosim``) it runs ``run`` in a supervised
    child process (``supervise``, :mod:`uwcosim.core.supervise`) and ends the process itself
    after a ``run``, ``demo`` or ``campaign`` (:func:`_leave`)."""
    code = _main(argv, supervise)
    if argv is None and _COMMAND[0] in ("run", "demo", "campaign"):
        _leave(code)
    return code


_COMMAND = [""]  # the command _main parsed last


def _main(argv: list[str] | None, supervise: bool | None) -> int:
    from uwcosim.core.runguard import install_cli_handlers

    args = build_parser().parse_args(argv)
    _COMMAND[0] = args.command
    level = max(logging.DEBUG, min(logging.WARNING + 10 * (args.quiet - args.verbose),
                                   logging.ERROR))
    logging.basicConfig(format="%(levelname)s %(name)s: %(message)s")
    logging.getLogger().setLevel(level)
    install_cli_handlers()
    for name in ("out", "plots"):
        if getattr(args, name, None) == "":
            print(f"uwcosim: error: --{name} '': an empty path; give a folder or file name",
                  file=sys.stderr)
            return 2
    if args.func in (_cmd_run, _cmd_demo) and (argv is None if supervise is None
                                                else supervise):
        return _supervised(args)
    return _dispatch(args)


def _dispatch(args) -> int:
    from uwcosim.core.runguard import signal_name

    try:
        return int(args.func(args) or 0)
    except UwcosimError as exc:
        print(f"uwcosim: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except OSError as exc:  # an output the system refused (read-only, a folder, disk full)
        line, code = os_error_line(exc)
        print(f"uwcosim: error: {line}", file=sys.stderr)
        return code
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", 2)
        print(f"uwcosim: interrupted by {signal_name(signum)}", file=sys.stderr)
        return 128 + signum


if __name__ == "__main__":
    sys.exit(main())
