"""Describe and check FMUs: :func:`fmu_info` (a readable summary) and :func:`validate`.

Works on any FMI 2.0 / 3.0 FMU, not only the ones :mod:`uwcosim.fmu.build` produces.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

from uwcosim.errors import FMUError


def _yes(flag) -> str:
    return "yes" if flag in (True, "true", "1") else "no"


def _check_archive(path: Path) -> list[str]:
    """Problems that make the file unusable as an FMU archive (empty list if readable)."""
    if not path.exists():
        return [f"{path}: file not found"]
    if path.is_dir():
        return [] if (path / "modelDescription.xml").is_file() else [
            f"{path}: folder without modelDescription.xml"]
    try:
        with zipfile.ZipFile(path) as zf:
            bad = zf.testzip()
            if bad is not None:
                return [f"{path}: corrupt archive (member {bad!r} fails its CRC check)"]
            if "modelDescription.xml" not in zf.namelist():
                return [f"{path}: no modelDescription.xml in the archive"]
    except zipfile.BadZipFile as exc:
        return [f"{path}: not a readable FMU archive ({exc})"]
    except (OSError, EOFError, ValueError, NotImplementedError) as exc:
        return [f"{path}: cannot read the archive ({exc})"]
    except Exception as exc:  # noqa: BLE001 - zlib errors of truncated members
        return [f"{path}: corrupt archive ({type(exc).__name__}: {exc})"]
    return []


def _read(path: Path):
    from fmpy import read_model_description

    problems = _check_archive(path)
    if problems:
        raise FMUError(problems[0])
    try:
        return read_model_description(str(path), validate=False)
    except Exception as exc:  # noqa: BLE001 - fmpy raises bare Exceptions
        raise FMUError(f"{path}: cannot read modelDescription.xml ({exc})") from None


def _names(path: Path) -> list[str]:
    if path.is_dir():
        return [p.relative_to(path).as_posix() for p in path.rglob("*") if p.is_file()]
    with zipfile.ZipFile(path) as zf:
        return zf.namelist()


def platform_problems(path: str | Path, md=None) -> list[str]:
    """A problem string if the FMU has no binary for this platform (empty list otherwise)."""
    import fmpy

    path = Path(path)
    md = md or _read(path)
    is_fmi3 = md.fmiVersion.startswith("3")
    plat = fmpy.platform_tuple if is_fmi3 else fmpy.platform
    names = _names(path)
    problems = []
    for iface in (md.modelExchange, md.coSimulation):
        if iface is None:
            continue
        lib = f"binaries/{plat}/{iface.modelIdentifier}{fmpy.sharedLibraryExtension}"
        if lib not in names:
            found = sorted({n.split("/")[1] for n in names
                            if n.startswith("binaries/") and n.count("/") >= 2})
            has = ", ".join(found) if found else "none"
            problems.append(f"{path}: no binary for this platform ({plat}): expected {lib}; "
                            f"binaries in the archive: {has}")
            break
    return problems


def validate(path: str | Path) -> list[str]:
    """Problems found in the FMU at ``path`` (empty list: valid).

    Checks that the archive is readable, fmpy's :func:`fmpy.validation.validate_fmu`
    (XML schema, variable names, ModelStructure, start values, units) and that the FMU has a
    binary for this platform. Never raises for a bad file: problems are returned as strings.
    """
    from fmpy.validation import validate_fmu

    path = Path(path)
    problems = _check_archive(path)
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
    from fmpy import supported_platforms

    path = Path(path)
    md = _read(path)
    lines = [f"{path.name}",
             f"  FMI version       {md.fmiVersion}",
             f"  model name        {md.modelName}"]
    if md.description:
        lines.append(f"  description       {md.description}")
    lines.append(f"  GUID / token      {md.guid}")
    if md.generationTool:
        lines.append(f"  generation tool   {md.generationTool}")
    ifaces = [(name, i) for name, i in (("CoSimulation", md.coSimulation),
                                        ("ModelExchange", md.modelExchange)) if i is not None]
    lines.append("  interfaces        " + ", ".join(
        f"{name} ({i.modelIdentifier})" for name, i in ifaces))
    try:
        plats = ", ".join(supported_platforms(str(path))) or "none"
    except Exception:  # noqa: BLE001
        plats = "unknown"
    lines.append(f"  platforms         {plats}")
    for name, i in ifaces:
        dd = getattr(i, "providesDirectionalDerivatives", None)
        if dd is None:
            dd = i.providesDirectionalDerivative
        caps = [f"get/set state {_yes(i.canGetAndSetFMUstate)}",
                f"serialize state {_yes(i.canSerializeFMUstate)}",
                f"directional derivatives {_yes(dd)}",
                f"several instances {_yes(not i.canBeInstantiatedOnlyOncePerProcess)}"]
        if name == "CoSimulation":
            caps.append(f"variable step {_yes(i.canHandleVariableCommunicationStepSize)}")
        lines.append(f"  {name + ':':<17} " + ", ".join(caps))
    lines.append(f"  continuous states {md.numberOfContinuousStates}, event indicators "
                 f"{md.numberOfEventIndicators}")
    ex = md.defaultExperiment
    if ex is not None:
        lines.append(f"  default experiment start {_fmt(ex.startTime)}, stop "
                     f"{_fmt(ex.stopTime)}, step {_fmt(ex.stepSize)}")
    header = ("name", "causality", "variability", "type", "unit", "start", "vr")
    rows = [header] + [(v.name, _fmt(v.causality), _fmt(v.variability), v.type,
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
