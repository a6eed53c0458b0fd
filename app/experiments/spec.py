"""Experiments as data: a validated TOML file of arms × seeds × implementation conditions.

An experiment names a base preset and overlay, arms (config overlays), implementation
conditions (ImplementationSettings overlays), the comparisons it makes (claims of the thesis),
the thesis's own numbers, and scales (`smoke`, `small`, `thesis`: overlays applied last, with a
seed count). The config of arm A, seed i, at scale S is

    thesis defaults ← preset ← base overlay ← arm A ← scale S ← {seed = i}

and condition C implements it with `[implementation]` ← condition C ← scale S's
`[implementation]`, so a scale sizes every condition. Every arm × condition × scale config is
validated when the file loads; a bad file raises `ExperimentError` with one line naming the
problem.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from app.experiments.results import (
    METRICS,
    TASK_METRICS,
    Arm,
    ClaimKind,
    Comparison,
    Condition,
    Direction,
    Family,
    MarginForm,
    ThesisValue,
)
from app.settings.config import (
    PRESET_NAMES,
    ConfigError,
    ImplementationSettings,
    RunConfig,
    preset_layer,
)
from app.settings.loading import build_config, describe_problems

Scale = Literal["smoke", "small", "thesis"]
SCALES: tuple[Scale, ...] = get_args(Scale)
SHIPPED_PACKAGE = "app.experiments.shipped"
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,63}$")
_NAME_RULE = "1-64 letters, digits, '_', '.' or '-', starting with a letter or digit"


class ExperimentError(ValueError):
    """An experiment file, name or folder cannot be used as asked; the message is one line."""


def check_name(name: str, what: str = "experiment name") -> str:
    """A name that is safe as a file or folder name (no path, no hidden file)."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(f"{what} {name!r} must be {_NAME_RULE}")
    return name


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class ArmSpec(_Frozen):
    """One arm: a config overlay (e.g. the learning method)."""

    name: str = Field(description="short name used in comparisons and file names")
    label: str = Field(description="as the thesis names it")
    config: dict[str, Any] = Field(default_factory=dict, description="RunConfig overlay")
    brain: Literal["gnp", "fracnetics"] = Field(
        default="gnp",
        description="a task experiment's brain: ours (GNP, as the config says) or fracnetics "
        "with its documented settings (app.tasks.fracnetics_arm)",
    )

    @model_validator(mode="after")
    def _named(self) -> ArmSpec:
        check_name(self.name, "arm name")
        return self


class ConditionSpec(_Frozen):
    """One implementation condition: an ImplementationSettings overlay (faults, noise)."""

    name: str = Field(description="name of the implementation stored in every run file")
    label: str
    implementation: dict[str, Any] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _named(self) -> ConditionSpec:
        check_name(self.name, "condition name")
        return self


class ComparisonSpec(_Frozen):
    """A claim: arm `a` is `direction` than arm `b` on a scalar metric (or, `equivalent`,
    within ±margin of it)."""

    name: str
    a: str
    b: str
    metric: str
    condition: str | None = None
    condition_b: str | None = Field(
        None, description="b's condition: one arm (a = b) compared across two conditions"
    )
    metric_b: str | None = Field(
        None, description="b's metric: one arm (a = b) compared on two metrics"
    )
    direction: Direction
    source: str = Field(description="where the thesis claims it, e.g. 'Fig. 3.9'")
    margin: float | None = Field(
        None,
        gt=0,
        description="the thesis's effect, to rule out (equivalence: the margin), declared "
        "before the runs; in the metric's units or, relative, as a share of b's mean",
    )
    margin_form: MarginForm = "absolute"
    margin_source: str = Field("", description="where the margin comes from, and why")
    role: ClaimKind | None = Field(
        None,
        description="question (a thesis's method-versus-baseline claim) or sanity (within one "
        "arm); unset: sanity when one arm is compared with itself",
    )
    family: Family = Field(
        "primary",
        description="primary: judged with the experiment's family-wise error control; "
        "exploratory: reported with its unadjusted interval, never counted among the verdicts",
    )
    paired: bool | None = Field(
        None,
        description="test paired by seed (the arms share seeds, start poses and broken sensors) "
        "or not, declared before the runs; unset: paired when one arm is compared with itself",
    )

    @model_validator(mode="after")
    def _margin_explained(self) -> ComparisonSpec:
        if self.margin is not None and not self.margin_source:
            raise ValueError(f"comparison {self.name!r}: say where its margin comes from")
        if self.direction == "equivalent" and self.margin is None:
            raise ValueError(f"comparison {self.name!r}: an equivalence claim needs a margin")
        return self


