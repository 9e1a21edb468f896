"""``modelDescription.xml`` (FMI 2.0 and FMI 3.0) of a :class:`~uwcosim.fmu.specs.ModelSpec`.

Both interfaces (ModelExchange and CoSimulation) share one binary and one model identifier.
Variables: ``time`` (independent), states (causality output, initial exact: their start values
are settable before initialization), their derivatives ``der(s)`` (local), inputs, parameters,
calculated parameters, outputs and String parameters; the ModelStructure lists outputs,
derivatives and initial unknowns with the dependencies from the CasADi Jacobian sparsity.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import casadi

from uwcosim.core.version import __version__
from uwcosim.fmu.specs import UNITS, ModelSpec, Variable, dependencies, layout

_CAUSALITY = {
    "time": ("independent", "continuous", None),
    "state": ("output", "continuous", "exact"),
    "der": ("local", "continuous", "calculated"),
    "input": ("input", "continuous", None),
    "param": ("parameter", "fixed", "exact"),
    "tunable": ("parameter", "tunable", "exact"),
    "calc": ("calculatedParameter", "fixed", "calculated"),
    "output": ("output", "continuous", "calculated"),
    "string": ("parameter", "fixed", "exact"),
}

_LOG_CATEGORIES = (
    ("logStatusError", "Errors (always reported)"),
    ("logStatusWarning", "Warnings (always reported)"),
    ("logAll", "Informational messages (when logging is on)"),
)


def _num(v: float) -> str:
    return repr(float(v))


def generation_tool() -> str:
    return f"uwcosim {__version__} (CasADi {casadi.__version__})"


def _structure(spec: ModelSpec, variables: list[Variable]):
    """(outputs, derivatives, initial unknowns) as lists of (variable, [dependency vars])."""
    by_name = {v.name: v for v in variables}
    deps = dependencies(spec)

    def resolve(names: list[str]) -> list[Variable]:
        return sorted((by_name[n] for n in names), key=lambda v: v.vr)

    outputs, derivatives, initial = [], [], []
    for v in variables:
        if v.kind == "state":
            outputs.append((v, [v]))
        elif v.kind == "output":
            outputs.append((v, resolve(deps[v.name][0])))
        if v.kind == "der":
            derivatives.append((v, resolve(deps[v.name][0])))
        if v.kind in ("der", "output", "calc"):
            initial.append((v, resolve(deps[v.name][1])))
    return outputs, derivatives, initial


def _units(root: ET.Element, variables: list[Variable]) -> None:
    used = sorted({v.unit for v in variables if v.unit})
    if not used:
        return
    defs = ET.SubElement(root, "UnitDefinitions")
    for name in used:
        unit = ET.SubElement(defs, "Unit", name=name)
        ET.SubElement(unit, "BaseUnit", {k: str(e) for k, e in UNITS[name].items()})


def _log_categories(root: ET.Element) -> None:
    cats = ET.SubElement(root, "LogCategories")
    for name, description in _LOG_CATEGORIES:
        ET.SubElement(cats, "Category", name=name, description=description)


def _experiment(root: ET.Element, spec: ModelSpec) -> None:
    ET.SubElement(root, "DefaultExperiment", startTime="0.0", stopTime=_num(spec.stop_time),
                  stepSize=_num(spec.step_size))


def _var_attrs(v: Variable) -> dict[str, str]:
    causality, variability, initial = _CAUSALITY[v.kind]
    attrs = {"name": v.name, "valueReference": str(v.vr)}
    if v.description:
        attrs["description"] = v.description
    attrs["causality"] = causality
    attrs["variability"] = variability
    if initial is not None:
        attrs["initial"] = initial
    return attrs


def _interfaces(root: ET.Element, spec: ModelSpec, fmi3: bool) -> None:
    state = "FMUState" if fmi3 else "FMUstate"
    common = {
        "modelIdentifier": spec.name,
        "canBeInstantiatedOnlyOncePerProcess": "false",
        f"canGetAndSet{state}": "true",
        f"canSerialize{state}": "true",
    }
    if fmi3:
        me = {**common, "providesDirectionalDerivatives": "false",
              "needsCompletedIntegratorStep": "false"}
        cs = {**common, "providesDirectionalDerivatives": "false",
              "canHandleVariableCommunicationStepSize": "true",
              "providesIntermediateUpdate": "false", "hasEventMode": "false"}
    else:
        extra = {"canNotUseMemoryManagementFunctions": "true",
                 "providesDirectionalDerivative": "false"}
        me = {**common, **extra, "completedIntegratorStepNotNeeded": "true"}
        cs = {**common, **extra, "canHandleVariableCommunicationStepSize": "true",
              "canInterpolateInputs": "false"}
    ET.SubElement(root, "ModelExchange", me)
    ET.SubElement(root, "CoSimulation", cs)


def model_description_fmi2(spec: ModelSpec, guid: str) -> str:
    variables = layout(spec)
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": spec.name, "guid": guid,
        "description": spec.description, "generationTool": generation_tool(),
        "variableNamingConvention": "flat", "numberOfEventIndicators": "0",
    })
    _interfaces(root, spec, fmi3=False)
    _units(root, variables)
    _log_categories(root)
    _experiment(root, spec)
    mv = ET.SubElement(root, "ModelVariables")
    index = {}
    for i, v in enumerate(variables, start=1):
        index[v.vr] = i
        sv = ET.SubElement(mv, "ScalarVariable", _var_attrs(v))
        if v.kind == "string":
            ET.SubElement(sv, "String", start=str(v.start))
            continue
        attrs = {}
        if v.unit:
            attrs["unit"] = v.unit
        if v.start is not None and v.kind != "time":
            attrs["start"] = _num(v.start)
        if v.state_vr is not None:
            attrs["derivative"] = str(index[v.state_vr])
        ET.SubElement(sv, "Real", attrs)
    outputs, derivatives, initial = _structure(spec, variables)
    ms = ET.SubElement(root, "ModelStructure")
    for tag, unknowns in (("Outputs", outputs), ("Derivatives", derivatives),
                          ("InitialUnknowns", sorted(initial, key=lambda e: e[0].vr))):
        if not unknowns:
            continue
        group = ET.SubElement(ms, tag)
        for v, deps in unknowns:
            ET.SubElement(group, "Unknown", index=str(index[v.vr]),
                          dependencies=" ".join(str(index[d.vr]) for d in deps))
    return _serialize(root)


def model_description_fmi3(spec: ModelSpec, token: str) -> str:
    variables = layout(spec)
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "3.0", "modelName": spec.name, "instantiationToken": token,
        "description": spec.description, "generationTool": generation_tool(),
        "variableNamingConvention": "flat",
    })
    _interfaces(root, spec, fmi3=True)
    _units(root, variables)
    _log_categories(root)
    _experiment(root, spec)
    mv = ET.SubElement(root, "ModelVariables")
    for v in variables:
        attrs = _var_attrs(v)
        if v.kind == "string":
            ET.SubElement(ET.SubElement(mv, "String", attrs), "Start", value=str(v.start))
            continue
        if v.unit:
            attrs["unit"] = v.unit
        if v.start is not None and v.kind != "time":
            attrs["start"] = _num(v.start)
        if v.state_vr is not None:
            attrs["derivative"] = str(v.state_vr)
        ET.SubElement(mv, "Float64", attrs)
    outputs, derivatives, initial = _structure(spec, variables)
    ms = ET.SubElement(root, "ModelStructure")
    for tag, unknowns in (("Output", outputs), ("ContinuousStateDerivative", derivatives),
                          ("InitialUnknown", initial)):
        for v, deps in unknowns:
            ET.SubElement(ms, tag, valueReference=str(v.vr),
                          dependencies=" ".join(str(d.vr) for d in deps))
    return _serialize(root)


def model_description(spec: ModelSpec, fmi_version: str, guid: str) -> str:
    """``modelDescription.xml`` text for ``fmi_version`` "2.0" or "3.0"."""
    if fmi_version == "2.0":
        return model_description_fmi2(spec, guid)
    return model_description_fmi3(spec, guid)


def _serialize(root: ET.Element) -> str:
    ET.indent(root, space="  ")
    text = ET.tostring(root, encoding="unicode")
    return f'<?xml version="1.0" encoding="UTF-8"?>\n{text}\n'
