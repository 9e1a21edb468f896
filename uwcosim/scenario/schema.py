"""The scenario schema (pydantic): every key, its type and its default.

A scenario names the FMUs and how they connect, the control inputs, the noise, the sensors and
their loss models, the filter model and estimators, the run length, step and seed, and what to
log; or, instead of FMUs, a recorded file to replay (``[replay]``, :mod:`uwcosim.scenario.replay`:
a :class:`ReplayScenario`); its geographic frame (``[geo]``, :mod:`uwcosim.scenario.geo`).
Unknown keys are errors. :mod:`uwcosim.scenario.validate` reports every error of this
schema at once, checks each ``[estimators.NAME]`` against its filter's settings model and the
cross-references between sections; the FMU variables (connections, targets, sensors) are
checked against the FMUs' model descriptions by the master (``uwcosim check`` runs both).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    TypeAdapter,
    ValidationError,
    field_validator,
    model_validator,
)

from uwcosim.master.system import (
    FMU,
    BernoulliLoss,
    Bool,
    Connection,
    ConnectionTransform,
    Control,
    Float,
    GilbertElliottLoss,
    Int,
    Loss,
    Noise,
    NonNegativeFloat,
    PositiveFloat,
    PositiveInt,
    Sensor,
    Str,
    table_problem,
)
from uwcosim.scenario.control_files import ControlSpec
from uwcosim.scenario.geo import GeoSpec, LatLon  # noqa: F401 (error tags)
from uwcosim.scenario.replay import ColumnSpec, GeographicColumns, ReplaySpec  # noqa: F401

# The FMU, connection-transform, control, noise, sensor and loss records are the system
# layer's own types (:mod:`uwcosim.master.system`), validated the same way as the records
# below: strict types (a TOML string is never taken for a number, "50" is refused for a
# duration; a float never for an integer; an integer is a valid float), NaN and infinity refused
# everywhere (``allow_inf_nan=False``), unknown keys refused.
__all__ = ["FMU", "BernoulliLoss", "ConnectionTransform", "Control", "ControlSpec",
           "GilbertElliottLoss", "Loss", "Noise", "ReplayScenario", "Scenario", "Sensor"]

#: more steps than this cannot be represented as ``t0 + k*h`` to the step (2**53 / 1000)
MAX_STEPS = 9_000_000_000_000
#: largest synthetic map grid (cells)
MAX_MAP_CELLS = 50_000_000


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class RunSpec(Strict):
    duration: PositiveFloat
    step: PositiveFloat
    start_time: Float = 0.0
    seed: Int = 0
    #: an FMU's request to stop ends the run with status "terminated" (exit 0) or, with
    #: "error", as a failure (exit 3)
    stop_on_terminate: Literal["stop", "error"] = "stop"
    #: run-wide watchdog (s): an FMU call lasting longer ends the run (failed, log kept)
    fmu_timeout_s: PositiveFloat | None = None
    #: the limit (MiB) of an FMU's or the system.ssp archive's unpacked size (a zip bomb is
    #: refused before it is inflated); default: UWCOSIM_FMU_MAX_UNPACKED_MB, else 512
    fmu_max_unpacked_mb: PositiveFloat | None = None
    #: the master algorithm: "gauss-seidel" (dependency order) or "jacobi" (every FMU from
    #: the values of the previous communication point)
    algorithm: Literal["gauss-seidel", "jacobi"] = "gauss-seidel"
    #: an algebraic loop between FMUs is solved (Newton) or refused when the scenario loads
    algebraic_loops: Literal["solve", "error"] = "solve"
    #: a loop converged when every residual |r_i| <= loop_tolerance * (1 + |u_i|)
    loop_tolerance: PositiveFloat = 1e-10
    #: Newton iterations allowed per solve of a loop
    loop_max_iterations: PositiveInt = 50
    #: the estimators run over blocks of this many steps, one after the other, after the
    #: co-simulation computed them (faster: their data stay in the CPU caches); the results
    #: do not depend on it; 1 = every estimator at every step
    filter_block: PositiveInt = 64

    @model_validator(mode="after")
    def _steps(self) -> RunSpec:
        n = self.duration / self.step
        if not n <= MAX_STEPS:
            raise ValueError(f"'duration' / 'step' = {n:.3g} steps, more than {MAX_STEPS:.0e} "
                             f"(time t0 + k*step would lose precision)")
        return self


class ReplayRunSpec(RunSpec):
    """``[run]`` of a replay: the steps are the file's rows (no ``step``); ``duration`` (s),
    when given, keeps the rows up to the first replayed time plus it, ``start_time`` (when
    given) the rows from it on."""

    duration: PositiveFloat | None = None
    step: PositiveFloat | None = None  # refused (replay_problems): the file gives the steps

    @model_validator(mode="after")
    def _steps(self) -> ReplayRunSpec:
        return self


class SystemSpec(Strict):
    """The truth side from another tool: an SSP file (see :mod:`uwcosim.scenario.ssp`)."""

    ssp: Str


class SurveyErrorSpec(Strict):
    """``[map.truth] survey_error``: the survey's error, a correlated Gaussian field."""

    std_m: NonNegativeFloat
    correlation_m: PositiveFloat = 500.0