class ThesisValueSpec(_Frozen):
    """A number the thesis reports, to sit beside ours."""

    arm: str
    metric: str
    condition: str | None = None
    value: float
    source: str


class DesignSpec(_Frozen):
    """A pre-registered sequential design: the looks, the cap and the power analysis behind
    them, declared before any run (a decisive experiment)."""

    looks: tuple[int, ...] = Field(
        min_length=1, description="seeds per arm at each look (Lan–DeMets O'Brien–Fleming)"
    )
    max_primary: int = Field(4, ge=1, le=10, description="at most this many primary claims")
    core_hours: float = Field(gt=0, description="the cap in core-hours, all looks together")
    power: str = Field(description="the power analysis that fixed the looks and the cap")

    @model_validator(mode="after")
    def _increasing(self) -> DesignSpec:
        if (
            any(b <= a for a, b in zip(self.looks, self.looks[1:], strict=False))
            or min(self.looks) < 2
        ):
            raise ValueError(f"design.looks must increase from at least 2: {list(self.looks)}")
        return self


class TaskSpec(_Frozen):
    """A task experiment: every run trains on a Gymnasium task instead of the robot, and its
    final elite is tested on the same K episode seeds for every arm (app.tasks.peer)."""

    id: str = Field(description="a Gymnasium id, e.g. CartPole-v1")
    test_seeds: int = Field(default=20, ge=1, le=10_000, description="K test episodes")
    first_test_seed: int = Field(
        default=1_000_000,
        ge=0,
        le=2**31 - 10_001,
        description="test episode seeds first_test_seed..+K-1 (none a training episode's)",
    )

    def seeds(self) -> tuple[int, ...]:
        return tuple(range(self.first_test_seed, self.first_test_seed + self.test_seeds))


class ScaleSpec(_Frozen):
    """A size: a config overlay applied after the arm's, and a seed count."""

    seeds: int | None = Field(default=None, ge=1, le=10_000, description="unset = the file's")
    config: dict[str, Any] = Field(default_factory=dict)
    measured: str = Field(default="", description="a measured wall time, shown by `list`")


def _unique(kind: str, names: list[str]) -> None:
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise ValueError(f"duplicate {kind} name {name!r}")
        seen.add(name)


def _check_metric(where: str, metric: str, condition: str | None, conditions: set[str]) -> None:
    if metric not in METRICS:
        raise ValueError(f"{where}: unknown metric {metric!r}; choose one of {', '.join(METRICS)}")
    if METRICS[metric].scope == "condition":
        if condition is None:
            raise ValueError(f"{where}: metric {metric!r} needs a condition")
        if condition not in conditions:
            raise ValueError(f"{where}: unknown condition {condition!r}")
    elif condition is not None:
        raise ValueError(f"{where}: metric {metric!r} is a training metric; drop the condition")


