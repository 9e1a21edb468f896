"""The filters' side of a scenario: its bathymetry map (:func:`scenario_map`) and the filters'
state-space model (:func:`build_model`, from ``[model]`` and the truth settings).

By default the filters are matched to the truth: ``Q`` from the ``[noise]`` PSDs and ``R`` from
the sensors' ``sigma``; ``model.q_psd`` overrides the former, ``model.map_error_std_m`` adds
the map's error variance to the depth sounder's ``R`` (for a truth with ``[map.truth]``).
``model.control_noise`` names the ``[noise]`` source on the controls whose PSDs the TAN model's
``Q`` includes (not part of the default ``q_psd``). The scenario was validated when
it was loaded (:func:`uwcosim.scenario.validate.reference_problems`: sensors, sigma per output,
the number of PSDs and the sensors the TAN model takes, a map for a depth sensor).

This is where the implementation is chosen, explicitly: ``kind = "tan"`` gives the closed-form
numpy :class:`~uwcosim.models.tan.TANModel` (its CasADi form, from the same expressions as the
FMUs, is ``model.symbolic``), ``kind = "cv"`` the :class:`~uwcosim.models.linear.LinearModel`,
and ``type`` a user's model: the builder it names (:mod:`uwcosim.models.builder`) is called
with the scenario's :class:`~uwcosim.models.builder.ModelContext` (:func:`model_context`) and
``[model.parameters]``, and what it returns is checked against the scenario (measurement names,
states, controls). The filters use the model they are given and see it only through
:class:`uwcosim.models.protocol.StateSpaceModel`.
"""

from __future__ import annotations

import numpy as np

from uwcosim.core.errors import ScenarioError
from uwcosim.core.plugins import describe_error
from uwcosim.models.builder import ModelContext, model_problems, resolve_builder
from uwcosim.models.linear import LinearModel, constant_velocity_model
from uwcosim.models.protocol import StateSpaceModel
from uwcosim.models.tan import TANModel, tan_model
from uwcosim.models.terrain import Bathymetry, load_map, synthetic_bathymetry
from uwcosim.scenario.loaded import LoadedScenario
from uwcosim.scenario.schema import MapSpec, model_noise_psds
from uwcosim.scenario.validate import search_dirs, state_problems


def scenario_map(loaded: LoadedScenario) -> Bathymetry | None:
    """The bathymetry of the scenario's ``[map]`` (None without one)."""
    m = loaded.spec.map
    if m is None:
        return None
    return build_map(loaded, m)


def build_map(loaded: LoadedScenario, m: MapSpec) -> Bathymetry:
    """The bathymetry of the map keys ``m`` (``[map]``, or ``[map]`` with ``[map.truth]``'s
    overrides), files resolved against the scenario's folder."""
    if m.kind == "file":  # a lat/lon file: projected to the frame of [geo] origin or its centre
        geo = getattr(loaded.spec, "geo", None)
        origin = (geo.origin.lat, geo.origin.lon) if geo is not None and geo.origin else None
        res = m.resolution if "resolution" in m.model_fields_set else None
        return load_map(loaded.resolve(m.file), m.variable, origin=origin,
                        projection=m.projection, resolution=res)
    return synthetic_bathymetry(m.seed, m.extent, m.resolution, relief_std=m.relief_std)


def build_model(loaded: LoadedScenario,
                bathymetry: Bathymetry | None) -> TANModel | LinearModel | StateSpaceModel:
    """The filters' model of a validated scenario (``[model]``)."""
    spec = loaded.spec
    m = spec.model
    if m.type is not None:
        return user_model(loaded, bathymetry)
    q, qc = model_noise_psds(spec)
    sensors = [spec.sensors[s] for s in m.sensors]
    names = tuple(o for s in sensors for o in s.outputs)
    if m.kind == "tan":
        depth = len(sensors) == 2
        sigma_h = sensors[1].sigma[0] if depth else None
        if depth and m.map_error_std_m > 0:  # R_h = sigma^2 + sigma_map^2
            sigma_h = float(np.hypot(sigma_h, m.map_error_std_m))
        return tan_model(q, sensors[0].sigma, sigma_h, bathymetry if depth else None, names,
                         control_psd=qc)
    r = np.array([sg**2 for s in sensors for sg in s.sigma])
    return constant_velocity_model(q_psd=q, R=np.diag(r), measurement_names=names)


def model_context(loaded: LoadedScenario, bathymetry: Bathymetry | None) -> ModelContext:
    """What the builder of a user's model gets from the validated scenario."""
    spec = loaded.spec
    m = spec.model
    q, qc = model_noise_psds(spec)
    sensors = {s: tuple(spec.sensors[s].outputs) for s in m.sensors}
    sigma = {o: float(sg) for s in m.sensors
             for o, sg in zip(spec.sensors[s].outputs, spec.sensors[s].sigma, strict=True)}
    return ModelContext(
        measurement_names=tuple(o for outs in sensors.values() for o in outs), sigma=sigma,
        q_psd=tuple(q), noise={n: tuple(nz.psd) for n, nz in spec.noise.items()},
        control_psd=tuple(qc) if qc is not None else None, controls=tuple(m.controls),
        truth=tuple(m.truth), sensors=sensors, step=spec.run.step, bathymetry=bathymetry,
        scenario_dir=loaded.base_dir)


def user_model(loaded: LoadedScenario, bathymetry: Bathymetry | None) -> StateSpaceModel:
    """The model ``[model] type`` builds, checked against the scenario (ScenarioError, one
    line naming the key: the builder's own error, its file and line, or what does not match)."""
    spec, where = loaded.spec, str(loaded.path)
    m = spec.model
    key = f"{where}: key 'model.type'"
    try:
        builder = resolve_builder(m.type, search_dirs(where))
    except ScenarioError as exc:
        raise ScenarioError(f"{key}: {exc}") from None
    context = model_context(loaded, bathymetry)
    try:
        model = builder(context, **m.parameters)
    except Exception as exc:  # noqa: BLE001 - the user's builder: its error in one line
        raise ScenarioError(f"{key}: building the model with {m.type!r} failed: "
                            f"{describe_error(exc)}") from None
    problems = [f"{key}: {p}" for p in model_problems(model, m.type, context)]
    if not problems:
        problems = [f"{where}: {p}" for p in state_problems(
            spec, tuple(model.state_names), f"model {m.type!r}")]
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise ScenarioError(problems[0] + more)
    return model
