"""Export a scenario's truth side as an SSP 1.0 or 2.0 file (``uwcosim ssp export
[--ssp-version 1.0|2.0]``).

Written: every FMU (``resources/NAME.fmu``) as a component with its interface as the
``implementation``, connectors for its connected variables (type and unit from the FMU),
its parameters and start values as one parameter set ``resources/NAME.ssv``, the connections
(a ``{factor, offset}`` as an ``ssc:LinearTransformation``), and the run's start and stop time
as the DefaultExperiment, with the communication step in an annotation of type
``org.uwcosim`` (SSP 1.0 has no step; other tools ignore the annotation). The archive is
byte-for-byte reproducible (fixed member dates and order).

SSP 1.0 (the default) types connectors and parameter values with SSP 1.0's names (``Real``,
``Integer``, ``Boolean``, ``String``, ``Enumeration``); SSP 2.0 (same namespaces,
``version="2.0"``) with the FMU variable's own type name (FMI 3: ``Float64``, ``Float32``,
``Int8`` ... ``UInt64``; FMI 2: ``Real``, ``Integer``), and array parameters as value lists.

Not written (SSP has no place for them; listed in the returned notes): controls, noise,
sensors, estimators, the bathymetry map file, variable maps, and the master's per-FMU settings
(solver, substeps, rtol, period, timeout).
"""

from __future__ import annotations

import zipfile
from pathlib import Path

from lxml import etree

from uwcosim.core.errors import ScenarioError
from uwcosim.fmi.adapter import read_description
from uwcosim.fmi.varmap import fmu_unit
from uwcosim.scenario.loaded import LoadedScenario
from uwcosim.scenario.ssp.xml import FMU_TYPE, INT_TYPES, NS, REAL_TYPES, UWC_NS

_IMPLEMENTATION = {"cs": "CoSimulation", "me": "ModelExchange"}
_DATE = (1980, 1, 1, 0, 0, 0)


def _element(parent, tag: str, **attrib):
    from lxml import etree

    prefix, _, name = tag.partition(":")
    return etree.SubElement(parent, f"{{{NS[prefix]}}}{name}",
                            {k: v for k, v in attrib.items() if v is not None})


def type_name(var: object, version: str) -> str | None:
    """The SSP type element of an FMU variable: SSP 1.0 names, or (2.0) the variable's own."""
    t = var.type
    if version == "2.0":
        return t if t in (*REAL_TYPES, *INT_TYPES, "Boolean", "String", "Enumeration") else None
    if t in REAL_TYPES:
        return "Real"
    if t in INT_TYPES:
        return "Integer"
    return t if t in ("Boolean", "String", "Enumeration") else None


def _text(x) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    return repr(float(x)) if isinstance(x, float) else str(x)


def _typed(parent, value, var, version: str) -> None:
    """One ``ssv`` value element: typed by the variable (or, without one, by the value)."""
    items = value if isinstance(value, list) else [value]
    t = type_name(var, version) if var is not None else None
    if t is None or (t == "Enumeration" and not isinstance(items[0], str)):
        x = items[0]
        t = ("Boolean" if isinstance(x, bool) else "Integer" if isinstance(x, int) else
             "Real" if isinstance(x, float) else "String")
    if t in REAL_TYPES:
        items = [float(x) for x in items]
    unit = fmu_unit(var) if var is not None and t in REAL_TYPES else None
    if t == "String" and len(items) > 1:
        el = _element(parent, "ssv:String")
        for x in items:
            _element(el, "ssv:Value", value=str(x))
        return
    _element(parent, f"ssv:{t}", value=" ".join(_text(x) for x in items), unit=unit)