class ExperimentSpec(_Frozen):
    """A whole experiment file."""

    name: str
    description: str
    source: str = Field(description="the thesis result it reproduces")
    kind: Literal["thesis", "beyond"] = Field(
        default="thesis",
        description="thesis: it asks the thesis's questions; beyond: our own hypotheses (other "
        "controllers, another physics), reported apart",
    )
    preset: str = Field(description=f"base preset: {', '.join(PRESET_NAMES)}")
    seeds: int = Field(
        default=10, ge=1, le=10_000, description="seeds first_seed..first_seed+n-1 (paired)"
    )
    first_seed: int = Field(
        default=0,
        ge=0,
        le=2**31 - 10_001,
        description="the first run seed; a new pre-registration takes seeds no report used",
    )
    design: DesignSpec | None = Field(
        None, description="a pre-registered sequential design (decisive experiments)"
    )
    config: dict[str, Any] = Field(default_factory=dict, description="base overlay")
    arms: tuple[ArmSpec, ...] = Field(min_length=1)
    conditions: tuple[ConditionSpec, ...] = ()
    control: str | None = Field(
        None,
        description="the condition without a fault that `fault_effect` is measured against "
        "(same trial seeds as every condition)",
    )
    comparisons: tuple[ComparisonSpec, ...] = ()
    thesis: tuple[ThesisValueSpec, ...] = ()
    scales: dict[Scale, ScaleSpec] = Field(min_length=1)
    task: TaskSpec | None = Field(
        None, description="a Gymnasium task every run trains on instead of the robot"
    )

    @model_validator(mode="after")
    def _consistent(self) -> ExperimentSpec:
        check_name(self.name)
        self._check_task()
        if self.preset not in PRESET_NAMES:
            raise ValueError(f"unknown preset {self.preset!r}; choose one of {PRESET_NAMES}")
        _unique("arm", [a.name for a in self.arms])
        _unique("condition", [c.name for c in self.conditions])
        _unique("comparison", [c.name for c in self.comparisons])
        arms, conditions = {a.name for a in self.arms}, {c.name for c in self.conditions}
        if self.control is not None and self.control not in conditions:
            raise ValueError(f"control: unknown condition {self.control!r}")
        for comp in self.comparisons:
            where = f"comparison {comp.name!r}"
            for arm in (comp.a, comp.b):
                if arm not in arms:
                    raise ValueError(f"{where}: unknown arm {arm!r}")
            _check_metric(where, comp.metric, comp.condition, conditions)
            paired = comp.condition_b is not None or comp.metric_b is not None
            if not paired and comp.a == comp.b:
                raise ValueError(
                    f"{where}: compares arm {comp.a!r} with itself; give condition_b or "
                    "metric_b to compare it across two conditions or metrics"
                )
            if paired:
                if comp.a != comp.b:
                    raise ValueError(
                        f"{where}: condition_b and metric_b compare one arm with itself; "
                        f"a and b must be the same arm, not {comp.a!r} and {comp.b!r}"
                    )
                metric_b = comp.metric_b or comp.metric
                condition_b = comp.condition_b or comp.condition
                _check_metric(where, metric_b, condition_b, conditions)
                if (metric_b, condition_b) == (comp.metric, comp.condition):
                    raise ValueError(
                        f"{where}: b is the same as a (metric {metric_b!r}, condition "
                        f"{condition_b!r}); give b another condition_b or metric_b"
                    )
            span = METRICS[comp.metric].span
            if comp.margin is not None and comp.margin_form == "absolute" and comp.margin > span:
                raise ValueError(
                    f"{where}: margin {comp.margin:g} exceeds what {comp.metric} can differ by "
                    f"({span:g}): no run could reach it"
                )
            for metric in {comp.metric, comp.metric_b or comp.metric}:
                if METRICS[metric].kind != "scalar":
                    raise ValueError(f"{where}: metric {metric!r} is a curve, not a number")
                if metric == "fault_effect" and self.control is None:
                    raise ValueError(f"{where}: fault_effect needs the experiment's control")
        if self.design is not None:
            self._check_design(self.design)
        for value in self.thesis:
            where = f"thesis value of {value.arm!r} ({value.source})"
            if value.arm not in arms:
                raise ValueError(f"{where}: unknown arm {value.arm!r}")
            _check_metric(where, value.metric, value.condition, conditions)
        return self

    def _check_task(self) -> None:
        """A task experiment has no implementation conditions and measures returns; a robot
        experiment neither measures returns nor has a fracnetics arm."""
        metrics = [(f"comparison {c.name!r}", c.metric) for c in self.comparisons]
        metrics += [(f"comparison {c.name!r}", c.metric_b) for c in self.comparisons if c.metric_b]
        metrics += [(f"thesis value of {v.arm!r}", v.metric) for v in self.thesis]
        if self.task is None:
            for arm in self.arms:
                if arm.brain != "gnp":
                    raise ValueError(f"arm {arm.name!r}: brain {arm.brain!r} needs a task")
            for where, metric in metrics:
                if metric in TASK_METRICS:
                    raise ValueError(f"{where}: metric {metric!r} needs a task")
            return
        if self.conditions or self.control is not None:
            raise ValueError("a task experiment has no conditions or control (its test episodes)")
        if self.design is not None:
            raise ValueError("a task experiment has no sequential design")
        for where, metric in metrics:
            if metric in METRICS and metric not in TASK_METRICS:
                raise ValueError(
                    f"{where}: a task experiment measures {' or '.join(TASK_METRICS)}, "
                    f"not {metric!r}"
                )
        for arm in self.arms:
            if arm.brain == "fracnetics":
                from app.tasks.fracnetics_arm import DOCUMENTED

                if self.task.id not in DOCUMENTED:
                    raise ValueError(
                        f"arm {arm.name!r}: fracnetics documents no settings for "
                        f"{self.task.id!r}; choose one of {', '.join(DOCUMENTED)}"
                    )

    def _check_design(self, design: DesignSpec) -> None:
        primary = [c.name for c in self.comparisons if c.family == "primary"]
        if not primary or len(primary) > design.max_primary:
            raise ValueError(
                f"design: {len(primary)} primary claims; a decisive experiment names 1 to "
                f'{design.max_primary} (mark the others family = "exploratory")'
            )
        undeclared = [c.name for c in self.comparisons if c.paired is None]
        if undeclared:
            raise ValueError(
                f"design: comparison {undeclared[0]!r} must declare paired = true or false"
            )
        for name, scale in self.scales.items():
            if name != "smoke" and scale.seeds is not None and scale.seeds != design.looks[-1]:
                raise ValueError(
                    f"design: scale {name!r} has {scale.seeds} seeds; the last look has "
                    f"{design.looks[-1]}"
                )

    # -- what the runner needs --

    def seed_list(self, scale: Scale, seeds: int | None = None) -> tuple[int, ...]:
        """The paired run seeds first_seed.. (n of them): `seeds` if given, else the scale's,
        else the file's."""
        count = seeds or self.scale(scale).seeds or self.seeds
        return tuple(range(self.first_seed, self.first_seed + count))

    def scale(self, scale: str) -> ScaleSpec:
        """The overlay of a scale this experiment defines."""
        if scale not in self.scales:
            raise ExperimentError(
                f"experiment {self.name!r} has no scale {scale!r}; "
                f"choose one of {', '.join(self.scales)}"
            )
        return self.scales[scale]

    def arm(self, name: str) -> ArmSpec:
        """An arm by name."""
        return next(a for a in self.arms if a.name == name)

    def run_config(self, arm: str, scale: str, seed: int) -> RunConfig:
        """The training config of one (arm, seed) at a scale."""
        layers = (preset_layer(self.preset), self.config, self.arm(arm).config)
        return build_config(*layers, self.scale(scale).config, {"seed": seed})

    def condition_settings(
        self, condition: ConditionSpec, run: RunConfig, scale: str
    ) -> ImplementationSettings:
        """The ImplementationSettings of a condition for a run of this experiment."""
        sized = self.scale(scale).config.get("implementation", {})
        config = build_config(
            {"implementation": run.implementation.model_dump()},
            {"implementation": condition.implementation},
            {"implementation": sized},
        )
        return config.implementation

    # -- the results contract --

    def arms_info(self) -> tuple[Arm, ...]:
        """The arms as the report sees them."""
        return tuple(Arm(a.name, a.label) for a in self.arms)

    def conditions_info(self, scale: str) -> tuple[Condition, ...]:
        """Conditions as the report sees them (sizes of the first arm, seed 0)."""
        run = self.run_config(self.arms[0].name, scale, 0)
        out = []
        for spec in self.conditions:
            s = self.condition_settings(spec, run, scale)
            out.append(
                Condition(
                    name=spec.name,
                    label=spec.label,
                    steps=s.steps,
                    fault_step=s.fault_step if s.has_fault else None,
                    broken_count=s.break_count or len(s.broken_sensors),
                    noise_sigma=s.noise_sigma,
                )
            )
        return tuple(out)

    def comparisons_info(self) -> tuple[Comparison, ...]:
        """The claims as the statistics see them."""
        return tuple(
            Comparison(**c.model_dump(exclude={"paired"}), pairing=c.paired)
            for c in self.comparisons
        )

    def check_control(self, scale: str) -> None:
        """The control condition has no fault and every condition's length (fault_effect
        subtracts its reward from theirs, step by step)."""
        if self.control is None:
            return
        info = {c.name: c for c in self.conditions_info(scale)}
        control = info[self.control]
        if control.fault_step is not None:
            raise ExperimentError(
                f"experiment {self.name!r}: control condition {self.control!r} has a fault"
            )
        for comparison in self.comparisons:
            for metric, name in (
                (comparison.metric, comparison.condition),
                (
                    comparison.metric_b or comparison.metric,
                    comparison.condition_b or comparison.condition,
                ),
            ):
                if metric == "fault_effect" and name is not None and info[name].fault_step is None:
                    raise ExperimentError(
                        f"experiment {self.name!r}, comparison {comparison.name!r}: fault_effect "
                        f"of condition {name!r}, which has no fault"
                    )
        for c in info.values():
            if c.steps != control.steps:
                raise ExperimentError(
                    f"experiment {self.name!r}: condition {c.name!r} lasts {c.steps} steps, "
                    f"the control {control.steps}"
                )

    def thesis_info(self) -> tuple[ThesisValue, ...]:
        """The thesis's numbers, to sit beside ours."""
        return tuple(ThesisValue(**v.model_dump()) for v in self.thesis)


