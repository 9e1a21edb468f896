"""The scenario schema (pydantic): every key, its type and its default.

A scenario names the FMUs and how they connect, the control inputs, the noise, the sensors and
their loss models, the filter model and estimators, the run length, step and seed, and what to
log. Unknown keys are errors. Cross-references (connections, targets, sensors) are checked in
:mod:`uwcosim.scenario.validate` against the FMUs' model descriptions.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

Scalar = float | int | bool | str
#: a start value or parameter: any FMI scalar as TOML gives it, or an array (FMI 3 arrays)
Value = Scalar | list[float | int | bool]
PositiveFloat = Annotated[float, Field(gt=0)]
PositiveInt = Annotated[int, Field(ge=1)]
Probability = Annotated[float, Field(ge=0.0, le=1.0)]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class RunSpec(Strict):
    duration: PositiveFloat
    step: PositiveFloat
    start_time: float = 0.0
    seed: int = 0
    #: an FMU's request to stop ends the run with status "terminated" (exit 0) or, with
    #: "error", as a failure (exit 3)
    stop_on_terminate: Literal["stop", "error"] = "stop"


class FMUSpec(Strict):
    path: str
    interface: Literal["cs", "me"] = "cs"
    solver: Literal["rk4", "adaptive"] = "rk4"
    substeps: PositiveInt = 1
    period: PositiveInt = 1
    rtol: PositiveFloat = 1e-8
    parameters: dict[str, Value] = {}
    start: dict[str, Value] = {}
    #: roles -> FMU variables with unit conversion (a TOML file name or an inline table;
    #: see :mod:`uwcosim.master.varmap`); start values may then use the role names
    map: str | dict[str, str | dict[str, Scalar]] | None = None
    #: role table the map is checked against (default: the FMU's name if it is a role)
    role: Literal["vehicle"] | None = None
    #: per-call time limit (s): the FMU then runs in a worker process, killed on timeout
    timeout_s: PositiveFloat | None = None


class ConnectionTransform(Strict):
    """A linear transformation on a connection: ``input = factor * output + offset``."""

    factor: float = 1.0
    offset: float = 0.0


#: ``[output, input]`` or ``[output, input, {factor = ..., offset = ...}]``
Connection = tuple[str, str] | tuple[str, str, ConnectionTransform]


class SystemSpec(Strict):
    """The truth side from another tool: an SSP file (see :mod:`uwcosim.ssp`)."""

    ssp: str


class ControlSpec(Strict):
    target: str
    table: list[tuple[float, float]] | None = None
    waypoints: list[tuple[float, float]] | None = None
    interpolation: Literal["linear", "hold"] = "linear"
    position: tuple[str, str] = ("vehicle.x", "vehicle.y")
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
    targets: list[str]
    psd: list[Annotated[float, Field(ge=0)]]

    @model_validator(mode="after")
    def _same_length(self) -> NoiseSpec:
        if len(self.targets) != len(self.psd):
            raise ValueError(f"'psd' has {len(self.psd)} values for {len(self.targets)} targets")
        return self


class SensorSpec(Strict):
    outputs: list[str]
    noise_inputs: list[str] = []
    sigma: list[Annotated[float, Field(ge=0)]] = []
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
    seed: int = 7
    extent: tuple[float, float, float, float] = (0.0, 25_000.0, 0.0, 25_000.0)
    resolution: PositiveFloat = 50.0
    relief_std: PositiveFloat = 60.0
    file: str | None = None
    variable: str | None = None
    fmu_parameter: str = "sounder.mapFile"

    @model_validator(mode="after")
    def _file(self) -> MapSpec:
        if self.kind == "file" and not self.file:
            raise ValueError("kind = 'file' needs 'file'")
        return self


class ModelSpec(Strict):
    kind: Literal["tan", "cv"] = "tan"
    truth: list[str]
    controls: list[str] = []
    sensors: list[str]
    q_psd: list[float] | None = None


class EstimatorSpec(BaseModel):
    """``type`` picks the filter; ``policy`` the lost-measurement policy; other keys are the
    filter's own settings (checked by the filter)."""

    model_config = ConfigDict(extra="allow")
    type: str
    policy: str = "skip"
    sensors: list[str] | None = None
    initial_std: list[Annotated[float, Field(gt=0)]] | None = None


class EstimationSpec(Strict):
    initial_std: list[Annotated[float, Field(gt=0)]]
    initial_error: Literal["random", "zero"] = "random"


class LogSpec(Strict):
    signals: list[str] = ["*"]
    chunk_steps: PositiveInt = 1000


class OutputSpec(Strict):
    figures: bool = True
    density_snapshots: list[float] = []


class Scenario(Strict):
    name: str = "scenario"
    description: str = ""
    run: RunSpec
    system: SystemSpec | None = None
    fmus: dict[str, FMUSpec]
    connections: list[Connection] = []
    controls: dict[str, ControlSpec] = {}
    noise: dict[str, NoiseSpec] = {}
    sensors: dict[str, SensorSpec] = {}
    map: MapSpec | None = None
    model: ModelSpec | None = None
    estimation: EstimationSpec | None = None
    estimators: dict[str, EstimatorSpec] = {}
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
