"""The FMI layer, the master and the FMU tools keep their imports pointing down (issue 19).

Read from the source (``ast``: imports at the top, inside functions and under
``TYPE_CHECKING``): ``uwcosim.fmi`` imports only ``uwcosim.core`` and itself, ``uwcosim.master``
only ``core``, ``fmi`` and itself; none of these packages, nor the FMU tools or the SSP reader,
imports a module of ours inside a function, imports a private name of another module, or reads
a private attribute of another object; a third-party import inside a function says why it is
lazy. And at run time: importing the FMI layer loads nothing above it, nor fmpy.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "uwcosim"
#: package -> the uwcosim packages it may import
ALLOWED = {"fmi": ("core", "fmi"), "master": ("core", "fmi", "master")}
#: where no function-level import of ours, no private import and no private read is allowed
CLEAN = [*sorted((PKG / "fmi").glob("*.py")), *sorted((PKG / "master").glob("*.py")),
         *sorted((PKG / "fmu").glob("*.py")), PKG / "scenario" / "ssp" / "read.py"]


def _tree(path: Path) -> ast.Module:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        for child in ast.iter_child_nodes(node):
            child.parent = node  # type: ignore[attr-defined]
    return tree


def _in_function(node: ast.AST) -> bool:
    p = getattr(node, "parent", None)
    while p is not None:
        if isinstance(p, ast.FunctionDef | ast.AsyncFunctionDef):
            return True
        p = getattr(p, "parent", None)
    return False


def _modules(node: ast.Import | ast.ImportFrom) -> list[str]:
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    return [node.module or ""]


def _imports(path: Path):
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_imports_point_down(package):
    bad = []
    for path in sorted((PKG / package).glob("*.py")):
        for node in _imports(path):
            for mod in _modules(node):
                parts = mod.split(".")
                if parts[0] == "uwcosim" and (len(parts) < 2 or parts[1] not in ALLOWED[package]):
                    bad.append(f"{path.relative_to(ROOT)}:{node.lineno}: {mod}")
    assert not bad, "imports pointing up:\n" + "\n".join(bad)


def test_no_function_level_import_of_ours_and_lazy_ones_say_why():
    ours, silent = [], []
    for path in CLEAN:
        lines = path.read_text(encoding="utf-8").splitlines()
        for node in _imports(path):
            if not _in_function(node):
                continue
            where = f"{path.relative_to(ROOT)}:{node.lineno}"
            if any(m.split(".")[0] == "uwcosim" for m in _modules(node)):
                ours.append(where)
                continue
            body = node.parent.body  # type: ignore[attr-defined]
            i = body.index(node)
            while i > 0 and isinstance(body[i - 1], ast.Import | ast.ImportFrom):
                i -= 1  # a run of imports: the reason is given once, at its first
            first = body[i].lineno
            if not any("lazy" in lines[k - 1] for k in (first - 1, first, node.lineno)):
                silent.append(where)
    assert not ours, "function-level imports of uwcosim modules:\n" + "\n".join(ours)
    assert not silent, "lazy imports without a reason ('# lazy: ...'):\n" + "\n".join(silent)


def test_no_private_name_or_attribute_of_another_module_or_object():
    bad = []
    for path in CLEAN:
        for node in ast.walk(_tree(path)):
            where = f"{path.relative_to(ROOT)}:{node.lineno}" if hasattr(node, "lineno") else ""
            if isinstance(node, ast.ImportFrom):
                bad += [f"{where}: from {node.module} import {a.name}" for a in node.names
                        if a.name.startswith("_") and not a.name.startswith("__")]
            elif (isinstance(node, ast.Attribute) and node.attr.startswith("_")
                  and not node.attr.startswith("__")
                  and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))):
                bad.append(f"{where}: {ast.unparse(node)}")
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                  and node.func.id in ("getattr", "hasattr") and len(node.args) > 1
                  and isinstance(node.args[1], ast.Constant)
                  and str(node.args[1].value).startswith("_")):
                bad.append(f"{where}: {ast.unparse(node)}")
    assert not bad, "private access across modules or objects:\n" + "\n".join(bad)


def test_importing_the_fmi_layer_loads_nothing_above_it():
    code = ("import sys; import uwcosim.fmi.adapter, uwcosim.fmi.proxy, uwcosim.fmi.solvers; "
            "print(sorted(m for m in sys.modules if m.startswith('uwcosim.') and "
            "m.split('.')[1] not in ('core', 'fmi')), 'fmpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.strip()
    assert out == "[] False"


def test_the_instance_handle_gives_the_functions_fmpy_loaded(project_fmus):
    """Instance.function reads the C functions from the library (fmpy's public ``dll``): the
    very objects fmpy declared the argument types of (its private table, read here only)."""
    from uwcosim.fmi.adapter import FMUAdapter

    for name, interface in (("AUVKinematics", "me"), ("DVL_fmi2", "cs")):
        ad = FMUAdapter("probe", ROOT / "fmus" / f"{name}.fmu", interface)
        try:
            ad.instantiate({}, {}, 0.0, 1.0)
            inst = ad.instance
            loaded = inst.fmu._functions
            assert loaded and all(inst.function(n) is f for n, f in loaded.items())
        finally:
            ad.close()
        assert ad.instance is None