class MapTruthSpec(Strict):
    """``[map.truth]``: the seafloor the truth's sounder measures, when it is not the filters'
    map (:mod:`uwcosim.models.truth_map`). The map keys override ``[map]``'s for the truth only:
    ``kind``, ``seed``, ``relief_std``, ``file``, ``variable``, ``projection`` give another
    seafloor altogether; ``extent`` and ``resolution`` alone resample the filters' map's spline
    onto the truth's grid; then the unresolved relief and the survey error are added."""

    kind: Literal["synthetic", "file"] | None = None
    seed: Int | None = None
    extent: tuple[Float, Float, Float, Float] | None = None
    resolution: PositiveFloat | None = None
    relief_std: PositiveFloat | None = None
    file: Str | None = None
    variable: Str | None = None
    projection: Literal["tmerc", "equirectangular"] | None = None
    #: fine-scale relief the survey did not resolve: standard deviation and correlation (m)
    fine_relief_m: NonNegativeFloat = 0.0
    fine_scale_m: NonNegativeFloat = 0.0
    survey_error: SurveyErrorSpec | None = None
    #: tide or depth-bias offset (m) added to the measured depth, a piecewise-linear
    #: ``[time, value]`` table: a control on the sounder's ``offset_h`` input
    offset: list[tuple[Float, Float]] | None = Field(
        None, description="tide or depth-bias offset (m) over time: piecewise-linear "
        "[time, value] rows, the truth's sounder only (input 'offset_h' of the sounder)")
    #: the sounder's input the offset drives (FMU.variable; default: the FMU of fmu_parameter)
    offset_input: Str | None = None

    @model_validator(mode="after")
    def _truth(self) -> MapTruthSpec:
        if self.fine_relief_m > 0 and self.fine_scale_m <= 0:
            raise ValueError("'fine_relief_m' needs a positive 'fine_scale_m' (m)")
        if self.offset is not None:
            problem = table_problem(self.offset)
            if problem:
                raise ValueError(f"'offset': {problem}")
        return self

    def base_keys(self) -> dict[str, Any]:
        """The keys giving another seafloor than the filters' map (empty: resample it)."""
        keys = ("kind", "seed", "relief_std", "file", "variable", "projection")
        return {k: getattr(self, k) for k in keys if getattr(self, k) is not None}


class MapSpec(Strict):
    kind: Literal["synthetic", "file"] = "synthetic"
    seed: Int = 7
    extent: tuple[Float, Float, Float, Float] = (0.0, 25_000.0, 0.0, 25_000.0)
    resolution: PositiveFloat = 50.0
    relief_std: PositiveFloat = 60.0
    file: Str | None = None
    variable: Str | None = None
    fmu_parameter: Str = "sounder.mapFile"
    #: a latitude/longitude map file: projected to the local transverse Mercator frame
    #: (uwcosim.models.geo) or, as earlier versions did, equirectangularly
    projection: Literal["tmerc", "equirectangular"] = Field(
        "tmerc", description="projection of a latitude/longitude map file: 'tmerc' (local "
        "transverse Mercator at the map's centre or [geo] origin) or 'equirectangular'")
    #: the truth's seafloor when it is not this map (the filters keep this one)
    truth: MapTruthSpec | None = None

    @model_validator(mode="after")
    def _file(self) -> MapSpec:
        if self.kind == "file" and not self.file:
            raise ValueError("kind = 'file' needs 'file'")
        xmin, xmax, ymin, ymax = self.extent
        if not (xmin < xmax and ymin < ymax):
            raise ValueError(f"'extent' must be [xmin, xmax, ymin, ymax] with xmin < xmax and "
                             f"ymin < ymax (got {list(self.extent)})")
        if self.kind == "synthetic":
            cells = ((xmax - xmin) / self.resolution + 1) * ((ymax - ymin) / self.resolution + 1)
            if cells > MAX_MAP_CELLS:
                raise ValueError(f"'extent' / 'resolution' give a {cells:.3g}-cell synthetic map "
                                 f"(at most {MAX_MAP_CELLS:.0e}): coarsen 'resolution'")
        return self


