"""Command-line interface: a thin layer over the library.

``uwcosim run SCENARIO [--seed N] [--out DIR] [--set key=value ...]``
``uwcosim fmu build|info|validate|check ...``, ``uwcosim regress RUN BASELINE``,
``uwcosim baseline update|check``, ``uwcosim campaign SPEC``, ``uwcosim verify example1``.
User errors are caught once here: one line on stderr, a non-zero exit status, no traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from uwcosim.errors import UwcosimError


def _cmd_run(args) -> int:
    from uwcosim.runner import run_scenario
    from uwcosim.scenario import load_scenario

    loaded = load_scenario(args.scenario, args.set or [])
    out = Path(args.out) if args.out else Path("runs") / loaded.path.stem
    result = run_scenario(loaded, out, seed=args.seed, figures=not args.no_figures)
    from uwcosim.plots.run_figures import results_table

    print(results_table(result.summary), end="")
    t = result.summary["timing"]
    print(f"master overhead {1e6 * t['master_overhead_per_step_s']:.1f} us/step, "
          f"FMUs {1e6 * t['fmus_per_step_s']:.1f} us/step")
    print(f"run directory: {result.out_dir}")
    return 0


def _cmd_fmu_build(args) -> int:
    from uwcosim.fmu.build import build_fmus

    for p in build_fmus(args.out, names=args.names or None, force=args.force):
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
                          args.signals, plot_dir=plots)
    print(report.text())
    return 0 if report.ok else 1


def _cmd_baseline(args) -> int:
    from uwcosim.regress.baselines import (
        DEFAULT_OVERRIDES,
        check_baseline,
        shipped_scenarios,
        update_baseline,
    )

    scenarios = [Path(s) for s in args.scenarios] or shipped_scenarios(args.scenario_dir)
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


def _cmd_summary(args) -> int:
    print(json.dumps(json.loads(Path(args.run, "summary.json").read_text()), indent=2))
    return 0


def _cmd_campaign(args) -> int:
    from uwcosim.campaign import load_campaign
    from uwcosim.campaign.run import run_campaign

    campaign = load_campaign(args.spec)
    out = Path(args.out) if args.out else Path("runs") / f"campaign_{campaign.path.stem}"
    summary = run_campaign(campaign, out, runs=args.runs, workers=args.workers,
                           scheduler=args.scheduler, resume=args.resume)
    print((out / "table.md").read_text() if (out / "table.md").exists() else "no results")
    for f in summary.get("failed", []):
        print(f"failed: {f['variant']} run {f['run']}: {f['error']}", file=sys.stderr)
    print(f"{summary['runs']} runs in {out} ({summary['wall_time_s']:.1f} s)")
    from uwcosim.campaign.execute import session_line

    print(session_line(out))
    return 1 if summary.get("failed") else 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="uwcosim", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run a scenario")
    r.add_argument("scenario")
    r.add_argument("--seed", type=int, default=None, help="override run.seed")
    r.add_argument("--out", default=None, help="run directory (default runs/<scenario name>)")
    r.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override any scenario key, e.g. --set run.duration=100")
    r.add_argument("--no-figures", action="store_true", help="skip figures and report")
    r.set_defaults(func=_cmd_run)

    f = sub.add_parser("fmu", help="build and inspect FMUs")
    fs = f.add_subparsers(dest="fmu_command", required=True)
    b = fs.add_parser("build", help="build the project's FMUs into fmus/")
    b.add_argument("names", nargs="*")
    b.add_argument("--out", default="fmus")
    b.add_argument("--force", action="store_true")
    b.set_defaults(func=_cmd_fmu_build)
    i = fs.add_parser("info", help="variables and capabilities of an FMU")
    i.add_argument("fmu")
    i.set_defaults(func=_cmd_fmu_info)
    v = fs.add_parser("validate", help="validate an FMU (exit 1 if it has problems)")
    v.add_argument("fmu")
    v.set_defaults(func=_cmd_fmu_validate)
    k = fs.add_parser("check", help="can this FMU play a role? validation, capabilities, "
                      "variable map, smoke run (exit 1 if incompatible)")
    k.add_argument("fmu")
    k.add_argument("--role", choices=["vehicle"], default=None,
                   help="check the roles of this part (and smoke-run a vehicle)")
    k.add_argument("--map", default=None, help="variable map (TOML: role = {var=..., unit=...})")
    k.add_argument("--interface", choices=["cs", "me"], default=None,
                   help="interface of the smoke run (default: co-simulation if available)")
    k.add_argument("--duration", type=float, default=10.0, help="smoke run length (s)")
    k.add_argument("--step", type=float, default=0.5, help="smoke run step (s)")
    k.add_argument("--timeout", type=float, default=30.0, help="time limit per FMU call (s)")
    k.set_defaults(func=_cmd_fmu_check)

    c = sub.add_parser("campaign", help="Monte Carlo campaign (local processes or Dask)")
    c.add_argument("spec")
    c.add_argument("--runs", type=int, default=None, help="runs per variant (default: spec)")
    c.add_argument("--workers", type=int, default=None, help="local processes (default: cores)")
    c.add_argument("--scheduler", default=None, help="Dask scheduler, e.g. tcp://host:8786")
    c.add_argument("--out", default=None, help="campaign directory")
    c.add_argument("--resume", action="store_true", help="skip runs already finished")
    c.set_defaults(func=_cmd_campaign)

    from uwcosim.regress.compare import DEFAULT_ATOL, DEFAULT_RTOL, DEFAULT_TTOL

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
    g.set_defaults(func=_cmd_regress)

    bl = sub.add_parser("baseline", help="golden baselines of the shipped scenarios")
    bls = bl.add_subparsers(dest="baseline_command", required=True)
    for name, text in (("update", "regenerate the baselines (a deliberate change)"),
                       ("check", "run the scenarios and compare with their baselines")):
        q = bls.add_parser(name, help=text)
        q.add_argument("scenarios", nargs="*", help="default: every scenarios/*.toml")
        q.add_argument("--dir", default="tests/baselines", help="baseline folder")
        q.add_argument("--scenario-dir", default="scenarios")
        if name == "update":
            q.add_argument("--set", action="append", metavar="KEY=VALUE",
                           help="extra override (after run.duration=300)")
        else:
            tolerances(q)
            q.add_argument("--plots", default=None, help="folder for diff plots of failures")
        q.set_defaults(func=_cmd_baseline)

    ver = sub.add_parser("verify", help="verification examples")
    ver.add_argument("example", choices=["example1"])
    ver.add_argument("--out", default=None)
    ver.set_defaults(func=_cmd_verify)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except UwcosimError as exc:
        print(f"uwcosim: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("uwcosim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
