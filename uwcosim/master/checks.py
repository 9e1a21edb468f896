"""The checks that wire a system to its FMUs: variables, causalities, types, drivers.

:class:`SystemChecks` is a mixin of :class:`~uwcosim.master.master.Master`: each check raises a
one-line :class:`~uwcosim.core.errors.ScenarioError` naming the key, and
:meth:`SystemChecks._collect` records it and goes on, so that ``uwcosim check`` reports every
problem at once. A check about an FMU that could not be opened is skipped (that FMU's problem is
already reported).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from uwcosim.core.errors import ScenarioError, UwcosimError
from uwcosim.fmi import vartypes
from uwcosim.fmi.varmap import connection_affine


class _Skipped(Exception):
    """A check that refers to an FMU that could not be opened (already reported)."""


class SystemChecks:
    """Wiring checks of a master (needs ``system``, ``adapters``, ``slots``, ``out_vars``,
    ``transforms``, ``problems`` and ``_broken``)."""

    def _where(self, key: str) -> str:
        return f"{self.system.where}: key '{key}'"

    @contextmanager
    def _collect(self) -> Iterator[None]:
        """Record a problem of the block in :attr:`problems` and go on with the next check."""
        try:
            yield
        except _Skipped:
            pass
        except UwcosimError as exc:
            self.problems.append(exc)

    def _variable(self, signal: str, key: str):
        """The FMU variable named by ``fmu.variable``, or a one-line ScenarioError."""
        fmu, _, var = signal.partition(".")
        if fmu in self._broken:
            raise _Skipped(signal)
        if fmu not in self.adapters:
            raise ScenarioError(f"{self._where(key)}: unknown FMU {fmu!r} in {signal!r} "
                                f"(FMUs: {', '.join(self.adapters)})")
        v = self.adapters[fmu].variables.get(var)
        if v is None:
            raise ScenarioError(self._no_variable(fmu, var, key))
        return v

    def slot(self, signal: str, key: str) -> int:
        """The bus slot of the output ``signal``, or a one-line ScenarioError naming ``key``."""
        if signal not in self.slots:
            v = self._variable(signal, key)
            what = "an output" if v.causality != "output" else "an output of a supported type"
            raise ScenarioError(f"{self._where(key)}: {signal!r} is not {what} "
                                f"(causality {v.causality!r}, type {v.type})")
        return self.slots[signal]

    def _numeric_slot(self, signal: str, key: str) -> int:
        slot = self.slot(signal, key)
        v = self.out_vars.get(signal)
        if v is not None and vartypes.kind(v) == "string":
            raise ScenarioError(f"{self._where(key)}: {signal!r} is a String output; "
                                f"expected a numeric one")
        return slot

    def _no_variable(self, fmu: str, var: str, key: str) -> str:
        vmap = self.adapters[fmu].varmap
        hint = ""
        if vmap.aliases:
            hint = (f" (fmus.{fmu}.map gives roles {', '.join(vmap.aliases)}; "
                    f"map {var!r} there)")
        return f"{self._where(key)}: FMU {fmu!r} has no variable {var!r}{hint}"

    def _check_input(self, signal: str, key: str, drivers: dict, source: str,
                     float_only: bool = False) -> None:
        v = self._variable(signal, key)
        if v.causality != "input":
            raise ScenarioError(f"{self._where(key)}: {signal!r} has causality "
                                f"{v.causality!r}, expected 'input'")
        if float_only and vartypes.kind(v) != "float":
            raise ScenarioError(f"{self._where(key)}: {signal!r} is of type {v.type}; noise "
                                f"drives only Real/Float inputs")
        if signal in drivers:
            raise ScenarioError(f"{self._where(key)}: input {signal!r} is already driven by "
                                f"{drivers[signal]!r}")
        drivers[signal] = source

    def _check_connection(self, i: int, conn, drivers: dict) -> None:
        src, dst = conn[0], conn[1]
        key = f"connections[{i}]"
        if len(conn) > 2:
            self.transforms[dst] = connection_affine(conn[2], f"{self._where(key)}")
        self.slot(src, key)
        self._check_input(dst, key, drivers, src)
        dvar = self._variable(dst, key)
        svar = self.out_vars.get(src)  # None: a source of the master (a float)
        if svar is None:
            problem = None if vartypes.kind(dvar) == "float" else "expected a Real input"
        else:
            problem = vartypes.connection_problem(svar, dvar)
        if problem:
            if problem.startswith("cannot connect") and " (" in problem:
                problem = problem.split(" (", 1)[1].rstrip(")")  # the names are ours
            raise ScenarioError(
                f"{self._where(key)}: cannot connect {src!r} "
                f"({'Float64' if svar is None else svar.type}) to {dst!r} ({dvar.type}): "
                f"{problem}")