def _one_line(error: ValidationError, source: str) -> str:
    return f"invalid experiment {source}: {describe_problems(error, limit=1)}"


def parse(data: Mapping[str, Any], source: str) -> ExperimentSpec:
    """Validate an experiment's dict, including every arm × condition × scale config.

    Raises:
        ExperimentError: one line naming the problem.
    """
    try:
        spec = ExperimentSpec.model_validate(data)
    except ValidationError as error:
        raise ExperimentError(_one_line(error, source)) from None
    for arm in spec.arms:  # each overlay as written, before a scale can mask a bad value
        try:
            build_config(preset_layer(spec.preset), spec.config, arm.config)
        except ConfigError as error:
            message = f"invalid experiment {source}: arm {arm.name!r}: {error}"
            raise ExperimentError(message.replace("\n", " ")) from None
    for scale in spec.scales:
        shapes: dict[str, tuple[int, int]] = {}
        for arm in spec.arms:
            where = f"invalid experiment {source}: arm {arm.name!r} at scale {scale!r}"
            try:
                run = spec.run_config(arm.name, scale, 0)
            except ConfigError as error:
                raise ExperimentError(f"{where}: {error}".replace("\n", " ")) from None
            for condition in spec.conditions:
                try:
                    settings = spec.condition_settings(condition, run, scale)
                except ConfigError as error:
                    message = f"{where}, condition {condition.name!r}: {error}"
                    raise ExperimentError(message.replace("\n", " ")) from None
                shape = shapes.setdefault(condition.name, (settings.steps, settings.fault_step))
                if shape != (settings.steps, settings.fault_step):
                    raise ExperimentError(
                        f"{where}, condition {condition.name!r}: steps and fault_step must be "
                        f"the same for every arm (the first arm's are {shape})"
                    )
        spec.check_control(scale)
        _check_fracnetics(spec, scale, source)
    return spec


