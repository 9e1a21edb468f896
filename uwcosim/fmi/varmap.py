"""Variable maps: expose a third-party FMU under our role names, in our units and conventions.

A map gives, for each *role* (``x``, ``psi``...), the FMU variable that plays it and an affine
conversion ``ours = scale * theirs + offset``. The scale and offset come from

- ``unit`` (the FMU's unit; by default the unit the FMU declares) converted to the role's unit
  through :data:`UNITS` or, for a unit we do not know, through the FMU's own UnitDefinitions
  (base-unit exponents, factor and offset);
- or an explicit ``scale`` (then no unit conversion is done);
- then ``negate`` (conventions: clockwise against counter-clockwise, starboard against port)
  and ``offset`` (in our units; a number or a string such as ``"pi/2"``).

Heading clockwise from north in degrees, for example, is
``psi = {var = "heading", unit = "deg", negate = true, offset = "pi/2"}``:
``psi = pi/2 - heading * pi/180``.

A map is a TOML file (one key per role) or an inline table ``[fmus.NAME.map]``.
:func:`resolve_map` checks it against the model description and returns a
:class:`VariableMap` and the list of problems (empty when the map is usable).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fmpy.model_description import ModelDescription, ModelVariable


from uwcosim.core.errors import ScenarioError
from uwcosim.core.tomlfile import read_toml

#: our units and the FMU units we convert: name -> (factor to the SI unit, SI unit)
UNITS: dict[str, tuple[float, str]] = {
    "m": (1.0, "m"), "km": (1000.0, "m"), "ft": (0.3048, "m"), "nmi": (1852.0, "m"),
    "cm": (0.01, "m"),
    "rad": (1.0, "rad"), "deg": (math.pi / 180.0, "rad"),
    "m/s": (1.0, "m/s"), "km/h": (1.0 / 3.6, "m/s"), "ft/s": (0.3048, "m/s"),
    "knots": (1852.0 / 3600.0, "m/s"), "cm/s": (0.01, "m/s"), "mm/s": (0.001, "m/s"),
    "m/s2": (1.0, "m/s2"), "ft/s2": (0.3048, "m/s2"),
    "s": (1.0, "s"), "min": (60.0, "s"), "h": (3600.0, "s"), "ms": (0.001, "s"),
}
_ALIASES = {"kn": "knots", "knot": "knots", "kt": "knots", "kts": "knots", "m/s^2": "m/s2",
            "m/s²": "m/s2", "ft/s^2": "ft/s2", "kph": "km/h", "degree": "deg", "degrees": "deg",
            "NM": "nmi"}
#: SI units by base-unit exponents (for the FMU's UnitDefinitions)
_SI_BY_EXPONENTS = {(("m", 1),): "m", (("m", 1), ("s", -1)): "m/s",
                    (("m", 1), ("s", -2)): "m/s2", (("rad", 1),): "rad", (("s", 1),): "s"}

#: roles of the vehicle: name -> (causality, our unit, required)
VEHICLE_ROLES: dict[str, tuple[str, str, bool]] = {
    "x": ("output", "m", True), "y": ("output", "m", True),
    "vx": ("output", "m/s", True), "vy": ("output", "m/s", True),
    "psi_out": ("output", "rad", False),
    "psi": ("input", "rad", True), "a": ("input", "m/s2", True),
    "w_x": ("input", "m/s", False), "w_y": ("input", "m/s", False),
    "w_vx": ("input", "m/s2", False), "w_vy": ("input", "m/s2", False),
}
ROLES: dict[str, dict[str, tuple[str, str, bool]]] = {"vehicle": VEHICLE_ROLES}

REAL_TYPES = ("Real", "Float64")
_ENTRY_KEYS = ("var", "unit", "ours", "scale", "offset", "negate", "start_var")


def canonical_unit(unit: str) -> str:
    """The name :data:`UNITS` knows a unit by (``"kn"`` -> ``"knots"``, ``"m/s^2"`` ->
    ``"m/s2"``...; an unknown unit as written, without surrounding blanks)."""
    unit = unit.strip()
    return _ALIASES.get(unit, unit)


def parse_offset(value: object, where: str) -> float:
    """A number, or a string ``"[-][k*]pi[/n]"`` such as ``"pi/2"`` or ``"-pi"``."""
    if isinstance(value, bool):
        raise ScenarioError(f"{where}: expected a number or a multiple of pi, got {value!r}")
    if isinstance(value, int | float):
        return float(value)
    m = re.fullmatch(r"\s*([+-])?\s*(\d+(?:\.\d*)?)?\s*\*?\s*pi\s*(?:/\s*(\d+(?:\.\d*)?))?\s*",
                     str(value))
    if not m:
        raise ScenarioError(f"{where}: expected a number or a multiple of pi such as 'pi/2', "
                            f"got {value!r}")
    sign = -1.0 if m.group(1) == "-" else 1.0
    return sign * float(m.group(2) or 1.0) * math.pi / float(m.group(3) or 1.0)


def fmu_unit(var: ModelVariable) -> str | None:
    """The unit an FMU variable declares (its own or its declared type's)."""
    unit = getattr(var, "unit", None)
    if not unit and getattr(var, "declaredType", None) is not None:
        unit = getattr(var.declaredType, "unit", None)
    return unit or None


def unit_conversion(theirs: str, ours: str,
                    md: ModelDescription | None = None) -> tuple[float, float]:
    """``(f, g)`` with ``ours = f * theirs + g``; ScenarioError-free: raises ValueError."""
    t, o = canonical_unit(theirs), canonical_unit(ours)
    if t == o:
        return 1.0, 0.0
    if o not in UNITS:
        raise ValueError(f"unknown unit {ours!r} (known: {', '.join(UNITS)})")
    fo, so = UNITS[o]
    if t in UNITS:
        ft, st = UNITS[t]
        gt = 0.0
    else:
        defn = {u.name: u for u in (getattr(md, "unitDefinitions", None) or [])}.get(theirs)
        base = getattr(defn, "baseUnit", None)
        if base is None:
            raise ValueError(f"unknown unit {theirs!r} (known: {', '.join(UNITS)}; or define "
                             f"it with base units in the FMU's UnitDefinitions)")
        exps = tuple((k, getattr(base, k)) for k in ("kg", "m", "s", "A", "K", "mol", "cd",
                                                     "rad") if getattr(base, k))
        st = _SI_BY_EXPONENTS.get(exps, "/".join(f"{k}^{e}" for k, e in exps) or "1")
        ft, gt = float(base.factor), float(base.offset)
    if st != so:
        raise ValueError(f"cannot convert {theirs!r} ({st}) to {ours!r} ({so})")
    # theirs -> SI: si = ft * theirs + gt ; SI -> ours: ours = si / fo
    return ft / fo, gt / fo


@dataclass
class Alias:
    """One role played by one FMU variable: ``ours = scale * theirs + offset``."""

    role: str
    var: object  # fmpy ScalarVariable
    scale: float = 1.0
    offset: float = 0.0
    start_var: object | None = None
    their_unit: str | None = None
    our_unit: str | None = None

    @property
    def identity(self) -> bool:
        return self.scale == 1.0 and self.offset == 0.0

    def to_fmu(self, value: float) -> float:
        return (float(value) - self.offset) / self.scale

    def to_ours(self, value: float) -> float:
        return self.scale * float(value) + self.offset


@dataclass
class VariableMap:
    """Roles of one FMU; ``exposed`` lists every variable under the name the master sees."""

    aliases: dict[str, Alias] = field(default_factory=dict)
    exposed: dict[str, object] = field(default_factory=dict)
    raw_to_exposed: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @classmethod
    def identity(cls, md) -> VariableMap:
        exposed = {v.name: v for v in md.modelVariables}
        return cls({}, exposed, {n: n for n in exposed})

    def affine(self, name: str) -> tuple[float, float]:
        a = self.aliases.get(name)
        return (1.0, 0.0) if a is None else (a.scale, a.offset)


def _key(where: str, prefix: str, *parts: str) -> str:
    return f"{where}: key '{'.'.join(p for p in (prefix, *parts) if p)}'"


def normalize_entries(raw: dict, where: str, prefix: str = "") -> dict[str, dict]:
    """``{role: "var"}`` or ``{role: {var=..., ...}}`` -> ``{role: {...}}`` with known keys."""
    out = {}
    for role, entry in raw.items():
        if isinstance(entry, str):
            entry = {"var": entry}
        if not isinstance(entry, dict):
            raise ScenarioError(f"{_key(where, prefix, role)}: expected a variable name or a "
                                f"table, got {entry!r}")
        bad = [k for k in entry if k not in _ENTRY_KEYS]
        if bad:
            raise ScenarioError(f"{_key(where, prefix, role, bad[0])}: unknown key (expected "
                                f"one of: {', '.join(_ENTRY_KEYS)})")
        if "var" not in entry:
            raise ScenarioError(f"{_key(where, prefix, role, 'var')}: required key is missing")
        if "scale" in entry and "unit" in entry:
            raise ScenarioError(f"{_key(where, prefix, role)}: give 'unit' or 'scale', "
                                f"not both")
        if "scale" in entry and (not isinstance(entry["scale"], int | float)
                                 or isinstance(entry["scale"], bool) or entry["scale"] == 0):
            raise ScenarioError(f"{_key(where, prefix, role, 'scale')}: expected a non-zero "
                                f"number, got {entry['scale']!r}")
        if "negate" in entry and not isinstance(entry["negate"], bool):
            raise ScenarioError(f"{_key(where, prefix, role, 'negate')}: expected true or "
                                f"false, got {entry['negate']!r}")
        for k in ("var", "unit", "ours", "start_var"):
            if k in entry and not isinstance(entry[k], str):
                raise ScenarioError(f"{_key(where, prefix, role, k)}: expected a string, "
                                    f"got {entry[k]!r}")
        out[role] = dict(entry)
    return out


def load_entries(spec_map: str | dict, base_dir: Path, where: str,
                 prefix: str = "") -> tuple[dict[str, dict], str, str]:
    """The map's entries from a file name (relative to ``base_dir``) or an inline table;
    also the file and key prefix its messages should name."""
    if spec_map is None:
        return {}, where, prefix
    if isinstance(spec_map, str | Path):
        p = Path(spec_map)
        p = p if p.is_absolute() else base_dir / p
        if not p.is_file():
            raise ScenarioError(f"{_key(where, prefix)}: variable map file {p} not found")
        _, raw = read_toml(p, "variable map")
        return normalize_entries(raw, str(p)), str(p), ""
    return normalize_entries(dict(spec_map), where, prefix), where, prefix


def resolve_map(entries: dict[str, dict], md: ModelDescription, role: str | None = "vehicle",
                where: str = "map", prefix: str = "") -> tuple[VariableMap, list[str]]:
    """Check ``entries`` against the model description ``md``; ``(map, problems)``."""
    if not entries:
        return VariableMap.identity(md), []
    roles = ROLES.get(role or "", {})
    by_name = {v.name: v for v in md.modelVariables}
    problems: list[str] = []
    vmap = VariableMap()
    used: dict[str, str] = {}
    for rname, e in entries.items():
        key = _key(where, prefix, rname)
        v = by_name.get(e["var"])
        if v is None:
            close = [n for n in by_name if n.lower() == str(e["var"]).lower()]
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            problems.append(f"{key}: the FMU has no variable {e['var']!r}{hint}")
            continue
        if v.name in used:
            problems.append(f"{key}: variable {v.name!r} already plays role {used[v.name]!r}")
            continue
        used[v.name] = rname
        if v.type not in REAL_TYPES:
            problems.append(f"{key}: {v.name!r} has type {v.type}, expected Real/Float64")
            continue
        want = roles.get(rname)
        if want is not None and v.causality != want[0]:
            problems.append(f"{key}: {v.name!r} has causality {v.causality!r}, "
                            f"expected {want[0]!r} for role {rname!r}")
            continue
        declared = fmu_unit(v)
        our_unit = e.get("ours") or (want[1] if want else None)
        their_unit = e.get("unit") or declared
        if "scale" in e:
            f, g = float(e["scale"]), 0.0
        elif their_unit and our_unit:
            try:
                f, g = unit_conversion(their_unit, our_unit, md)
            except ValueError as exc:
                problems.append(f"{key}: {exc}")
                continue
            if (e.get("unit") and declared
                    and canonical_unit(declared) != canonical_unit(e["unit"])):
                vmap.warnings.append(f"{key}: unit {e['unit']!r} given, the FMU declares "
                                     f"{declared!r} for {v.name!r} (using {e['unit']!r})")
        else:
            f, g = 1.0, 0.0
            if our_unit and not their_unit:
                vmap.warnings.append(f"{key}: {v.name!r} declares no unit; assumed "
                                     f"{our_unit!r} (give 'unit' to convert)")
        sign = -1.0 if e.get("negate") else 1.0
        try:
            offset = parse_offset(e.get("offset", 0.0), _key(where, prefix, rname, "offset"))
        except ScenarioError as exc:
            problems.append(str(exc))
            continue
        start_var = None
        if e.get("start_var"):
            start_var = by_name.get(e["start_var"])
            if start_var is None:
                problems.append(f"{_key(where, prefix, rname, 'start_var')}: the FMU has no "
                                f"variable {e['start_var']!r}")
                continue
            if start_var.type not in REAL_TYPES:
                problems.append(f"{_key(where, prefix, rname, 'start_var')}: "
                                f"{start_var.name!r} has type {start_var.type}, expected "
                                f"Real/Float64")
                continue
        vmap.aliases[rname] = Alias(rname, v, sign * f, sign * g + offset, start_var,
                                    their_unit, our_unit)
    mapped = {a.var.name: r for r, a in vmap.aliases.items()}
    for v in md.modelVariables:
        if v.name in mapped:
            r = mapped[v.name]
            vmap.exposed[r] = v
            vmap.raw_to_exposed[v.name] = r
        elif v.name not in entries:
            vmap.exposed[v.name] = v
            vmap.raw_to_exposed[v.name] = v.name
    return vmap, problems


def missing_roles(vmap: VariableMap, role: str) -> list[str]:
    """Required roles of ``role`` the FMU does not expose with the right causality."""
    out = []
    for rname, (causality, unit, required) in ROLES.get(role, {}).items():
        v = vmap.exposed.get(rname)
        if v is None:
            if required:
                out.append(f"role {rname!r} ({causality}, {unit}): no variable of that name; "
                           f"map it, e.g. {rname} = {{var = \"...\", unit = \"{unit}\"}}")
        elif v.causality != causality:
            out.append(f"role {rname!r}: {v.name!r} has causality {v.causality!r}, "
                       f"expected {causality!r}")
    return out


def connection_affine(transform: object, where: str) -> tuple[float, float]:
    """``(factor, offset)`` of a connection's linear transformation: an object with ``factor``
    and ``offset`` attributes (the scenario's), a dict with those keys or a pair."""
    if isinstance(transform, dict):
        factor, offset = transform.get("factor", 1.0), transform.get("offset", 0.0)
    elif isinstance(transform, tuple | list):
        factor, offset = transform
    else:
        factor, offset = getattr(transform, "factor", 1.0), getattr(transform, "offset", 0.0)
    try:
        factor, offset = float(factor), float(offset)
    except (TypeError, ValueError):
        raise ScenarioError(f"{where}: a connection transform needs numbers factor and offset "
                            f"(got {transform!r})") from None
    if not (math.isfinite(factor) and math.isfinite(offset)):
        raise ScenarioError(f"{where}: a connection transform needs finite factor and offset")
    return factor, offset
