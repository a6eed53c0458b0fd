"""Run configuration: frozen pydantic models with the thesis's defaults, presets and TOML files.

A run is a function of its `RunConfig` and seed. Every field carries its range and unit; a bad
value raises `ConfigError` naming the field and what it allows.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializeAsAny,
    field_validator,
    model_validator,
)

from app.settings.arenas import inline_arena
from app.settings.errors import ConfigError
from app.settings.families import DEFAULT_BRAIN, BrainSettings, brain_section
from app.settings.fields import setting
from app.settings.layouts import layout_2
from sim import (
    CONTROL_PERIOD_S,
    DEFAULT_NOISE_STREAM,
    DEFAULT_PHYSICS,
    IR_MAX,
    LIFE_STEPS,
    N_SENSORS,
    FaultMode,
    NoiseStream,
    Physics,
)
from sim.arena import ArenaSpec
from sim.kinds import CFrom

ScheduleKind = Literal["fixed", "changing"]
GenerationProgress = Literal["last-generation-min", "g-over-G"]
"""How far Eq. 4.1-4.2 is at generation g: gnp's `gnp.config.GenerationProgress`, whose values
these are (tests/app/design/test_facts_once.py checks they agree)."""

PRESET_NAMES = ("quick", "thesis-ch2", "thesis-ch3", "thesis-ch4", "thesis-ch5")


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


def preset_layer(name: str) -> dict[str, Any]:
    """The raw settings of a shipped preset (see `PRESET_NAMES`)."""
    if name not in PRESET_NAMES:
        raise ConfigError(f"unknown preset {name!r}; choose one of {', '.join(PRESET_NAMES)}")
    text = (
        resources.files("app.settings.presets").joinpath(f"{name}.toml").read_text(encoding="utf-8")
    )
    return tomllib.loads(text)


METHOD_PRESET = "thesis-ch5"
"""The preset whose method is the lab's default: the thesis's last, GNP-TSRL with credit (CS),
where gnp's own default is its first (RL)."""


def _noise_sigma() -> Any:
    """The sensor noise σ field of both phases (Eq. 2.6), its range written here once: the
    live noise of the dashboard is checked against it too (`app.phases.live.checked_noise`)."""
    return setting(0.0, "sensor noise σ", "reading", label="Noise σ", ge=0.0, le=IR_MAX)


RATE_FIELDS = (
    "schedule",
    "epsilon",
    "alpha",
    "epsilon_max",
    "epsilon_min",
    "alpha_max",
    "alpha_min",
    "schedule_n",
)
"""The ε/α settings of both phases, in the order their models (and stored configs) list them."""


@dataclass(frozen=True)
class _PhaseRates:
    """What one phase's ε/α settings have of their own: the equations of its changing schedule,
    when that schedule starts and ends, and its defaults there (max, min)."""

    equations: str
    start: str
    end: str
    epsilon: tuple[float, float]
    alpha: tuple[float, float]


_TRAINING_RATES = _PhaseRates(
    "Eq. 4.1-4.2", "g = 0", "the last generation", epsilon=(0.15, 0.01), alpha=(0.70, 0.10)
)
_IMPLEMENTATION_RATES = _PhaseRates(
    "Eq. 4.3-4.4", "t = t'", "t = T", epsilon=(0.015, 0.0), alpha=(0.15, 0.0)
)


def _rate(phase: _PhaseRates, name: str) -> Any:
    """The ε/α field `name` (one of RATE_FIELDS) with `phase`'s defaults and wording: the type,
    bounds and text of each rate are written here once, for both phases."""
    if name == "schedule":
        return Field(default="fixed", description=f"ε/α fixed, or changing by {phase.equations}")
    if name == "schedule_n":
        return Field(default=1.0, gt=0.0, le=100.0, description=f"exponent n of {phase.equations}")
    if name == "epsilon":
        return setting(0.1, "fixed ε-greedy", "1", ge=0.0, le=1.0)
    if name == "alpha":
        return setting(0.1, "fixed learning rate α", "1", ge=0.0, le=1.0)
    rate, end = name.split("_")  # e.g. epsilon_max
    high, low = getattr(phase, rate)
    default, when = (high, phase.start) if end == "max" else (low, phase.end)
    symbol = {"epsilon": "ε", "alpha": "α"}[rate]
    return setting(default, f"changing {symbol} at {when}", "1", ge=0.0, le=1.0)