def _ssv(name: str, values: dict, variables: dict, version: str) -> bytes:
    root = etree.Element(f"{{{NS['ssv']}}}ParameterSet", {"version": version, "name": name},
                         nsmap={"ssv": NS["ssv"]})
    params = _element(root, "ssv:Parameters")
    for pname, value in values.items():
        p = _element(params, "ssv:Parameter", name=pname)
        _typed(p, value, variables.get(pname), version)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def export_ssp(loaded: LoadedScenario, out: str | Path,
               version: str = "1.0") -> tuple[Path, list[str]]:
    """Write the truth side of ``loaded`` to ``out`` as SSP ``version`` ("1.0" or "2.0");
    return the path and what was left out."""
    if version not in ("1.0", "2.0"):
        raise ScenarioError(f"SSP version {version!r} cannot be written (1.0 or 2.0)")
    spec = loaded.spec
    out = Path(out)
    where = str(loaded.path)
    if spec.replay is not None:
        raise ScenarioError(f"{where}: key 'replay': a replay scenario has no FMU system to "
                            f"export")
    notes: list[str] = []
    for key in ("controls", "noise", "sensors", "estimators"):
        if getattr(spec, key):
            notes.append(f"[{key}] not exported (SSP describes the FMU system only)")
    if spec.map is not None:
        notes.append(f"[map] not exported: set {spec.map.fmu_parameter} in the other tool")
    connected: dict[str, dict[str, str]] = {}
    for c in spec.connections:
        for sig, kind in ((c[0], "output"), (c[1], "input")):
            fmu, _, var = sig.partition(".")
            connected.setdefault(fmu, {})[var] = kind

    root = etree.Element(f"{{{NS['ssd']}}}SystemStructureDescription",
                         {"version": version, "name": spec.name},
                         nsmap={"ssd": NS["ssd"], "ssc": NS["ssc"], "ssv": NS["ssv"]})
    system = _element(root, "ssd:System", name=spec.name, description=spec.description or None)
    elements = _element(system, "ssd:Elements")
    files: list[tuple[str, bytes]] = []
    sources: dict[Path, str] = {}
    for name, f in spec.fmus.items():
        path = loaded.resolve(f.path)
        md = read_description(path)
        variables = {v.name: v for v in md.modelVariables}
        if f.map is not None:
            notes.append(f"fmus.{name}.map not exported (the SSP uses the FMU's own names)")
        dropped = [k for k in ("solver", "substeps", "rtol", "period", "timeout_s")
                   if getattr(f, k) != type(f).__pydantic_fields__[k].default]
        if dropped:
            notes.append(f"fmus.{name}: {', '.join(dropped)} not exported")
        if path not in sources:
            member = f"resources/{path.stem}.fmu"
            if member in {m for m, _ in files}:
                member = f"resources/{name}.fmu"
            sources[path] = member
            files.append((member, path.read_bytes()))
        comp = _element(elements, "ssd:Component", name=name, type=FMU_TYPE,
                        source=sources[path], implementation=_IMPLEMENTATION[f.interface])
        if name in connected:
            conns = _element(comp, "ssd:Connectors")
            for var, kind in connected[name].items():
                v = variables.get(var)
                if v is None:
                    raise ScenarioError(f"{where}: FMU {name!r} has no variable {var!r} "
                                        f"(connections)")
                c = _element(conns, "ssd:Connector", name=var, kind=kind)
                t = type_name(v, version)
                if t is not None:
                    _element(c, f"ssc:{t}", unit=fmu_unit(v) if t in REAL_TYPES else None)
        values = {**f.parameters, **f.start}
        unknown = [k for k in values if k not in variables]
        if unknown and f.map is None:
            raise ScenarioError(f"{where}: fmus.{name}: {', '.join(unknown)}: not variables "
                                f"of the FMU")
        if unknown:
            notes.append(f"fmus.{name}: {', '.join(unknown)} not exported (role names of the "
                         f"variable map)")
            values = {k: v for k, v in values.items() if k in variables}
        arrays = [k for k, v in values.items() if isinstance(v, list) or (
            isinstance(v, int) and not isinstance(v, bool) and not -2**31 <= v < 2**31)]
        if arrays and version == "1.0":
            notes.append(f"fmus.{name}: {', '.join(arrays)} not exported (arrays and integers "
                         f"beyond 32 bits need SSP 2.0: --ssp-version 2.0)")
            values = {k: v for k, v in values.items() if k not in arrays}
        if values:
            member = f"resources/{name}.ssv"
            files.append((member, _ssv(name, values, variables, version)))
            binds = _element(comp, "ssd:ParameterBindings")
            _element(binds, "ssd:ParameterBinding", source=member)
    if spec.connections:
        conns = _element(system, "ssd:Connections")
        for c in spec.connections:
            (se, _, sc), (ee, _, ec) = c[0].partition("."), c[1].partition(".")
            conn = _element(conns, "ssd:Connection", startElement=se, startConnector=sc,
                            endElement=ee, endConnector=ec)
            if len(c) > 2:
                _element(conn, "ssc:LinearTransformation", factor=repr(float(c[2].factor)),
                         offset=repr(float(c[2].offset)))
    run = spec.run
    exp = _element(root, "ssd:DefaultExperiment", startTime=repr(float(run.start_time)),
                   stopTime=repr(float(run.start_time + run.duration)))
    ann = _element(_element(exp, "ssd:Annotations"), "ssc:Annotation", type="org.uwcosim")
    etree.SubElement(ann, f"{{{UWC_NS}}}Experiment", {"stepSize": repr(float(run.step))},
                     nsmap={"uwc": UWC_NS})
    ssd = etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        for member, data in [("SystemStructure.ssd", ssd), *files]:
            zf.writestr(zipfile.ZipInfo(member, _DATE), data, zipfile.ZIP_DEFLATED)
    return out, notes
