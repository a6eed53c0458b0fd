"""Experiments as data: a validated TOML file of arms × seeds × implementation conditions.

An experiment names a base preset and overlay, arms (config overlays), implementation
conditions (ImplementationSettings overlays), the comparisons it makes (claims of the thesis),
the thesis's own numbers, and scales (`smoke`, `small`, `thesis`: overlays applied last, with a
seed count). The config of arm A, seed i, at scale S is

    thesis defaults ← preset ← base overlay ← arm A ← scale S ← {seed = i}

and condition C implements it with `[implementation]` ← condition C ← scale S's
`[implementation]`, so a scale sizes every condition. Every arm × condition × scale config is
validated when the file loads (`app.experiments.spec_loading`); a bad file raises
`ExperimentError` with one line naming the problem. Each of the file's tables is validated alone
in `app.experiments.spec_tables`.
"""

from __future__ import annotations

from typing import Any, Literal, get_args

from pydantic import Field, model_validator

from app.experiments.results import (
    FAULT_EFFECTS,
    METRICS,
    TASK_METRICS,
    Arm,
    Comparison,
    Condition,
    ThesisValue,
)
from app.experiments.spec_tables import (
    ArmSpec,
    ComparisonSpec,
    ConditionSpec,
    DesignSpec,
    ScaleSpec,
    SpecModel,
    TaskSpec,
    ThesisValueSpec,
    check_name,
)
from app.settings.config import (
    PRESET_NAMES,
    ImplementationSettings,
    RunConfig,
    preset_layer,
)
from app.settings.loading import build_config

Scale = Literal["smoke", "small", "thesis"]
SCALES: tuple[Scale, ...] = get_args(Scale)


class ExperimentError(ValueError):
    """An experiment file, name or folder cannot be used as asked; the message is one line."""


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


class ExperimentSpec(SpecModel):
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
                if metric in FAULT_EFFECTS and self.control is None:
                    raise ValueError(f"{where}: {metric} needs the experiment's control")
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
                if metric in FAULT_EFFECTS and name is not None and info[name].fault_step is None:
                    raise ExperimentError(
                        f"experiment {self.name!r}, comparison {comparison.name!r}: {metric} "
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
