"""The scenario schema (pydantic): every key, its type and its default.

A scenario names the FMUs and how they connect, the control inputs, the noise, the sensors and
their loss models, the filter model and estimators, the run length, step and seed, and what to
log. Unknown keys are errors. :mod:`uwcosim.scenario.validate` reports every error of this
schema at once, checks each ``[estimators.NAME]`` against its filter's settings model and the
cross-references between sections; the FMU variables (connections, targets, sensors) are
checked against the FMUs' model descriptions by the master (``uwcosim check`` runs both).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    StrictFloat,
    StrictInt,
    StrictStr,
    ValidationError,
    field_validator,
    model_validator,
)

# Strict types: a TOML string is never taken for a number ("50" is refused for a duration),
# a float never for an integer; an integer is a valid float. NaN and infinity are refused
# everywhere (``allow_inf_nan=False``).
Float, Int, Bool, Str = StrictFloat, StrictInt, StrictBool, StrictStr
Scalar = StrictFloat | StrictInt | StrictBool | StrictStr
#: a start value or parameter: any FMI scalar as TOML gives it, or an array (FMI 3 arrays)
Value = Scalar | list[StrictFloat | StrictInt | StrictBool]
PositiveFloat = Annotated[StrictFloat, Field(gt=0)]
NonNegativeFloat = Annotated[StrictFloat, Field(ge=0)]
PositiveInt = Annotated[StrictInt, Field(ge=1)]
Probability = Annotated[StrictFloat, Field(ge=0.0, le=1.0)]
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


class FMUSpec(Strict):
    path: Str
    interface: Literal["cs", "me"] = "cs"
    solver: Literal["rk4", "adaptive"] = "rk4"
    substeps: PositiveInt = 1
    period: PositiveInt = 1
    rtol: PositiveFloat = 1e-8
    parameters: dict[Str, Value] = {}
    start: dict[Str, Value] = {}
    #: roles -> FMU variables with unit conversion (a TOML file name or an inline table;
    #: see :mod:`uwcosim.master.varmap`); start values may then use the role names
    map: Str | dict[Str, Str | dict[Str, Scalar]] | None = None
    #: role table the map is checked against (default: the FMU's name if it is a role)
    role: Literal["vehicle"] | None = None
    #: per-call time limit (s): the FMU then runs in a worker process, killed on timeout
    timeout_s: PositiveFloat | None = None


class ConnectionTransform(Strict):
    """A linear transformation on a connection: ``input = factor * output + offset``."""

    factor: Float = 1.0
    offset: Float = 0.0


#: ``[output, input]`` or ``[output, input, {factor = ..., offset = ...}]``
Connection = tuple[Str, Str] | tuple[Str, Str, ConnectionTransform]


class SystemSpec(Strict):
    """The truth side from another tool: an SSP file (see :mod:`uwcosim.ssp`)."""

    ssp: Str


class ControlSpec(Strict):
    target: Str
    table: list[tuple[Float, Float]] | None = None
    waypoints: list[tuple[Float, Float]] | None = None
    interpolation: Literal["linear", "hold"] = "linear"
    position: tuple[Str, Str] = ("vehicle.x", "vehicle.y")
    acceptance_radius: PositiveFloat = 50.0

    @model_validator(mode="after")
    def _one_kind(self) -> ControlSpec:
        if (self.table is None) == (self.waypoints is None):
            raise ValueError("give exactly one of 'table' or 'waypoints'")
        if self.table is not None:
            times = [t for t, _ in self.table]
            if not times or any(b <= a for a, b in zip(times, times[1:])):
                raise ValueError("'table' needs at least one [time, value] row, times increasing")
        if self.waypoints is not None and len(self.waypoints) < 1:
            raise ValueError("'waypoints' needs at least one [x, y] point")
        return self


class BernoulliLoss(Strict):
    model: Literal["bernoulli"]
    p: Probability = 0.0


class GilbertElliottLoss(Strict):
    model: Literal["gilbert_elliott"]
    p_good_to_bad: Probability
    p_bad_to_good: Probability
    loss_good: Probability = 0.0
    loss_bad: Probability = 1.0


LossSpec = Annotated[BernoulliLoss | GilbertElliottLoss, Field(discriminator="model")]


class NoiseSpec(Strict):
    targets: list[Str]
    psd: list[NonNegativeFloat]

    @model_validator(mode="after")
    def _same_length(self) -> NoiseSpec:
        if len(self.targets) != len(self.psd):
            raise ValueError(f"'psd' has {len(self.psd)} values for {len(self.targets)} targets")
        return self


class SensorSpec(Strict):
    outputs: list[Str]
    noise_inputs: list[Str] = []
    sigma: list[NonNegativeFloat] = []
    period: PositiveInt = 1
    loss: LossSpec | None = None

    @model_validator(mode="after")
    def _same_length(self) -> SensorSpec:
        if self.noise_inputs and len(self.noise_inputs) != len(self.sigma):
            raise ValueError(
                f"'sigma' has {len(self.sigma)} values for {len(self.noise_inputs)} noise_inputs"
            )
        if not self.noise_inputs and self.sigma and len(self.sigma) != len(self.outputs):
            raise ValueError(
                f"'sigma' without noise_inputs is additive noise on the outputs: it needs "
                f"{len(self.outputs)} values, got {len(self.sigma)}"
            )
        return self


class MapSpec(Strict):
    kind: Literal["synthetic", "file"] = "synthetic"
    seed: Int = 7
    extent: tuple[Float, Float, Float, Float] = (0.0, 25_000.0, 0.0, 25_000.0)
    resolution: PositiveFloat = 50.0
    relief_std: PositiveFloat = 60.0
    file: Str | None = None
    variable: Str | None = None
    fmu_parameter: Str = "sounder.mapFile"

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
    kind: Literal["tan", "cv"] = "tan"
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
    #: extent widened by its larger side; uwcosim.divergence)
    position_bound: tuple[Float, Float, Float, Float] | None = None

    @model_validator(mode="after")
    def _bound(self) -> EstimationSpec:
        b = self.position_bound
        if b is not None and not (b[0] < b[1] and b[2] < b[3]):
            raise ValueError(f"'position_bound' must be [xmin, xmax, ymin, ymax] with "
                             f"xmin < xmax and ymin < ymax (got {list(b)})")
        return self


class LogSpec(Strict):
    signals: list[Str] = ["*"]
    chunk_steps: PositiveInt = 1000


class OutputSpec(Strict):
    figures: Bool = True
    density_snapshots: list[Float] = []


class Scenario(Strict):
    name: Str = "scenario"
    description: Str = ""
    run: RunSpec
    system: SystemSpec | None = None
    fmus: dict[Str, FMUSpec]
    connections: list[Connection] = []
    controls: dict[Str, ControlSpec] = {}
    noise: dict[Str, NoiseSpec] = {}
    sensors: dict[Str, SensorSpec] = {}
    map: MapSpec | None = None
    model: ModelSpec | None = None
    estimation: EstimationSpec | None = None
    estimators: dict[Str, EstimatorSpec] = {}
    log: LogSpec = LogSpec()
    output: OutputSpec = OutputSpec()

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
                    ConnectionTransform.model_validate(c[2])
                except ValidationError as exc:
                    err = exc.errors()[0]
                    raise ValueError(f"entry {i}: {'.'.join(map(str, err['loc']))}: "
                                     f"{err['msg']} (expected factor, offset: numbers)") from None
        return value
