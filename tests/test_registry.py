"""The name registries (:mod:`uwcosim.core.registry`): a declared name is imported on its first
lookup; the built-in filters' table names every filter the package registers, with its module."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from uwcosim.core.errors import ScenarioError
from uwcosim.core.registry import Registry

#: the registry the module written by ``fake_module`` registers on (a new one per test)
REGISTRY = Registry("estimator")
#: one element per import of that module
IMPORTS: list[int] = []


@pytest.fixture
def fake_module(tmp_path, monkeypatch):
    """Write a module ``uwc_fake_filters`` that counts its imports and, if asked, registers
    ``fake`` on :data:`REGISTRY`; returns a function giving the number of imports."""

    def install(registers: bool = True):
        body = f"import {__name__} as t\nt.IMPORTS.append(1)\n"
        if registers:
            body += "t.REGISTRY.add('fake', object)\n"
        (tmp_path / "uwc_fake_filters.py").write_text(body)
        monkeypatch.syspath_prepend(str(tmp_path))
        monkeypatch.delitem(sys.modules, "uwc_fake_filters", raising=False)
        monkeypatch.setattr(sys.modules[__name__], "REGISTRY", Registry("estimator"))
        IMPORTS.clear()
        return lambda: len(IMPORTS)

    return install


def test_a_declared_name_is_listed_and_imported_on_its_first_lookup_only(fake_module):
    imports = fake_module()
    reg = REGISTRY
    reg.declare("fake", "uwc_fake_filters")
    assert "fake" in reg and reg.names() == ["fake"] and imports() == 0
    assert reg.loaded() == {}
    assert reg.get("fake") is object and imports() == 1
    assert reg.get("fake") is object and imports() == 1  # once
    assert reg.loaded() == {"fake": object}


def test_load_all_imports_every_declared_module(fake_module):
    imports = fake_module()
    reg = REGISTRY
    reg.declare("fake", "uwc_fake_filters")
    reg.load_all()
    assert imports() == 1 and reg.loaded() == {"fake": object}


def test_a_declared_module_that_does_not_register_its_name_is_an_error(fake_module):
    fake_module(registers=False)
    reg = REGISTRY
    reg.declare("fake", "uwc_fake_filters")
    with pytest.raises(ValueError, match="importing uwc_fake_filters did not register it"):
        reg.get("fake")


def test_a_name_is_declared_once_and_an_unknown_one_lists_the_declared_ones():
    reg = Registry("estimator")
    reg.declare("a", "uwc_nowhere")
    reg.add("b", object)
    with pytest.raises(ValueError, match="declared twice"):
        reg.declare("a", "uwc_elsewhere")
    with pytest.raises(ValueError, match="declared twice"):
        reg.declare("b", "uwc_elsewhere")
    with pytest.raises(ScenarioError, match=r"unknown estimator 'c' \(valid: a, b\)"):
        reg.get("c")


def test_the_built_in_table_names_every_registered_filter_with_its_module():
    """Importing every module of ``uwcosim.filters`` registers exactly the names of
    ``BUILT_IN``, each from the module the table gives (all inside the filters package: the
    registry's imports stay inside the layer that ``lint-imports`` checks)."""
    code = (
        "import importlib, json, pkgutil\n"
        "import uwcosim.filters as pkg\n"
        "for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + '.'):\n"
        "    importlib.import_module(m.name)\n"
        "print(json.dumps({n: c.__module__ for n, c in pkg.ESTIMATORS.loaded().items()}))\n"
        "print(json.dumps(pkg.BUILT_IN))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    registered, table = (json.loads(line) for line in done.stdout.splitlines()[-2:])
    assert registered == table
    assert all(m.startswith("uwcosim.filters.") for m in table.values())