class TrainingSettings(_Frozen):
    """The training phase (thesis §2.5, 3.5, 4.5, 5.5)."""

    arena: ArenaSpec = Field(
        default="training",  # inlined by the validator
        validate_default=True,
        description="arena: a shipped name or a JSON file, stored inline",
    )
    _inline_arena = field_validator("arena", mode="before")(inline_arena)
    population: int = setting(300, "individuals", "count", ge=2, le=100_000)
    generations: int = setting(1000, "generations G", "count", ge=1, le=1_000_000)
    steps: int = setting(
        LIFE_STEPS, "life time T", "control steps", label="Life T (steps)", ge=1, le=1_000_000
    )
    redraw_every: int = setting(
        0, "new start pose every R steps, 0 = never", "steps", ge=0, le=1_000_000
    )
    noise_sigma: float = _noise_sigma()
    control_period: float = setting(CONTROL_PERIOD_S, "control step", "s", gt=0.0, le=1.0)
    physics: Physics = Field(
        default=DEFAULT_PHYSICS,
        description="the world's physics in both phases, like control_period: pymunk (the "
        "reference) or analytic (the same contacts in numba, faster, for sweeps)",
    )
    noise_stream: NoiseStream = Field(
        default=DEFAULT_NOISE_STREAM,
        description="how the sensor noise's normals are drawn in both phases: box-muller-v1 "
        "(every earlier run's bits) or ziggurat-v1 (faster, other draws of the same N(0, σ²))",
    )
    # ε/α: the fields every phase has (RATE_FIELDS), written once in `_rate`
    schedule: ScheduleKind = _rate(_TRAINING_RATES, "schedule")
    epsilon: float = _rate(_TRAINING_RATES, "epsilon")
    alpha: float = _rate(_TRAINING_RATES, "alpha")
    epsilon_max: float = _rate(_TRAINING_RATES, "epsilon_max")
    epsilon_min: float = _rate(_TRAINING_RATES, "epsilon_min")
    alpha_max: float = _rate(_TRAINING_RATES, "alpha_max")
    alpha_min: float = _rate(_TRAINING_RATES, "alpha_min")
    schedule_n: float = _rate(_TRAINING_RATES, "schedule_n")
    schedule_progress: GenerationProgress = Field(
        default="last-generation-min",
        description="progress of Eq. 4.1-4.2 at generation g = 0..G-1: g/(G-1), so the last "
        "generation uses the min (last-generation-min), or g/G as printed (g-over-G)",
    )
    checkpoint_every: int = setting(
        1, "full-population checkpoint period", "generations", ge=1, le=1_000_000
    )
    shard_size: int = setting(
        75,
        "robots per simulated world, the unit of work a worker owns "
        "(at most one worker per shard is used)",
        "robots",
        ge=1,
        le=100_000,
    )

    @model_validator(mode="after")
    def _ordered(self) -> TrainingSettings:
        _check_ordered(self)
        return self