class ModelSpec(Strict):
    kind: Literal["tan", "cv"] = Field(
        "tan", description="a built-in filter model: tan (seed 000 eq. 54-55) or cv "
        "(constant velocity); not with 'type'")
    #: a user's model: a builder ``package.module:build`` or an entry point of
    #: ``uwcosim.models`` (:mod:`uwcosim.models.builder`), instead of ``kind``
    type: Str | None = Field(
        None, description="a model of yours instead of 'kind': 'package.module:build' "
        "(imported with the scenario's folder and the current folder on sys.path) or an "
        "entry point of group uwcosim.models; build(context, **parameters) returns a "
        "StateSpaceModel (docs/your_own_model.md)")
    #: keyword arguments of the builder of ``type``
    parameters: dict[Str, Any] = Field(
        {}, description="keyword arguments of the builder named by 'type'")
    truth: list[Str]
    controls: list[Str] = []
    sensors: list[Str]
    q_psd: list[NonNegativeFloat] | None = None
    #: a ``[noise.NAME]`` source on the truth's controls (heading, acceleration) that the
    #: filters know: its PSDs enter Q through the step's Jacobian in the controls (tan only)
    control_noise: Str | None = Field(
        None, description="name of the [noise.NAME] source on the vehicle's controls (psi, a) "
        "that the filters' Q includes, mapped through the step's Jacobian in the controls "
        "(tan model; default: none)")

    #: the filters know their map is imperfect: its error's variance is added to the depth
    #: sounder's R (tan model)
    map_error_std_m: NonNegativeFloat = Field(
        0.0, description="standard deviation (m) of the map's error as the filters assume it: "
        "R of the depth sounder = sigma^2 + map_error_std_m^2 (tan model; default 0: the map "
        "is exact)")

    @model_validator(mode="after")
    def _kind_or_type(self) -> ModelSpec:
        if self.type is not None and "kind" in self.model_fields_set:
            raise ValueError("give 'kind' (a built-in model) or 'type' (a model of yours), "
                             "not both")
        if self.parameters and self.type is None:
            raise ValueError("'parameters' are the keyword arguments of a model builder: "
                             "they need 'type'")
        return self


def model_noise_psds(spec: Scenario) -> tuple[list[float], list[float] | None]:
    """``(q, q_c)`` of the filters' model: the process-noise PSDs (``model.q_psd``, else every
    ``[noise]`` source but the control noise) and the control-noise PSDs (or None)."""
    m = spec.model
    cn = m.control_noise if m is not None else None
    q = m.q_psd if m is not None and m.q_psd is not None else \
        [p for name, nz in spec.noise.items() if name != cn for p in nz.psd]
    qc = list(spec.noise[cn].psd) if cn is not None and cn in spec.noise else None
    return list(q), qc


