"""The tables of an experiment file, each validated alone: arms, conditions, comparisons (the
claims), the thesis's values, a sequential design, a task and scales; and what a name may be."""

from __future__ import annotations

import re
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.experiments.results import ClaimKind, Direction, Family, MarginForm
from app.tasks.common import EpisodeProtocol

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,63}$")
_NAME_RULE = "1-64 letters, digits, '_', '.' or '-', starting with a letter or digit"


def check_name(name: str, what: str = "experiment name") -> str:
    """A name that is safe as a file or folder name (no path, no hidden file)."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(f"{what} {name!r} must be {_NAME_RULE}")
    return name


class SpecModel(BaseModel):
    """A table of an experiment file: frozen, and no key it does not know."""

    model_config = ConfigDict(frozen=True, extra="forbid")


class ArmSpec(SpecModel):
    """One arm: a config overlay (e.g. the learning method)."""

    name: str = Field(description="short name used in comparisons and file names")
    label: str = Field(description="as the thesis names it")
    config: dict[str, Any] = Field(default_factory=dict, description="RunConfig overlay")
    brain: Literal["gnp", "fracnetics"] = Field(
        default="gnp",
        description="a task experiment's brain: ours (GNP, as the config says) or fracnetics "
        "with its documented settings (app.tasks.fracnetics_arm)",
    )
    fracnetics: dict[str, Any] = Field(
        default_factory=dict,
        description="a fracnetics arm's settings over its documented ones, e.g. the "
        "[fracnetics] table of a preset `gnp-lab tune --brain fracnetics` wrote",
    )

    @model_validator(mode="after")
    def _named(self) -> ArmSpec:
        check_name(self.name, "arm name")
        if self.fracnetics and self.brain != "fracnetics":
            raise ValueError(f"arm {self.name!r}: fracnetics settings need brain = 'fracnetics'")
        return self


class ConditionSpec(SpecModel):
    """One implementation condition: an ImplementationSettings overlay (faults, noise)."""

    name: str = Field(description="name of the implementation stored in every run file")
    label: str
    implementation: dict[str, Any] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _named(self) -> ConditionSpec:
        check_name(self.name, "condition name")
        return self


class ComparisonSpec(SpecModel):
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


class ThesisValueSpec(SpecModel):
    """A number the thesis reports, to sit beside ours."""

    arm: str
    metric: str
    condition: str | None = None
    value: float
    source: str


class DesignSpec(SpecModel):
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


class TaskSpec(SpecModel, EpisodeProtocol):
    """A task experiment: every run trains on a Gymnasium task instead of the robot, and its
    final elite is tested on the same K episode seeds for every arm (app.tasks.peer); how its
    episodes are seeded and its elite chosen and tested (`EpisodeProtocol`: test_protocol,
    validation_episodes, shared_episodes) as every run's `TaskTraining` says."""

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


class ScaleSpec(SpecModel):
    """A size: a config overlay applied after the arm's, and a seed count."""

    seeds: int | None = Field(default=None, ge=1, le=10_000, description="unset = the file's")
    config: dict[str, Any] = Field(default_factory=dict)
    measured: str = Field(default="", description="a measured wall time, shown by `list`")