class ImplementationSettings(_Frozen):
    """The implementation phase: a trained individual in an unseen arena, sensors breaking."""

    arena: ArenaSpec = Field(
        default="implementation",  # inlined by the validator
        validate_default=True,
        description="arena: a shipped name or a JSON file, stored inline",
    )
    _inline_arena = field_validator("arena", mode="before")(inline_arena)
    steps: int = setting(3000, "life time T", "control steps", ge=1, le=1_000_000)
    repeats: int = setting(300, "trials per start pose", "count", ge=1, le=100_000)
    noise_sigma: float = _noise_sigma()
    broken_sensors: tuple[int, ...] = Field(
        default=(), max_length=N_SENSORS, description="sensors that break at the fault step, 0..7"
    )
    break_count: int = setting(
        0,
        "k sensors that break at the fault step, drawn per trial from its own "
        "seeded stream (instead of a fixed `broken_sensors` set)",
        "count",
        ge=0,
        le=N_SENSORS,
    )
    fault_mode: FaultMode = Field(default="dead", description="what a broken sensor reads")
    fault_step: int = setting(500, "fault step t'", "control steps", ge=0, le=1_000_000)
    # ε/α: the fields every phase has (RATE_FIELDS), written once in `_rate`
    schedule: ScheduleKind = _rate(_IMPLEMENTATION_RATES, "schedule")
    epsilon: float = _rate(_IMPLEMENTATION_RATES, "epsilon")
    alpha: float = _rate(_IMPLEMENTATION_RATES, "alpha")
    epsilon_max: float = _rate(_IMPLEMENTATION_RATES, "epsilon_max")
    epsilon_min: float = _rate(_IMPLEMENTATION_RATES, "epsilon_min")
    alpha_max: float = _rate(_IMPLEMENTATION_RATES, "alpha_max")
    alpha_min: float = _rate(_IMPLEMENTATION_RATES, "alpha_min")
    schedule_n: float = _rate(_IMPLEMENTATION_RATES, "schedule_n")
    recorded_trials: int = setting(
        3, "trials whose trajectory and trace are stored", "count", ge=0, le=100
    )
    generation: int | None = Field(
        default=None, ge=0, description="take the best of this generation; unset = the final elite"
    )
    seed: int | None = Field(default=None, ge=0, description="random seed; unset = the run's seed")

    @model_validator(mode="after")
    def _consistent(self) -> ImplementationSettings:
        _check_ordered(self)
        if self.broken_sensors and self.break_count:
            raise ValueError(
                "give either broken_sensors (a fixed set) or break_count (k random sensors "
                "per trial), not both"
            )
        if self.has_fault and self.fault_step >= self.steps:
            raise ValueError(
                f"fault_step ({self.fault_step}) must be below steps ({self.steps}) "
                "for the sensors to break"
            )
        return self

    @property
    def has_fault(self) -> bool:
        """Whether any sensor breaks."""
        return bool(self.broken_sensors) or self.break_count > 0

    @field_validator("broken_sensors")
    @classmethod
    def _sensors_in_range(cls, sensors: tuple[int, ...]) -> tuple[int, ...]:
        if any(not 0 <= s < N_SENSORS for s in sensors):
            raise ValueError(f"sensors are numbered 0..7, got {list(sensors)}")
        if len(set(sensors)) != len(sensors):
            raise ValueError(f"a sensor is listed twice in {list(sensors)}")
        return tuple(sorted(sensors))


def _check_ordered(settings: TrainingSettings | ImplementationSettings) -> None:
    for name in ("epsilon", "alpha"):
        low, high = getattr(settings, f"{name}_min"), getattr(settings, f"{name}_max")
        if low > high:
            raise ValueError(f"{name}_min ({low}) must not exceed {name}_max ({high})")


class RewardSettings(_Frozen):
    """The reward of Eq. 2.7 (thesis §2.5.2)."""

    c_from: CFrom = Field(
        default="true",
        description="readings C of Eq. 2.7 is judged from (C = 1 iff every reading < 1000 and "
        "at least one > 100): the true readings, or those the controller sees (observed: "
        "noise of Eq. 2.6, then faults)",
    )


def _default_brain() -> dict[str, Any]:
    return {"family": DEFAULT_BRAIN}  # checked with GNP's model when a config is made


def brain_field() -> Any:
    """The `brain` field of a run's config (a robot run's, a task run's): the family's section,
    checked with its model by `app.settings.families.brain_section` (a model that has this
    field validates it with that, `mode="before"`), GNP's by default."""
    return Field(
        default_factory=_default_brain,
        validate_default=True,
        description="the brain family that runs and its own settings",
    )


class RunConfig(_Frozen):
    """Everything a run's results depend on (worker count excluded: results do not depend on it).

    `brain` is the family's section (layout 2, app/settings/layouts.py): `brain.family` names
    the family and the section is checked with the model the family declares (GNP's
    `controller` and `evolution`, a net's size); a config in layout 1 is moved to it when read.
    """

    seed: int = Field(default=0, ge=0, le=2**63 - 1, description="random seed of the run")
    brain: SerializeAsAny[BrainSettings] = brain_field()
    training: TrainingSettings = TrainingSettings()
    implementation: ImplementationSettings = ImplementationSettings()
    reward: RewardSettings = RewardSettings()

    @model_validator(mode="before")
    @classmethod
    def _in_layout_2(cls, data: Any) -> Any:
        return layout_2(data) if isinstance(data, dict) else data

    _brain_section = field_validator("brain", mode="before")(brain_section)