class EstimatorSpec(BaseModel):
    """``type`` picks the filter; ``policy`` the lost-measurement policy; other keys are the
    filter's own settings (checked against its settings model, :mod:`uwcosim.filters.settings`,
    by :mod:`uwcosim.scenario.validate`)."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)
    type: Str
    policy: Str = "skip"
    sensors: list[Str] | None = None
    initial_std: list[Annotated[Float, Field(gt=0)]] | None = None


class EstimationSpec(Strict):
    initial_std: list[Annotated[Float, Field(gt=0)]]
    initial_error: Literal["random", "zero"] = "random"
    #: [xmin, xmax, ymin, ymax] (m): an estimate outside is diverged (default: the map's
    #: extent widened by its larger side; uwcosim.run.divergence)
    position_bound: tuple[Float, Float, Float, Float] | None = None
    #: the estimators' initial mean of these states (by state name), instead of the truth at
    #: the start time (e.g. a replay without a reference there); the initial error is added
    initial_state: dict[Str, Float] | None = Field(
        None, description="initial mean of states by name, e.g. {vx = 0.5, vy = 0} (default: "
        "the truth, or a replay's reference, at the start time)")

    @model_validator(mode="after")
    def _bound(self) -> EstimationSpec:
        b = self.position_bound
        if b is not None and not (b[0] < b[1] and b[2] < b[3]):
            raise ValueError(f"'position_bound' must be [xmin, xmax, ymin, ymax] with "
                             f"xmin < xmax and ymin < ymax (got {list(b)})")
        return self


class BoundSpec(Strict):
    runs: PositiveInt = Field(
        description="truth runs the PCRB's expectations are taken over (uwcosim.run.bound)")


class EvaluationSpec(Strict):
    #: the posterior Cramér-Rao bound beside the filters (``bound.*`` log columns,
    #: ``summary.json`` ``bound.position_m``); None: none
    bound: BoundSpec | None = Field(
        None, description="the posterior Cramér-Rao bound over N truth runs, e.g. "
        "{ runs = 100 } (default: none)")


class LogSpec(Strict):
    signals: list[Str] = ["*"]
    chunk_steps: PositiveInt = 1000


class OutputSpec(Strict):
    figures: Bool = True
    density_snapshots: list[Float] = []
    #: the trajectory figure's axes: x/y (m) or, for a georeferenced run, longitude/latitude
    trajectory_axes: Literal["xy", "latlon"] = "xy"


class Scenario(Strict):
    name: Str = "scenario"
    description: Str = ""
    run: RunSpec
    system: SystemSpec | None = None
    fmus: dict[Str, FMU]
    connections: list[Connection] = []
    controls: dict[Str, ControlSpec] = {}
    noise: dict[Str, Noise] = {}
    sensors: dict[Str, Sensor] = {}
    map: MapSpec | None = None
    model: ModelSpec | None = None
    estimation: EstimationSpec | None = None
    estimators: dict[Str, EstimatorSpec] = {}
    evaluation: EvaluationSpec | None = None
    log: LogSpec = LogSpec()
    output: OutputSpec = OutputSpec()
    replay: ReplaySpec | None = None
    geo: GeoSpec | None = None

    @field_validator("connections", mode="before")
    @classmethod
    def _connection_shape(cls, value):
        """One clear message for a malformed entry (instead of the tuple union's two)."""
        for i, c in enumerate(value if isinstance(value, list) else []):
            ok = isinstance(c, list | tuple) and len(c) in (2, 3) \
                and all(isinstance(s, str) for s in c[:2]) \
                and (len(c) == 2 or isinstance(c[2], dict | ConnectionTransform))
            if not ok:
                raise ValueError(f"entry {i}: expected [\"fmu.output\", \"fmu.input\"] or "
                                 f"[output, input, {{factor = ..., offset = ...}}], got {c!r}")
            if len(c) == 3 and isinstance(c[2], dict):
                try:
                    TypeAdapter(ConnectionTransform).validate_python(c[2])
                except ValidationError as exc:
                    err = exc.errors()[0]
                    msg = "Extra inputs are not permitted" \
                        if err["type"] == "unexpected_keyword_argument" else err["msg"]
                    raise ValueError(f"entry {i}: {'.'.join(map(str, err['loc']))}: "
                                     f"{msg} (expected factor, offset: numbers)") from None
        return value


class ReplayScenario(Scenario):
    """A scenario with ``[replay]``: no FMUs (the file gives the measurements, controls and
    reference); ``[run]`` without a step. The sections that drive FMUs (``[fmus]``,
    ``connections``, ``[controls]``, ``[noise]``, ``[system]``) must stay empty
    (:func:`uwcosim.scenario.replay.replay_problems` says so, key by key)."""

    run: ReplayRunSpec = ReplayRunSpec()
    fmus: dict[Str, FMU] = {}
    replay: ReplaySpec


def scenario_model(data: dict) -> type[Scenario]:
    """The schema of scenario data: :class:`ReplayScenario` with a ``[replay]`` table."""
    return ReplayScenario if isinstance(data.get("replay"), dict) else Scenario
