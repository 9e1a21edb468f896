"""Everyday commands: --version, -v/-q, help text and defaults, list, completion, and a wheel
installed alone that runs ``uwcosim demo`` with FMUs built into the user cache folder."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import pytest

from uwcosim import __version__
from uwcosim.cli import ANEES_NOTE, build_parser, main, walk_parsers

ROOT = Path(__file__).resolve().parents[1]
ANEES_LINE = ANEES_NOTE


def _uwcosim(*args, cwd=None, env=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "uwcosim", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"uwcosim {__version__}"


def _actions():
    for parser in walk_parsers(build_parser()):
        for action in parser._actions:
            if not isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
                yield parser, action


def test_every_argument_has_help_and_every_default_is_shown():
    seen = 0
    for parser, action in _actions():
        assert action.help, f"{parser.prog}: {action.dest} has no help text"
        seen += 1
        if action.default in (None, False, argparse.SUPPRESS) or action.dest in (
                "version", "verbose", "quiet"):
            continue
        # without white space: argparse wraps long defaults (paths) at spaces and hyphens
        helptext = "".join(parser.format_help().split())
        shown = "".join(str(action.default).split())
        assert f"(default:{shown})" in helptext or "default" in action.help, \
            f"{parser.prog}: default of {action.dest} not shown"
    assert seen > 50


def test_help_says_set_paths_are_relative_to_the_current_folder():
    run = next(p for p in walk_parsers(build_parser()) if p.prog.endswith(" run"))
    assert "relative to the current folder" in " ".join(run.format_help().split())


def test_baseline_paths_do_not_depend_on_the_current_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = build_parser().parse_args(["baseline", "check"])
    assert Path(args.dir) == ROOT / "tests" / "baselines"
    assert Path(args.scenario_dir) == ROOT / "scenarios"


def test_list_estimators_scenarios_fmus(capsys):
    from uwcosim.filters import ESTIMATORS

    assert main(["list", "estimators"]) == 0
    out = capsys.readouterr().out
    for name in ESTIMATORS.names():
        assert f"\n{name}: " in f"\n{out}"
    assert "n_particles=1000" in out and "resampling='systematic'" in out
    assert "rng" not in out
    # the keys of every estimator, listed once before the filters
    head = out.split("\nckf: ")[0]
    for key in ("type", "policy='skip'", "sensors=None", "initial_std=None"):
        assert f"\n    {key}" in head, key
    assert "('extrapolate' | 'skip' | 'zero')" in head
    # descriptions end where their sentence ends, however the docstring wraps them
    assert ("\nrbpf: Marginalized particle filter: particles on the nonlinear states, one "
            "Kalman filter per particle (common covariance) on the linear-Gaussian ones "
            "[built-in]") in out
    for name in ESTIMATORS.names():
        line = next(x for x in out.splitlines() if x.startswith(f"{name}: "))
        text = line[len(name) + 2:line.rindex(" [")]
        doc = " ".join(" ".join((ESTIMATORS.get(name).__doc__ or "").split("\n\n")[0].split()
                                ).split())
        rest = doc[len(text):]
        assert doc.startswith(text) and (rest in ("", ".") or rest.startswith((". ", ".\n"))), \
            (name, text, rest[:20])
    assert main(["list", "scenarios"]) == 0
    out = capsys.readouterr().out
    assert "tan_terrain: AUV with DVL and terrain depth sounder" in out
    assert main(["list", "fmus"]) == 0
    out = capsys.readouterr().out
    assert "AUVKinematics: AUV planar kinematics" in out and "AUVKinematics_fmi2.fmu" in out


def test_verbose_and_quiet_set_the_log_level(project_fmus):
    loud = _uwcosim("-v", "fmu", "build", "--out", str(project_fmus), "AUVKinematics")
    assert loud.returncode == 0 and "INFO uwcosim.fmu.build: " in loud.stderr
    normal = _uwcosim("fmu", "build", "--out", str(project_fmus), "AUVKinematics")
    assert normal.returncode == 0 and "INFO" not in normal.stderr


def test_completion_scripts(capsys):
    assert main(["completion", "bash"]) == 0
    script = capsys.readouterr().out
    for word in ("uwcosim", "report", "export", "campaign", "estimators"):
        assert word in script
    res = subprocess.run(["bash", "-n"], input=script, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert main(["completion", "zsh"]) == 0
    assert "#compdef uwcosim" in capsys.readouterr().out


@pytest.fixture(scope="module")
def wheel_venv(tmp_path_factory):
    """The wheel built from the checkout and installed (``--no-deps --no-index``: no download)
    into a fresh venv that sees the project venv's dependencies through a ``.pth`` line (its
    ``.pth`` files, the editable install among them, are not processed there); the venv's
    ``bin`` folder."""
    import sysconfig

    tmp = tmp_path_factory.mktemp("wheel")
    wheels = tmp / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-build-isolation", "--no-deps",
                    "--no-index", "-q", str(ROOT), "-w", str(wheels)], check=True,
                   capture_output=True, timeout=600)
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True,
                   timeout=120)
    py = venv / "bin" / "python"
    site = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_path("
                                "'purelib'))"], check=True, capture_output=True, text=True
                               ).stdout.strip())
    (site / "project_deps.pth").write_text(sysconfig.get_path("purelib") + "\n")
    subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "-q",
                    "--no-deps", "--no-index", *map(str, wheels.glob("*.whl"))], check=True,
                   capture_output=True, timeout=600)
    return venv / "bin"


def _wheel_env(tmp_path) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    # the numpy kernels: a fresh install has no Numba cache (keyed by the source's path), and
    # its first compile (1-3 min) is not what these tests are about (tests/test_kernel_*.py)
    return {**env, "XDG_CACHE_HOME": str(tmp_path / "cache"),
            "XDG_DATA_HOME": str(tmp_path / "data"), "UWCOSIM_NUMBA": "0"}


def _run(bindir: Path, *args, cwd, env) -> subprocess.CompletedProcess:
    return subprocess.run([str(bindir / "uwcosim"), *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def test_a_wheel_alone_runs_what_it_lists(wheel_venv, tmp_path):
    """From an empty folder, with only the installed wheel: ``list scenarios`` and its paths,
    ``run tan_terrain`` by name (the FMUs built into $XDG_CACHE_HOME on first use, saying so),
    the smoke campaign spec by name, ``baseline check`` on the shipped baselines, ``docs``."""
    env = _wheel_env(tmp_path)
    work = tmp_path / "work"
    work.mkdir()
    where = _run(wheel_venv, "list", "scenarios", cwd=work, env=env)
    assert where.returncode == 0, where.stderr
    listed = [w for w in where.stdout.split() if w.endswith(".toml")]
    data = next(Path(p) for p in listed if p.endswith("tan_terrain.toml")).parent
    assert data.parts[-3:] == ("uwcosim", "_data", "scenarios") and ROOT not in data.parents
    assert {Path(p).name for p in listed} >= {"tan_terrain.toml", "tan_dead_reckoning.toml",
                                             "lost_measurements.toml"}

    res = _run(wheel_venv, "run", "tan_terrain", "--set", "run.duration=10", "--no-figures",
               cwd=work, env=env)
    assert res.returncode == 0, res.stderr
    cache = tmp_path / "cache" / "uwcosim"
    assert f"building the project's FMUs AUVKinematics.fmu, DVL.fmu, DepthSounder.fmu into " \
        f"{cache / 'fmus'}" in res.stderr
    assert "| point_mass |" in res.stdout and ANEES_LINE in res.stdout
    assert f"run directory: {work / 'runs' / 'tan_terrain'}\n" in res.stdout
    for path in listed:  # every listed path runs (the FMUs are in place now: no build line)
        res = _run(wheel_venv, "run", path, "--set", "run.duration=3", "--no-figures",
                   "--out", str(work / "runs" / "listed"), "--force", cwd=work, env=env)
        assert res.returncode == 0, (path, res.stderr)
        assert ("building" in res.stderr) == path.endswith("lost_measurements.toml"), path

    camp = _run(wheel_venv, "campaign", "smoke", "--runs", "1", "--workers", "1", cwd=work,
                env=env)
    assert camp.returncode == 0, camp.stderr
    assert "with_terrain" in camp.stdout and "2 runs in runs/campaign_smoke" in camp.stdout

    base = _run(wheel_venv, "baseline", "check", "tan_dead_reckoning", cwd=work, env=env)
    assert base.returncode == 0, base.stdout + base.stderr
    assert "_data/baselines" in base.stderr and "signals pass" in base.stdout

    docs = _run(wheel_venv, "docs", cwd=work, env=env)
    assert docs.returncode == 0 and "architecture.md" in docs.stdout
    assert (Path(docs.stdout.split()[1]) / "README.md").is_file()
    meta = subprocess.run([str(wheel_venv / "python"), "-c", "import importlib.metadata as m; "
                           "print(m.metadata('uwcosim').get_all('Project-URL'))"],
                          capture_output=True, text=True, env=env, cwd=work)
    assert "Source, https://" in meta.stdout and "Documentation, https://" in meta.stdout
    assert sorted(p.name for p in work.iterdir()) == ["runs"]


def test_a_wheel_alone_runs_the_demo(wheel_venv, tmp_path):
    """``uwcosim demo`` from the installed wheel: the scenarios come from the package data, the
    FMUs are built into $XDG_CACHE_HOME; the output names the absolute run folder and what to
    open in it."""
    env = _wheel_env(tmp_path)
    work = tmp_path / "work"
    work.mkdir()
    res = _run(wheel_venv, "demo", "--set", "run.duration=20", cwd=work, env=env)
    assert res.returncode == 0, res.stderr
    run_dir = work / "runs" / "demo"
    assert "| point_mass |" in res.stdout and f"run directory: {run_dir}\n" in res.stdout
    assert "open: report.md, trajectory.png, position_error.png" in res.stdout
    cache = tmp_path / "cache" / "uwcosim"
    assert {p.name for p in (cache / "fmus").glob("*.fmu")} >= {
        "AUVKinematics.fmu", "DVL.fmu", "DepthSounder.fmu"}
    assert (run_dir / "report.md").is_file()
    assert sorted(p.name for p in work.iterdir()) == ["runs"]
    for stage in ("simulating 20 steps", "evaluating", "figures"):
        assert f"uwcosim: {stage}" in res.stderr, res.stderr


def test_campaign_checks_its_fmus_before_any_worker_starts(tmp_path, project_fmus):
    """A variant whose FMU is missing (and not one of the project's, so not built): one line,
    exit 3, no run started."""
    scen = (ROOT / "scenarios" / "tan_dead_reckoning.toml").read_text()
    scen = scen.replace("../fmus/DVL.fmu", str(tmp_path / "X.fmu"))
    (tmp_path / "s.toml").write_text(scen.replace('"../fmus/', f'"{project_fmus}/'))
    (tmp_path / "c.toml").write_text('name = "c"\nruns = 1\n[[variants]]\nname = "v"\n'
                                     'scenario = "s.toml"\n')
    res = _uwcosim("campaign", str(tmp_path / "c.toml"), "--out", str(tmp_path / "out"),
                   cwd=tmp_path)
    assert res.returncode == 3, res.stderr
    assert res.stderr.strip().splitlines() == [
        f"uwcosim: error: {tmp_path / 'X.fmu'}: FMU not found (variant scenarios of "
        f"{tmp_path / 'c.toml'} need 1 missing FMU; nothing was run)"]
    assert not (tmp_path / "out").exists()


def test_the_commands_of_the_docs_parse():
    """Every ``$ uwcosim ...`` line of the README and docs/bring_your_own_fmu.md is valid."""
    import shlex

    parser = build_parser()
    lines = []
    for doc in (ROOT / "README.md", ROOT / "docs" / "bring_your_own_fmu.md"):
        for line in doc.read_text().splitlines():
            line = line.strip()
            if line.startswith("$ uwcosim "):
                lines.append(line[2:])
    assert len(lines) >= 6
    for line in lines:
        parser.parse_args(shlex.split(line)[1:])


def test_fmu_validate_and_check_say_why_both_hold(capsys):
    """pythonfmu leaves ModelStructure/InitialUnknowns empty: ``fmu validate`` (conformance)
    exits 1, ``fmu check`` (can uwcosim run it) calls it compatible; each says why."""
    pytest.importorskip("pythonfmu")
    try:
        from thirdparty_fmus import PYFMU_DIR, build_pythonfmu_vehicle
    except ImportError:
        from tests.thirdparty_fmus import PYFMU_DIR, build_pythonfmu_vehicle
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        fmu = str(build_pythonfmu_vehicle(Path(tmp)))
        assert main(["fmu", "validate", fmu]) == 1
        err = capsys.readouterr().err
        assert "InitialUnknowns" in err
        assert err.splitlines()[-1].startswith(f"{fmu}: not valid: ")
        assert "'uwcosim fmu check' lists the findings of the FMI standard's rules as " \
            "warnings" in err
        assert main(["fmu", "check", fmu, "--role", "vehicle", "--map",
                     str(PYFMU_DIR / "map.toml")]) == 0
        out = capsys.readouterr().out
        assert "result: compatible, with " in out and "finding" in out
        assert "'uwcosim fmu validate', a conformance check, exits 1 on them" in out


def test_fast_exit_keeps_the_exit_code_and_closed_files(tmp_path, project_fmus):
    """``run`` ends with ``os._exit`` after its files are closed: the exit status of a user
    error (2) and of a good run (0), a readable log, the stdout printed in full."""
    bad = _uwcosim("run", "lost_measurements", "--set", "run.duration=-1", "--out",
                   str(tmp_path / "bad"))
    assert bad.returncode == 2 and bad.stderr.startswith("uwcosim: error: "), bad.stderr
    ok = _uwcosim("run", "lost_measurements", "--set", "run.duration=5", "--no-figures",
                  "--out", str(tmp_path / "ok"))
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.rstrip().splitlines()[-3:] == [
        f"run directory: {tmp_path / 'ok'}", "open: summary.json, log.parquet",
        f"figures and report: uwcosim report {tmp_path / 'ok'} [--html]"]
    from uwcosim.runlog import read_log

    cols, _ = read_log(tmp_path / "ok" / "log.parquet")
    assert len(cols["time"]) == 6 and not (tmp_path / "ok" / "log.parquet.journal").exists()
