"""``uwcosim fmu check FMU --role vehicle [--map MAP]``: can this FMU play a role here?

Five parts, each reported: fmpy validation, the platform binary and that it loads (in a child
process) with the FMI functions its interfaces need; what the FMU needs that the master does
not do (scheduled execution only, FMI 3 clocks: :mod:`uwcosim.fmi.features`); capabilities
(FMI version,
co-simulation / model exchange, get/set state, directional derivatives, several instances);
the variable map (names exist, causality, type, declared units and the conversion); and for
the vehicle role a short smoke run with constant inputs (heading 0.5 rad, acceleration
0.01 m/s^2, speed 1 m/s along the body x axis when the start velocity can be set), in a
worker process with a per-call time limit so a hanging or crashing FMU is reported, not
suffered. The run must give finite outputs, a path length equal to the integral of the speed
and a direction of motion that agrees with the filters' model (eq. 54); the distance to the
eq. (54) trajectory itself is a warning only (a vehicle may have other dynamics).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fmpy.validation import validate_fmu

from uwcosim.core.errors import FMUError, ScenarioError
from uwcosim.fmi.archive import archive_problems, library_problems, open_archive
from uwcosim.fmi.features import missing_features
from uwcosim.fmi.proxy import ProxyAdapter
from uwcosim.fmi.varmap import (
    ROLES,
    VariableMap,
    fmu_unit,
    load_entries,
    missing_roles,
    resolve_map,
)
from uwcosim.fmu.info import platform_problems
from uwcosim.models.auv_equations import rk4_step, vehicle_ode

SMOKE_PSI = 0.5  # rad
SMOKE_A = 0.01  # m/s^2
SMOKE_V0 = 1.0  # m/s


@dataclass
class CheckReport:
    """What ``fmu check`` found: ``lines`` to print, ``problems`` make the FMU incompatible."""

    path: Path
    lines: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: findings of the FMI standard's rules (fmpy's ``validate_fmu``), among the warnings
    findings: int = 0

    @property
    def ok(self) -> bool:
        return not self.problems

    def text(self) -> str:
        out = list(self.lines)
        if self.warnings:
            out.append("  warnings:")
            out += [f"    - {w}" for w in self.warnings]
        if self.problems:
            out.append(f"  result: INCOMPATIBLE ({len(self.problems)} problem"
                       f"{'s' if len(self.problems) > 1 else ''})")
            out += [f"    - {p}" for p in self.problems]
        elif self.findings:
            out.append(f"  result: compatible, with {self.findings} finding"
                       f"{'s' * (self.findings != 1)} against the FMI standard (warnings: the "
                       f"master does not rely on them; 'uwcosim fmu validate', a conformance "
                       f"check, exits 1 on them)")
        else:
            out.append("  result: compatible")
        return "\n".join(out)


def _yes(flag) -> str:
    return "yes" if flag in (True, "true", "1") else "no"


def _capabilities(md) -> list[str]:
    lines = [f"  FMI version       {md.fmiVersion}"]
    if md.generationTool:
        lines.append(f"  generation tool   {md.generationTool}")
    for label, i in (("co-simulation", md.coSimulation), ("model exchange", md.modelExchange)):
        if i is None:
            lines.append(f"  {label:<17} no")
            continue
        dd = getattr(i, "providesDirectionalDerivatives", None)
        if dd is None:
            dd = getattr(i, "providesDirectionalDerivative", None)
        caps = [f"get/set state {_yes(i.canGetAndSetFMUstate)}",
                f"directional derivatives {_yes(dd)}",
                f"several instances {_yes(not i.canBeInstantiatedOnlyOncePerProcess)}"]
        if label == "co-simulation":
            caps.append(f"variable step {_yes(i.canHandleVariableCommunicationStepSize)}")
        lines.append(f"  {label:<17} yes ({i.modelIdentifier}): " + ", ".join(caps))
    return lines


def me_solver_lines(path: Path, md, timeout_s: float, report: CheckReport) -> None:
    """Which integrator the master uses for the FMU as model exchange, and why.

    Event indicators are read from the model description; time events are known only after
    initialization, so an FMU without event indicators is initialized (default parameters) in
    a worker process to see whether it defines a time event."""
    nz = int(md.numberOfEventIndicators or 0)
    nx = int(md.numberOfContinuousStates or 0)
    head = f"  ME solver         {nx} continuous state(s), {nz} event indicator(s): "
    if nz:
        report.lines.append(head + "state events -> the event-aware solver (CVode with root "
                            "finding) will be used, not the fixed-step RK4 fast path")
        return
    ex = md.defaultExperiment
    t_stop = float(ex.stopTime) if ex is not None and ex.stopTime else 10.0
    ad = ProxyAdapter(Path(path).stem, path, "me", "rk4", 1, 1e-8, timeout_s)  # its name
    try:
        ad.instantiate({}, {}, 0.0, t_stop)
        used = ad.solver_used
    except (FMUError, ScenarioError) as exc:
        report.warnings.append(f"ME solver: could not initialize the FMU to look for time "
                               f"events ({exc})")
        report.lines.append(head + "time events unknown (initialization failed)")
        return
    finally:
        ad.close()
    if used == "cvode":
        report.lines.append(head + "a time event after initialization -> the event-aware "
                            "solver (CVode, stops at each time event) will be used")
    else:
        report.lines.append(head + "no time event at initialization -> fixed-step RK4 fast "
                            "path (a step event is handled at the end of the step; a later time "
                            "event switches to the event-aware solver)")


def _fmt_affine(scale: float, offset: float) -> str:
    if scale == 1.0 and offset == 0.0:
        return "theirs"
    s = "theirs" if scale == 1.0 else "-theirs" if scale == -1.0 else f"{scale:.6g}*theirs"
    if offset:
        s += f" {'+' if offset > 0 else '-'} {abs(offset):.6g}"
    return s


def _map_lines(vmap: VariableMap, role: str | None) -> list[str]:
    roles = ROLES.get(role or "", {})
    names = list(roles) + [r for r in vmap.aliases if r not in roles]
    rows = [("role", "FMU variable", "causality", "unit (theirs -> ours)", "ours =")]
    for r in names:
        a = vmap.aliases.get(r)
        v = a.var if a else vmap.exposed.get(r)
        if v is None:
            rows.append((r, "-", "-", "-", "not mapped" + (" (required)" if roles.get(
                r, ("", "", False))[2] else " (optional)")))
            continue
        their = (a.their_unit if a else fmu_unit(v)) or "?"
        ours = (a.our_unit if a else roles.get(r, ("", "", False))[1]) or their
        scale, offset = (a.scale, a.offset) if a else (1.0, 0.0)
        rows.append((r, v.name, str(v.causality), f"{their} -> {ours}",
                     _fmt_affine(scale, offset)))
    widths = [max(len(row[k]) for row in rows) for k in range(5)]
    return ["  roles:"] + ["    " + "  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip()
                           for row in rows]


def _settable(v) -> bool:
    return v is not None and (v.causality in ("parameter", "input")
                              or v.initial in ("exact", "approx"))


def reference_positions(t: np.ndarray, p0, v0, psi: float, a: float):
    """Positions of eq. (54) at times ``t`` from ``(p0, v0)`` with constant heading and
    acceleration, from its one definition
    (:func:`~uwcosim.models.auv_equations.vehicle_ode`; one RK4 step of any length is exact for
    it)."""
    t = np.asarray(t, dtype=float)
    x0 = np.array([p0[0], p0[1], v0[0], v0[1]], dtype=float)
    X = np.array(rk4_step(vehicle_ode()).map(t.size)(x0, [psi, a], np.zeros(4), t))
    return X[0], X[1]


def smoke_run(path: Path, entries: dict, role: str, interface: str, duration: float,
              step: float, timeout_s: float, report: CheckReport,
              where: tuple[str, str] = ("", "")) -> None:
    """Run the FMU for ``duration`` s with constant inputs; add lines/problems to ``report``."""
    ad = ProxyAdapter(Path(path).stem, path, interface, "rk4", 4, 1e-8, timeout_s)
    try:
        if entries:
            ad.use_map(entries, role, *where)
        exposed = ad.variables
        outs = [r for r in ("x", "y", "vx", "vy") if r in exposed]
        if len(outs) < 4:
            report.problems.append("smoke run: skipped (x, y, vx, vy are not all mapped)")
            return
        ins = [r for r, (c, _, _) in ROLES[role].items() if c == "input" and r in exposed
               and exposed[r].causality == "input"]
        value = {"psi": SMOKE_PSI, "a": SMOKE_A}
        b_in, b_out = ad.bind(ins), ad.bind(outs)
        b_in.view[:] = [value.get(r, 0.0) for r in ins]
        alias = ad.varmap.aliases
        can_set = all(_settable((alias[r].start_var or alias[r].var) if r in alias
                                else exposed.get(r)) for r in ("vx", "vy"))
        start = {"vx": SMOKE_V0, "vy": 0.0} if can_set else {}
        n = max(1, int(round(duration / step)))
        desc = (f"  smoke run         {'co-simulation' if interface == 'cs' else 'model exchange'}"
                f", {n * step:g} s in steps of {step:g} s: psi {SMOKE_PSI} rad, a {SMOKE_A} "
                f"m/s2" + (f", vx(0) {SMOKE_V0} m/s" if start else ", its own start velocity"))
        report.lines.append(desc)
        ad.instantiate({}, start, 0.0, n * step)
        ad.set_inputs(b_in, 0.0)
        rows = [ad.get_outputs(b_out, 0.0).copy()]
        for k in range(n):
            ad.do_step(k * step, step, b_in, None)
            rows.append(ad.get_outputs(b_out, (k + 1) * step).copy())
    except (FMUError, ScenarioError) as exc:
        report.problems.append(f"smoke run: {exc}")
        return
    finally:
        ad.close()
    _judge(np.array(rows), step, report)


def _judge(rows: np.ndarray, step: float, report: CheckReport) -> None:
    def line(label: str, ok: bool, text: str) -> None:
        report.lines.append(f"    {label:<26} {'ok' if ok else 'FAILED'} ({text})")

    if not np.all(np.isfinite(rows)):
        k = int(np.argmax(~np.all(np.isfinite(rows), axis=1)))
        line("outputs finite", False, f"non-finite at t={k * step:g}")
        report.problems.append(f"smoke run: non-finite outputs at t={k * step:g}")
        return
    line("outputs finite", True, f"{rows.shape[0]} samples")
    p, v = rows[:, :2], rows[:, 2:]
    path_len = float(np.sum(np.hypot(*np.diff(p, axis=0).T)))
    speed = np.hypot(v[:, 0], v[:, 1])
    integral = float(np.sum((speed[1:] + speed[:-1]) / 2) * step)
    ok = integral > 0 and abs(path_len - integral) <= 0.05 * integral + 1e-9
    line("path length = speed x time", ok, f"{path_len:.4g} m travelled, integral of the "
         f"speed {integral:.4g} m")
    if not ok:
        ratio = path_len / integral if integral > 0 else float("inf")
        report.problems.append(f"smoke run: the position moves {ratio:.4g} times as far as the "
                               f"speed says (unit of x/y or vx/vy wrong? e.g. ft, knots)")
    t = step * np.arange(rows.shape[0])
    xe, ye = reference_positions(t, p[0], v[0], SMOKE_PSI, SMOKE_A)
    d_ref = math.atan2(ye[-1] - ye[0], xe[-1] - xe[0])
    d_fmu = math.atan2(p[-1, 1] - p[0, 1], p[-1, 0] - p[0, 0])
    err = abs((d_fmu - d_ref + math.pi) % (2 * math.pi) - math.pi)
    ok = math.degrees(err) <= 2.0
    line("direction of motion", ok, f"{math.degrees(d_fmu):.2f} deg from the x axis, eq. (54) "
         f"gives {math.degrees(d_ref):.2f} deg")
    if not ok:
        report.problems.append(
            "smoke run: the vehicle does not move along its heading as eq. (54) says (heading "
            "convention? check negate/offset of psi, and x/y order)")
    dev = float(np.max(np.hypot(p[:, 0] - xe, p[:, 1] - ye)))
    ok = dev <= 0.01 * max(integral, 1e-9) + 1e-6
    line("trajectory of eq. (54)", ok, f"largest distance {dev:.3g} m")
    if not ok:
        report.warnings.append(f"smoke run: the trajectory is {dev:.3g} m from eq. (54) after "
                               f"{t[-1]:g} s (other dynamics: the filters' model will not match)")


def check_fmu(path: str | Path, role: str | None = "vehicle", map_file: str | None = None,
              interface: str | None = None, duration: float = 10.0, step: float = 0.5,
              timeout_s: float = 30.0) -> CheckReport:
    """Check the FMU at ``path`` for ``role`` with the variable map ``map_file``."""
    path = Path(path)
    if not path.exists():
        raise FMUError(f"{path}: FMU not found")
    rep = CheckReport(path)
    rep.lines.append(f"{path.name}" + (f" (role {role}" if role else " (no role")
                     + (f", map {map_file})" if map_file else ")"))
    rep.problems += archive_problems(path)
    if rep.problems:
        rep.lines.append("  archive           FAILED")
        return rep
    try:
        md = open_archive(path)
        rep.problems += platform_problems(path, md)
    except FMUError as exc:
        rep.problems.append(str(exc))
        return rep
    # the standard's finer points (fmpy's validation) do not stop the master: warnings
    try:
        findings = list(validate_fmu(str(path)))
    except Exception as exc:  # noqa: BLE001 - fmpy raises bare Exceptions
        findings = [f"validation failed ({exc})"]
    rep.warnings += [f"fmpy validation: {f}" for f in findings]
    rep.findings = len(findings)
    rep.lines.append("  validation        " + (
        "ok (fmpy validate_fmu)" if not findings else
        f"{len(findings)} finding(s) of fmpy validate_fmu (see warnings)"))
    rep.lines.append("  platform binary   " + ("FAILED" if rep.problems else "ok"))
    if rep.problems:
        return rep
    loading = library_problems(path, md, timeout_s=timeout_s)
    rep.lines.append("  binary loads      " + ("FAILED" if loading else "ok (FMI functions "
                                                "exported)"))
    rep.problems += loading
    needs = missing_features(md)
    rep.lines.append("  features          " + ("FAILED" if needs else
                                                "ok (co-simulation/model exchange, no clocks)"))
    rep.problems += [f"cannot be run by the master: {n}" for n in needs]
    rep.lines += _capabilities(md)
    if rep.problems:
        return rep
    entries, where, prefix = load_entries(map_file, Path.cwd(), str(map_file or path))
    vmap, map_problems = resolve_map(entries, md, role, where, prefix)
    rep.problems += map_problems
    rep.warnings += vmap.warnings
    if map_problems:
        return rep
    if md.modelExchange is not None and interface != "cs":
        me_solver_lines(path, md, timeout_s, rep)
    if role:
        rep.lines += _map_lines(vmap, role)
        rep.problems += missing_roles(vmap, role)
    if rep.problems or role != "vehicle":
        return rep
    if interface is None:
        interface = "cs" if md.coSimulation is not None else "me"
    if (md.coSimulation if interface == "cs" else md.modelExchange) is None:
        label = "co-simulation" if interface == "cs" else "model exchange"
        rep.problems.append(f"the FMU has no {label} interface")
        return rep
    smoke_run(path, entries, role, interface, duration, step, timeout_s, rep, (where, prefix))
    return rep
