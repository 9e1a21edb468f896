"""Describe and check FMUs: :func:`fmu_info` (a readable summary), :func:`validate` and
:func:`platform_problems`.

Works on any FMI 2.0 / 3.0 FMU, not only the ones :mod:`uwcosim.fmu.build` produces. The
archive checks are those of the master (:mod:`uwcosim.fmi.archive`).
"""

from __future__ import annotations

from pathlib import Path

from fmpy import supported_platforms
from fmpy.validation import validate_fmu

from uwcosim.core.errors import FMUError
from uwcosim.fmi.archive import archive_problems, binary_problems, open_archive
from uwcosim.fmi.features import clock_variables, missing_features
from uwcosim.fmi.vartypes import describe


def _yes(flag) -> str:
    return "yes" if flag in (True, "true", "1") else "no"


def platform_problems(path: str | Path, md=None) -> list[str]:
    """A problem string if the FMU has no binary for this platform (empty list otherwise)."""
    path = Path(path)
    return binary_problems(path, md or open_archive(path))


def validate(path: str | Path) -> list[str]:
    """Problems found in the FMU at ``path`` (empty list: valid).

    Checks that the archive is readable, fmpy's :func:`fmpy.validation.validate_fmu`
    (XML schema, variable names, ModelStructure, start values, units) and that the FMU has a
    binary for this platform. Never raises for a bad file: problems are returned as strings.
    """
    path = Path(path)
    problems = archive_problems(path)
    if problems:
        return problems
    try:
        problems = [f"{path.name}: {p}" for p in validate_fmu(str(path))]
    except Exception as exc:  # noqa: BLE001 - fmpy raises bare Exceptions
        return [f"{path}: validation failed ({exc})"]
    if problems:
        return problems
    try:
        return platform_problems(path)
    except FMUError as exc:
        return [str(exc)]


def _fmt(v) -> str:
    return "" if v is None else str(v)


def fmu_info(path: str | Path) -> str:
    """A readable summary of the FMU: FMI version, interfaces, capabilities, variables."""
    path = Path(path)
    md = open_archive(path)
    lines = [f"{path.name}",
             f"  FMI version       {md.fmiVersion}",
             f"  model name        {md.modelName}"]
    if md.description:
        lines.append(f"  description       {md.description}")
    lines.append(f"  GUID / token      {md.guid or '(none: FMI 2.0 and 3.0 require one)'}")
    if md.generationTool:
        lines.append(f"  generation tool   {md.generationTool}")
    ifaces = [(name, i) for name, i in (("CoSimulation", md.coSimulation),
                                        ("ModelExchange", md.modelExchange),
                                        ("ScheduledExecution",
                                         getattr(md, "scheduledExecution", None)))
              if i is not None]
    lines.append("  interfaces        " + ", ".join(
        f"{name} ({i.modelIdentifier})" for name, i in ifaces))
    try:
        plats = ", ".join(supported_platforms(str(path))) or "none"
    except Exception:  # noqa: BLE001
        plats = "unknown"
    lines.append(f"  platforms         {plats}")
    missing = binary_problems(path, md)
    lines.append("  this platform     " + ("binary ok" if not missing else
                                          missing[0].split(": ", 1)[1]))
    for name, i in ifaces:
        dd = getattr(i, "providesDirectionalDerivatives", None)
        if dd is None:
            dd = getattr(i, "providesDirectionalDerivative", None)
        caps = [f"get/set state {_yes(i.canGetAndSetFMUstate)}",
                f"serialize state {_yes(i.canSerializeFMUstate)}",
                f"directional derivatives {_yes(dd)}",
                f"several instances {_yes(not i.canBeInstantiatedOnlyOncePerProcess)}"]
        if name == "CoSimulation":
            caps.append(f"variable step {_yes(i.canHandleVariableCommunicationStepSize)}")
            if md.fmiVersion.startswith("3"):
                caps.append(f"event mode {_yes(getattr(i, 'hasEventMode', False))}")
        lines.append(f"  {name + ':':<17} " + ", ".join(caps))
    clocks = clock_variables(md)
    if clocks:
        lines.append(f"  clocks            {', '.join(clocks)}")
    needs = missing_features(md)
    lines.append("  uwcosim can run   " + ("yes (from the model description; 'uwcosim fmu check' "
                                          "also loads the binary)" if not needs and not missing
                                          else
                                          "no: " + "; ".join(needs or [missing[0]])))
    lines.append(f"  continuous states {md.numberOfContinuousStates}, event indicators "
                 f"{md.numberOfEventIndicators}")
    ex = md.defaultExperiment
    if ex is not None:
        lines.append(f"  default experiment start {_fmt(ex.startTime)}, stop "
                     f"{_fmt(ex.stopTime)}, step {_fmt(ex.stepSize)}")
    header = ("name", "causality", "variability", "type", "unit", "start", "vr")
    rows = [header] + [(v.name, _fmt(v.causality), _fmt(v.variability), describe(v),
                        _fmt(v.unit or (v.declaredType.unit if v.declaredType else None)),
                        repr(v.start) if v.type == "String" and v.start is not None
                        else _fmt(v.start), str(v.valueReference))
                       for v in md.modelVariables]
    widths = [max(len(r[k]) for r in rows) for k in range(len(header))]
    lines.append(f"  variables ({len(md.modelVariables)}):")
    for r in rows:
        cells = (c.ljust(w) for c, w in zip(r, widths, strict=True))
        lines.append(("    " + "  ".join(cells)).rstrip())
    return "\n".join(lines)
