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
    SerializerFunctionWrapHandler,
    field_validator,
    model_serializer,
    model_validator,
)

import gnp
from app.settings.arenas import inline_arena
from app.settings.fields import read_setting, setting, settings_of
from gnp import METHODS, TRAITS, EvolutionConfig, GnpConfig, Method, Schedule
from gnp.config import (
    GenerationProgress,
    ProcessingOutput,
    SkipReward,
    ThresholdInit,
    TieBreak,
)
from neuro.neat_params import NeatParams
from sim import CONTROL_PERIOD_S, IR_MAX, LIFE_STEPS, N_SENSORS, FaultMode, NoiseStream, Physics
from sim.arena import ArenaSpec
from sim.kinds import CFrom

ScheduleKind = Literal["fixed", "changing"]

PRESET_NAMES = ("quick", "thesis-ch2", "thesis-ch3", "thesis-ch4", "thesis-ch5")


class ConfigError(ValueError):
    """A configuration value, file or preset is invalid; the message names the problem."""


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


def _of_gnp(name: str, unit: str | None = None, **narrower: Any) -> Any:
    """A `ControllerSettings` field with the default and description `gnp.GnpConfig` gives it
    (written there once), and its bounds unless the lab allows `narrower` ones."""
    fact = read_setting(GnpConfig, name)
    assert fact is not None, name
    bounds = dict(narrower)
    if not narrower and fact.low is not None:
        bounds["gt" if fact.low_open else "ge"] = fact.low
    if not narrower and fact.high is not None:
        bounds["lt" if fact.high_open else "le"] = fact.high
    return setting(fact.default, fact.description, unit, **bounds)


def _noise_sigma() -> Any:
    """The sensor noise σ field of both phases (Eq. 2.6), its range written here once: the
    live noise of the dashboard is checked against it too (`app.phases.live.checked_noise`)."""
    return setting(0.0, "sensor noise σ", "reading", label="Noise σ", ge=0.0, le=IR_MAX)