def _check_fracnetics(spec: ExperimentSpec, scale: str, source: str) -> None:
    """A fracnetics arm's population holds its tournament (else fracnetics never returns)."""
    if spec.task is None:
        return
    from app.tasks.common import TaskError
    from app.tasks.fracnetics_arm import check_population, documented

    for arm in spec.arms:
        if arm.brain == "fracnetics":
            population = spec.run_config(arm.name, scale, 0).training.population
            try:
                check_population(documented(spec.task.id), population)
            except TaskError as error:
                where = f"invalid experiment {source}: arm {arm.name!r} at scale {scale!r}"
                raise ExperimentError(f"{where}: {error}") from None


def load_file(path: str | Path) -> ExperimentSpec:
    """An experiment TOML file."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ExperimentError(f"experiment file not found: {path}") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as error:
        raise ExperimentError(f"cannot read experiment file {path}: {error}") from None
    except tomllib.TOMLDecodeError as error:
        message = f"experiment file {path} is not valid TOML: {error}"
        raise ExperimentError(message.replace("\n", " ")) from None
    return parse(data, str(path))


def shipped_names() -> tuple[str, ...]:
    """Names of the experiments shipped in the package."""
    files = resources.files(SHIPPED_PACKAGE).iterdir()
    return tuple(sorted(f.name.removesuffix(".toml") for f in files if f.name.endswith(".toml")))


def load_shipped(name: str) -> ExperimentSpec:
    """A shipped experiment by name."""
    if name not in shipped_names():
        raise ExperimentError(
            f"no shipped experiment named {name!r}; choose one of {', '.join(shipped_names())} "
            "or give --file"
        )
    text = resources.files(SHIPPED_PACKAGE).joinpath(f"{name}.toml").read_text(encoding="utf-8")
    return parse(tomllib.loads(text), f"{name!r}")
