"""The public API: ``from uwcosim import ...`` (light, lazy), ``py.typed``, type hints on the
public functions, and every Python block of the README runs as written."""

from __future__ import annotations

import inspect
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

try:
    from event_fmus import event_fmus  # noqa: F401 - the fixture
except ImportError:  # pragma: no cover
    from tests.event_fmus import event_fmus  # noqa: F401

ROOT = Path(__file__).resolve().parents[1]
API = ("Master", "System", "load_scenario", "run_scenario", "simulate", "evaluate", "report")
#: modules whose every public function and method has type hints
TYPED_MODULES = ("uwcosim", "uwcosim.api", "uwcosim.run.simulate", "uwcosim.run.bank",
                 "uwcosim.run.recorder", "uwcosim.run.density", "uwcosim.run.divergence",
                 "uwcosim.run.factory", "uwcosim.run.preflight", "uwcosim.evaluation.summary",
                 "uwcosim.evaluation.metrics", "uwcosim.reports.run_report",
                 "uwcosim.reports.runfiles", "uwcosim.reports.html", "uwcosim.reports.table",
                 "uwcosim.reports.signal_report", "uwcosim.master.master",
                 "uwcosim.master.system", "uwcosim.master.measurement", "uwcosim.master.node",
                 "uwcosim.master.observer", "uwcosim.master.sources", "uwcosim.master.graph",
                 "uwcosim.runlog.parquet", "uwcosim.runlog.columns", "uwcosim.runlog.rundir",
                 "uwcosim.fmi.vartypes", "uwcosim.fmi.varmap", "uwcosim.fmi.solvers",
                 "uwcosim.fmi.proxy", "uwcosim.fmi.archive", "uwcosim.fmi.adapter",
                 "uwcosim.fmi.binding", "uwcosim.fmi.instance", "uwcosim.fmi.structure",
                 "uwcosim.core.runguard", "uwcosim.core.process",
                 "uwcosim.core.rng", "uwcosim.demo", "uwcosim.plots.run_figures",
                 "uwcosim.plots.html", "uwcosim.plots.signals", "uwcosim.plots.density_figures",
                 "uwcosim.scenario.system", "uwcosim.scenario.overrides",
                 "uwcosim.scenario.ssp.xml", "uwcosim.scenario.ssp.convert",
                 "uwcosim.scenario.ssp.read", "uwcosim.ssp.export", "uwcosim.campaign.report",
                 "uwcosim.campaign.html", "uwcosim.models.states", "uwcosim.verify.example1",
                 "uwcosim.cli")


def test_public_names_import_lazily():
    code = ("import sys, uwcosim; light = 'numpy' not in sys.modules; "
            f"from uwcosim import {', '.join(API)}; "
            "import uwcosim.reports; from uwcosim import report as r2; "
            "print(light, all(callable(f) for f in (report, r2, simulate, evaluate)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.split()
    assert out == ["True", "True"]


def test_py_typed_is_package_data():
    assert (ROOT / "uwcosim" / "py.typed").is_file()
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "py.typed" in data["tool"]["setuptools"]["package-data"]["uwcosim"]


def _public_functions(module):
    for name, obj in vars(module).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
            continue
        if inspect.isfunction(obj):
            yield name, obj
        elif inspect.isclass(obj):
            for n, f in vars(obj).items():
                if inspect.isfunction(f) and (not n.startswith("_") or n in ("__init__",
                                                                               "__call__")):
                    yield f"{name}.{n}", f


def test_public_functions_have_type_hints():
    import importlib

    import uwcosim

    missing = []
    for modname in TYPED_MODULES:
        module = importlib.import_module(modname)
        funcs = list(_public_functions(module))
        if modname == "uwcosim":
            funcs = [(n, getattr(uwcosim, n)) for n in API if inspect.isfunction(
                getattr(uwcosim, n))]
        for name, f in funcs:
            sig = inspect.signature(f)
            bare = [p.name for p in sig.parameters.values()
                    if p.name not in ("self", "cls") and p.annotation is inspect.Parameter.empty
                    and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
            if bare or (sig.return_annotation is inspect.Signature.empty
                        and not name.endswith("__init__")):
                missing.append(f"{modname}:{name} {bare or 'return'}")
    assert not missing, missing


def _python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, re.S | re.M)


def test_readme_python_blocks_run(project_fmus, event_fmus, tmp_path, capsys):
    """Each ```python block of README.md, in order, in a folder with the scenarios and the
    test FMUs the blocks name (``BouncingBall.fmu``, ``Feedthrough.fmu``)."""
    blocks = _python_blocks((ROOT / "README.md").read_text())
    assert len(blocks) >= 3 and any("simulate(" in b and "evaluate(" in b for b in blocks)
    os.symlink(ROOT / "scenarios", tmp_path / "scenarios")
    for model in ("BouncingBall", "Feedthrough"):
        shutil.copy(event_fmus[(model, "3.0")], tmp_path / f"{model}.fmu")
    cwd = Path.cwd()
    os.chdir(tmp_path)
    try:
        for i, block in enumerate(blocks):
            exec(compile(block, f"README.md python block {i + 1}", "exec"), {})
    finally:
        os.chdir(cwd)
    run = tmp_path / "runs" / "api"
    for f in ("log.parquet", "simulation.json", "summary.json", "report.md", "trajectory.png"):
        assert (run / f).is_file(), f
    assert json.loads((run / "summary.json").read_text())["status"] == "ok"


def test_readme_structure_names_existing_paths(project_fmus):
    """Every path in the first column of the README's "Repository structure" table exists."""
    text = (ROOT / "README.md").read_text()
    section = text.split("## Repository structure", 1)[1].split("\n## ", 1)[0]
    paths = [p for line in section.splitlines() if line.startswith("| `")
             for p in re.findall(r"`([^`]+)`", line.split("|")[1])]
    assert len(paths) > 15
    missing = [p for p in paths if not (ROOT / p).exists()]
    assert not missing, f"README's repository structure names missing paths: {missing}"
