"""The package's layers (docs/architecture.md): every import points down, checked by
import-linter's contracts (``[tool.importlinter]`` in pyproject.toml), and the rules the
contracts cannot express, checked by reading every import of the package (top level, inside
functions and under ``TYPE_CHECKING``)."""

from __future__ import annotations

import ast
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "uwcosim"
#: the only module whose functions may import uwcosim modules: the command line imports each
#: command's modules when the command runs (start-up laziness)
LAZY_OK = {"uwcosim/cli.py"}


def _imports(tree: ast.AST):
    """``(node, inside a function)`` of every import statement."""
    def walk(node, inside):
        for child in ast.iter_child_nodes(node):
            fn = inside or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            if isinstance(child, ast.Import | ast.ImportFrom):
                yield child, inside
            yield from walk(child, fn)
    yield from walk(tree, False)


def _module_of(path: Path, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)  # a package's: its __init__
    base = parts[:len(parts) - node.level + (path.name == "__init__.py")]
    return ".".join(base + ([node.module] if node.module else []))


def _sources():
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path, ast.parse(path.read_text(encoding="utf-8"))


def test_lint_imports_keeps_every_contract():
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    assert exe is not None, "import-linter is a test dependency (pyproject.toml [test])"
    proc = subprocess.run([exe, "--no-cache"], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert "0 broken" in proc.stdout


def test_no_function_level_import_of_the_package_outside_the_cli():
    found = []
    for path, tree in _sources():
        rel = path.relative_to(ROOT).as_posix()
        for node, inside in _imports(tree):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) \
                else [_module_of(path, node)]
            if inside and rel not in LAZY_OK and any(n.startswith("uwcosim") for n in names):
                found.append(f"{rel}:{node.lineno}")
    assert not found, found


def test_no_private_name_imported_across_modules():
    found = []
    for path, tree in _sources():
        for node, _ in _imports(tree):
            if isinstance(node, ast.ImportFrom) and _module_of(path, node).startswith("uwcosim"):
                private = [a.name for a in node.names
                           if a.name.startswith("_") and not a.name.startswith("__")]
                if private:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno} {private}")
    assert not found, found


@pytest.mark.parametrize("package", ["uwcosim.master", "uwcosim.filters", "uwcosim.models"])
def test_the_lower_layers_load_nothing_above_them(package):
    """Importing the master, the filters or the models (every module of each) loads no module
    of the scenario, run, evaluation, plots, reports or campaign packages."""
    above = ("uwcosim.scenario", "uwcosim.run", "uwcosim.simulation", "uwcosim.evaluation",
             "uwcosim.plots", "uwcosim.reports", "uwcosim.campaign", "uwcosim.api")
    code = (
        "import importlib, json, pkgutil, sys\n"
        f"pkg = importlib.import_module({package!r})\n"
        "for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + '.'):\n"
        "    importlib.import_module(m.name)\n"
        "print(json.dumps(sorted(sys.modules)))\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    loaded = json.loads(proc.stdout.splitlines()[-1])
    bad = [m for m in loaded if m.startswith(above)]
    assert not bad, bad


#: private attributes of other objects read on purpose: of third-party objects without a
#: public way (the standard library's ``os._exit``, argparse's actions, the process pool's
#: processes, killed when a campaign is interrupted) and a new instance of the same class
PRIVATE_READS_OK = {
    ("uwcosim/core/process.py", "os._exit"), ("uwcosim/core/runguard.py", "os._exit"),
    ("uwcosim/core/supervise.py", "os._exit"),
    ("uwcosim/cli.py", "parser._actions"), ("uwcosim/cli.py", "super()._get_help_string"),
    ("uwcosim/cli.py", "argparse._SubParsersAction"),
    ("uwcosim/cli.py", "argparse._VersionAction"),
    ("uwcosim/campaign/execute.py", "getattr(ex, '_processes', None)"),
    ("uwcosim/filters/projection/series.py", "new._cache"),
    # the command line's fast exit: the exit handlers, then no interpreter teardown
    ("uwcosim/cli.py", "atexit._run_exitfuncs"), ("uwcosim/cli.py", "os._exit"),
}


def test_no_private_attribute_of_another_object_is_read():
    """``other._x`` and ``getattr(other, "_x")`` only on ``self``/``cls`` (and the few listed
    third-party cases); a name or string in a tuple passed to ``hasattr`` counts too."""
    found = []
    for path, tree in _sources():
        rel = path.relative_to(ROOT).as_posix()
        for node in ast.walk(tree):
            text = None
            own = isinstance(getattr(node, "value", None), ast.Name) \
                and node.value.id in ("self", "cls")
            if isinstance(node, ast.Attribute) and node.attr.startswith("_") \
                    and not node.attr.startswith("__") and not own:
                text = ast.unparse(node)
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                    and node.func.id in ("getattr", "hasattr", "setattr") and len(node.args) > 1 \
                    and not (isinstance(node.args[0], ast.Name) and node.args[0].id == "self"):
                names = [node.args[1]] if not isinstance(node.args[1], ast.Name) else []
                if any(isinstance(n, ast.Constant) and str(n.value).startswith("_")
                       and not str(n.value).startswith("__") for n in names):
                    text = ast.unparse(node)
            elif isinstance(node, ast.Tuple) and any(
                    isinstance(e, ast.Constant) and isinstance(e.value, str)
                    and e.value.startswith("_") and not e.value.startswith("__")
                    and e.value[1:2].isalpha() for e in node.elts) \
                    and rel.startswith("uwcosim/filters/"):
                text = ast.unparse(node)  # names of attributes probed on a model
            if text is not None and (rel, text) not in PRIVATE_READS_OK:
                found.append(f"{rel}:{node.lineno}: {text}")
    assert not found, found


def test_every_module_has_a_docstring_and_one_concept_of_at_most_800_lines():
    """One concept per module, about 800 lines at most; the docstring says what it holds."""
    long, bare = [], []
    for path, tree in _sources():
        rel = path.relative_to(ROOT).as_posix()
        if len(path.read_text(encoding="utf-8").splitlines()) > 800:
            long.append(rel)
        if not ast.get_docstring(tree):
            bare.append(rel)
    assert not long, long
    assert not bare, bare