class ControllerSettings(_Frozen):
    """The GNP individual (Tables 2.4, 3.1, 5.1). Defaults and descriptions are gnp's
    (`GnpConfig`); the lab keeps narrower bounds on the sizes."""

    method: Method = Field(
        default=preset_layer(METHOD_PRESET)["controller"]["method"],
        description="GNP-RL (RL), GNP-TSRL with branch selection (BS) or credit (CS)",
    )
    fuzzy: bool = _of_gnp("fuzzy")
    n_judgment: int = _of_gnp("n_judgment", "count", ge=8, le=400)
    n_processing: int = _of_gnp("n_processing", "count", ge=2, le=200)
    n_sub: int | None = setting(
        None,
        "sub nodes per node; unset = the thesis's choice for the method ("
        + ", ".join(f"{m} {TRAITS[m].default_n_sub}" for m in METHODS)
        + "; Tables 3.1, 5.1)",
        "count",
        ge=1,
        le=8,
    )
    n_branch: int = _of_gnp("n_branch", ge=1, le=8)
    gamma: float = _of_gnp("gamma", "1")
    q0: float = _of_gnp("q0", "1")
    tie_break: TieBreak = _of_gnp("tie_break")
    skip_reward: SkipReward = _of_gnp("skip_reward")
    threshold_init: ThresholdInit = _of_gnp("threshold_init")
    processing_output: ProcessingOutput = _of_gnp("processing_output")

    @property
    def sub_nodes(self) -> int:
        """Sub nodes per node, resolving the method's thesis default."""
        if self.n_sub is not None:
            return self.n_sub
        return TRAITS[self.method].default_n_sub

    def gnp_config(self) -> GnpConfig:
        """The brain's config for these settings."""
        return GnpConfig(
            method=self.method,
            fuzzy=self.fuzzy,
            n_judgment=self.n_judgment,
            n_processing=self.n_processing,
            n_sub=self.sub_nodes,
            n_branch=self.n_branch,
            gamma=self.gamma,
            q0=self.q0,
            tie_break=self.tie_break,
            skip_reward=self.skip_reward,
            threshold_init=self.threshold_init,
            processing_output=self.processing_output,
        )


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
        default="pymunk",
        description="the world's physics in both phases, like control_period: pymunk (the "
        "reference) or analytic (the same contacts in numba, faster, for sweeps)",
    )
    noise_stream: NoiseStream = Field(
        default="box-muller-v1",
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

    def schedules(self) -> tuple[Schedule, Schedule]:
        """(ε, α) over generations: fixed values, or Eq. 4.1-4.2 from max to min."""
        return _schedules(self)


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

    def schedules(self) -> tuple[Schedule, Schedule]:
        """(ε, α) after the fault: fixed values, or Eq. 4.3-4.4 from max to min."""
        return _schedules(self)

    def learning(self) -> LearningSettings:
        """Online learning of the trials: fixed ε/α until t', then the configured schedule
        over T − t'."""
        return LearningSettings(
            epsilon=self.epsilon,
            alpha=self.alpha,
            after_fault=self.schedules() if self.schedule == "changing" else None,
            horizon=max(1, self.steps - self.fault_step),
        )

    @field_validator("broken_sensors")
    @classmethod
    def _sensors_in_range(cls, sensors: tuple[int, ...]) -> tuple[int, ...]:
        if any(not 0 <= s < N_SENSORS for s in sensors):
            raise ValueError(f"sensors are numbered 0..7, got {list(sensors)}")
        if len(set(sensors)) != len(sensors):
            raise ValueError(f"a sensor is listed twice in {list(sensors)}")
        return tuple(sorted(sensors))


_IMPLEMENTATION = ImplementationSettings.model_fields
_IMPLEMENTATION_FACTS = {s.name: s for s in settings_of(ImplementationSettings)}


@dataclass(frozen=True)
class LearningSettings:
    """Online Sarsa of a batch: ε and α at each step, given the step of the latest fault.

    Before any fault ε/α are the fixed values (thesis §4.5: fixed until t'); from a fault on they
    follow `after_fault`, the (ε, α) schedules of Eq. 4.3–4.4 from max to min over `horizon`
    steps (the implementation phase's T − t'), or stay fixed when it is None.
    """

    online: bool = True
    # Defaults: the implementation phase's (ImplementationSettings), written there once.
    epsilon: float = _IMPLEMENTATION["epsilon"].default
    alpha: float = _IMPLEMENTATION["alpha"].default
    after_fault: tuple[gnp.Schedule, gnp.Schedule] | None = None
    horizon: int = _IMPLEMENTATION["steps"].default - _IMPLEMENTATION["fault_step"].default
    second_stage: bool = True  # off: live ablation of BS's branch / CS's credit (gnp.step)

    def __post_init__(self) -> None:
        # Built directly too (the page's learning, a live session), not only from checked
        # settings: the same bounds as the implementation phase's fields.
        for name, field in (("ε", "epsilon"), ("α", "alpha")):
            value, fact = getattr(self, field), _IMPLEMENTATION_FACTS[field]
            low, high = fact.low, fact.high
            assert low is not None and high is not None  # both fields are bounded
            if not low <= value <= high:
                raise ValueError(f"{name} must be in {fact.range_text()}, got {value}")
        fewest = _IMPLEMENTATION_FACTS["steps"].low  # a horizon is some of the phase's steps
        assert fewest is not None
        if self.horizon < fewest:
            raise ValueError(f"the schedule horizon must be ≥ {fewest} step, got {self.horizon}")

    def rates(self, t: int, fault_step: int | None) -> tuple[float, float]:
        """ε and α at step `t`, the latest fault (or the phase's t') at `fault_step`."""
        if self.after_fault is None or fault_step is None or t < fault_step:
            return self.epsilon, self.alpha
        return gnp.epsilon_alpha_after_fault(
            *self.after_fault, t, fault_step, fault_step + self.horizon
        )


def _check_ordered(settings: TrainingSettings | ImplementationSettings) -> None:
    for name in ("epsilon", "alpha"):
        low, high = getattr(settings, f"{name}_min"), getattr(settings, f"{name}_max")
        if low > high:
            raise ValueError(f"{name}_min ({low}) must not exceed {name}_max ({high})")


def _schedules(settings: TrainingSettings | ImplementationSettings) -> tuple[Schedule, Schedule]:
    if settings.schedule == "fixed":
        return Schedule.fixed(settings.epsilon), Schedule.fixed(settings.alpha)
    return (
        Schedule(max=settings.epsilon_max, min=settings.epsilon_min, n=settings.schedule_n),
        Schedule(max=settings.alpha_max, min=settings.alpha_min, n=settings.schedule_n),
    )


class RewardSettings(_Frozen):
    """The reward of Eq. 2.7 (thesis §2.5.2)."""

    c_from: CFrom = Field(
        default="true",
        description="readings C of Eq. 2.7 is judged from (C = 1 iff every reading < 1000 and "
        "at least one > 100): the true readings, or those the controller sees (observed: "
        "noise of Eq. 2.6, then faults)",
    )


Optimiser = Literal["cmaes", "neat"]


DEFAULT_BRAIN = "gnp"
"""The brain family of a config that names none: GNP, the thesis's."""


class NeuroSettings(_Frozen):
    """A neural controller instead of GNP (issue #23): an Elman net evolved by CMA-ES (pycma),
    or a NEAT net (neat-python). It does not learn online; training's ε/α are unused."""

    optimiser: Optimiser = Field(description="CMA-ES on an Elman net's weights, or NEAT")
    hidden: int = setting(8, "Elman hidden units (CMA-ES)", "count", ge=1, le=64)
    sigma0: float = setting(0.5, "CMA-ES initial step size, from weights 0", "1", gt=0.0, le=10.0)
    neat: NeatParams = NeatParams()

    @property
    def name(self) -> str:
        """The brain family this section selects: its optimiser's."""
        return self.optimiser


class FamilySettings(BaseModel):
    """A brain family registered from outside the lab (`app.brains.register`): its name and
    its own settings, which the family checks with a model of its own when the run starts."""

    model_config = ConfigDict(frozen=True, extra="allow")
    name: str = Field(description="the family's registered name")


class RunConfig(_Frozen):
    """Everything a run's results depend on (worker count excluded: results do not depend on it)."""

    seed: int = Field(default=0, ge=0, le=2**63 - 1, description="random seed of the run")
    controller: ControllerSettings = ControllerSettings()
    evolution: EvolutionConfig = EvolutionConfig()
    training: TrainingSettings = TrainingSettings()
    implementation: ImplementationSettings = ImplementationSettings()
    reward: RewardSettings = RewardSettings()
    neuro: NeuroSettings | None = Field(
        default=None, description="a neural controller instead of GNP; unset = GNP"
    )
    family: FamilySettings | None = Field(
        default=None, description="a brain family registered from outside the lab; unset = GNP"
    )

    @model_validator(mode="after")
    def _one_brain(self) -> RunConfig:
        if self.neuro is not None and self.family is not None:
            raise ValueError("a run has one brain: set `neuro` or `family`, not both")
        return self

    @property
    def brain(self) -> str:
        """The name of the brain family (`app.brains`) that runs: the section that names one,
        else GNP."""
        section = self.neuro or self.family
        return section.name if section is not None else DEFAULT_BRAIN

    @model_serializer(mode="wrap")
    def _gnp_as_before(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        # A run's stored config keeps the layout it had before other brains existed.
        data: dict[str, Any] = handler(self)
        for section in ("neuro", "family"):
            if getattr(self, section) is None:
                data.pop(section, None)
        return data
