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
from uwcosim.cli import build_parser, main, walk_parsers

ROOT = Path(__file__).resolve().parents[1]


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


def test_a_wheel_alone_runs_the_demo(project_fmus, tmp_path):
    """Build the wheel, install it into an empty folder, run ``uwcosim demo`` from elsewhere:
    the scenarios come from the package data, the FMUs are built into $XDG_CACHE_HOME."""
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-build-isolation", "--no-deps",
                    "-q", str(ROOT), "-w", str(wheels)], check=True, capture_output=True,
                   timeout=600)
    site = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target",
                    str(site), *map(str, wheels.glob("*.whl"))], check=True,
                   capture_output=True, timeout=600)
    assert (site / "uwcosim" / "_data" / "scenarios" / "tan_terrain.toml").is_file()
    assert (site / "uwcosim" / "fmu" / "templates" / "uwc_model.c").is_file()
    work = tmp_path / "work"
    work.mkdir()
    env = {**os.environ, "PYTHONPATH": str(site), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    where = _uwcosim("list", "scenarios", cwd=work, env=env)
    assert str(site / "uwcosim" / "_data" / "scenarios" / "tan_terrain.toml") in where.stdout
    res = _uwcosim("demo", "--set", "run.duration=20", cwd=work, env=env)
    assert res.returncode == 0, res.stderr
    assert "| point_mass |" in res.stdout and "run directory: runs/demo" in res.stdout
    cache = tmp_path / "cache" / "uwcosim"
    assert {p.name for p in (cache / "fmus").glob("*.fmu")} >= {
        "AUVKinematics.fmu", "DVL.fmu", "DepthSounder.fmu"}
    assert (work / "runs" / "demo" / "report.md").is_file()
    assert sorted(p.name for p in work.iterdir()) == ["runs"]


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
