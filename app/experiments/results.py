"""What an experiment measured, as plain arrays: the contract between the runner and the report.

The runner (`app.experiments.runner`) fills an `ExperimentResults` from the run files of an
experiment's folder (and writes it to the summary file); statistics (`app.experiments.stats`)
and the report (`app.experiments.report`) read only this. Nothing here knows about Dask or HDF5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np

MetricKind = Literal["scalar", "curve"]
MetricScope = Literal["training", "condition"]
#: The metrics of a task experiment (a Gymnasium task instead of the robot; app.tasks.peer).
TASK_METRICS = (
    "final_best_return",
    "test_return",
    "test_return_as_trained",
    "test_return_greedy",
    "training_env_steps",
)
#: A task run's env-steps in training (DESIGN §4: env-steps reported per arm), harvested only
#: where a run file holds them or a claim names it (files before #45 hold none).
ENV_STEPS_METRIC = "training_env_steps"
#: Each test protocol's metric (app.tasks.config.TEST_PROTOCOLS), as a task run file names it.
PROTOCOL_METRICS = {"as-trained": "test_return_as_trained", "greedy": "test_return_greedy"}
Direction = Literal["greater", "less", "equivalent"]
# `exploratory` is not a verdict: what an exploratory claim shows in a verdict's place.
Verdict = Literal["held", "reversed", "ruled out", "undecided", "exploratory"]
VERDICTS: tuple[Verdict, ...] = ("held", "reversed", "ruled out", "undecided")
# How a verdict is marked, as (background, text) colours: on the report's page and the dashboard.
VERDICT_COLOURS: dict[Verdict, tuple[str, str]] = {
    "held": ("#d8f3dc", "#1b5e20"),
    "reversed": ("#fde2e1", "#9b1c1c"),
    "ruled out": ("#fff1c2", "#7a4b00"),
    "undecided": ("#eee", "#555"),
    "exploratory": ("#e8eefc", "#2b4a8b"),
}
MarginForm = Literal["absolute", "relative"]
ClaimKind = Literal["question", "sanity"]
# Which error family a claim belongs to: `primary` claims share the family-wise error control
# (Holm over the looks); `exploratory` ones are reported with their unadjusted interval only
# and never counted among the verdicts. Specs that say nothing put every claim in the family.
Family = Literal["primary", "exploratory"]
FAMILIES: tuple[Family, ...] = get_args(Family)
# The metrics measured against the experiment's no-fault control: absolute and relative (#44).
FAULT_EFFECTS = ("fault_effect", "relative_fault_effect")
# Simulated steps per CPU second of this machine, measured after the compiled loop (#31):
# ch3-bs-rl-decisive at thesis scale, analytic physics, 7.8 G steps in 3,838 CPU s of every
# process of the run (workers, scheduler, writes; 2.04 M/s). Prices the seeds an undecided
# claim needs, and `experiment list`'s core time: future runs take the analytic physics (the
# same bits as pymunk, physics-equivalence); pymunk runs cost about 4.4x more (0.46 M/s,
# ch3-bs-rl at thesis, before #31).
CORE_STEPS_PER_SECOND = 2.0e6
PYMUNK_CORE_STEPS_PER_SECOND = 0.46e6
"""`CORE_STEPS_PER_SECOND` of a run on pymunk's physics (the measure above)."""


def core_steps_per_second(physics: str) -> float:
    """The lab's measured simulated steps per CPU second of a run on `physics`
    (`training.physics`)."""
    return CORE_STEPS_PER_SECOND if physics == "analytic" else PYMUNK_CORE_STEPS_PER_SECOND


CONVERGENCE_SHARE = 0.9  # convergence: the first generation at 90% of the run's final fitness


@dataclass(frozen=True)
class Metric:
    """A named measurement of one run: defined once here, used by the runner and the report."""

    name: str
    label: str  # for axes and tables
    kind: MetricKind  # one number per run, or one curve per run
    scope: MetricScope  # of the training phase, or of one implementation condition
    description: str
    # The values a run can take: a reward per step is C × terms in 0..1 (Eq. 2.7), a fitness
    # its mean (Eq. 2.8), a fault effect the difference of two of them.
    bounds: tuple[float, float] = (0.0, 1.0)

    @property
    def span(self) -> float:
        return self.bounds[1] - self.bounds[0]


METRICS: dict[str, Metric] = {
    m.name: m
    for m in (
        Metric(
            "final_best_fitness",
            "final best fitness",
            "scalar",
            "training",
            "best fitness (Eq. 2.8) of the last generation",
        ),
        Metric(
            "best_fitness_curve",
            "best fitness",
            "curve",
            "training",
            "best fitness of each generation",
        ),
        Metric(
            "mean_reward",
            "mean reward per step",
            "scalar",
            "condition",
            "reward per step averaged over a condition's trials and steps",
        ),
        Metric(
            "mean_reward_after_fault",
            "mean reward per step after the fault",
            "scalar",
            "condition",
            "reward per step averaged over a condition's trials, from the fault step on",
        ),
        Metric(
            "mean_reward_before_fault",
            "mean reward per step before the fault",
            "scalar",
            "condition",
            "reward per step averaged over a condition's trials, before the fault step (the "
            "whole trial when no sensor breaks)",
        ),
        Metric(
            "fault_effect",
            "fault effect on reward (fault − no-fault control)",
            "scalar",
            "condition",
            "reward per step from the fault step on, minus the same steps of the no-fault "
            "control condition with the same trial seeds (negative: the fault costs reward)",
            bounds=(-1.0, 1.0),
        ),
        Metric(
            "relative_fault_effect",
            "relative fault effect (fault_effect / the control's reward)",
            "scalar",
            "condition",
            "fault_effect divided by the no-fault control's reward per step over the same steps: "
            "the share of the arm's own no-fault level the fault costs (−0.1: a tenth lost; NaN "
            "where the control earned nothing)",
            bounds=(-1.0, math.inf),
        ),
        Metric(
            "convergence_generation",
            "convergence generation",
            "scalar",
            "training",
            f"first generation whose best fitness reaches {CONVERGENCE_SHARE:.0%} of the "
            "run's final best fitness (counted from 1)",
            bounds=(1.0, math.inf),
        ),
        Metric(
            "final_best_return",
            "final best return",
            "scalar",
            "training",
            "best episode return of the last generation (a task experiment)",
            bounds=(-math.inf, math.inf),
        ),
        Metric(
            "test_return",
            "test return of the final elite",
            "scalar",
            "training",
            "mean return of the last generation's best over the experiment's K test episodes, "
            "the same episode seeds for every arm (a task experiment)",
            bounds=(-math.inf, math.inf),
        ),
        Metric(
            "test_return_as_trained",
            "test return, as trained",
            "scalar",
            "training",
            "test_return with the final elite living its test episodes as it was trained (its "
            "generation's ε and α, Sarsa on; fracnetics: its fixed policy)",
            bounds=(-math.inf, math.inf),
        ),
        Metric(
            "test_return_greedy",
            "test return, greedy",
            "scalar",
            "training",
            "test_return with the final elite living its test episodes greedily (ε = α = 0, "
            "Sarsa frozen; fracnetics: its fixed policy)",
            bounds=(-math.inf, math.inf),
        ),
        Metric(
            ENV_STEPS_METRIC,
            "env-steps in training",
            "scalar",
            "training",
            "env-steps the run's training spent: the lengths of every episode of every "
            "generation, summed (one episode per individual per generation; a task experiment, "
            "either brain; not the validation or test episodes)",
            bounds=(0.0, math.inf),
        ),
        Metric(
            "reward_per_step",
            "reward per step",
            "curve",
            "condition",
            "reward of each step, averaged over a condition's trials",
        ),
    )
}


@dataclass(frozen=True)
class Arm:
    name: str  # short, used in comparisons ("BS")
    label: str  # as the thesis names it ("Fuzzy GNP-TSRL (BS) 2SS&2BS")


@dataclass(frozen=True)
class Condition:
    """One implementation condition of every run of the experiment."""

    name: str
    label: str
    steps: int  # implementation length T
    fault_step: int | None  # t', None when no sensor breaks
    broken_count: int  # how many sensors break (0 = none)
    noise_sigma: float


@dataclass(frozen=True)
class Comparison:
    """A claim: arm `a` is `direction` than arm `b` on `metric` (in `condition`, if any);
    or, paired, one arm (a = b) against itself in `condition_b` and/or on `metric_b`."""

    name: str
    a: str
    b: str
    metric: str  # a scalar metric of METRICS
    condition: str | None  # required for condition metrics, None for training metrics
    direction: Direction
    source: str  # where the thesis claims it ("Fig. 3.9")
    condition_b: str | None = None  # b's condition, when it is not a's (then b is a)
    metric_b: str | None = None  # b's metric, when it is not a's (then b is a)
    # The thesis's effect, to rule out (or the equivalence margin): in the metric's units
    # ("absolute") or as a share of b's mean ("relative"); None: no effect to rule out.
    margin: float | None = None
    margin_form: MarginForm = "absolute"
    margin_source: str = ""  # where the margin comes from, and why
    role: ClaimKind | None = None  # None: "sanity" for one arm against itself, else "question"
    family: Family = "primary"
    # Tested paired by seed (the arms' common random numbers) or not, as declared before the
    # runs; None: paired exactly when one arm is compared with itself (the same runs).
    pairing: bool | None = None

    @property
    def kind(self) -> ClaimKind:
        """A thesis question (method against baseline) or a sanity claim (within one arm)."""
        return self.role or ("sanity" if self.within_arm else "question")

    def margin_for(self, mean_b: float) -> float | None:
        """The margin in the metric's units, given our mean of side b."""
        if self.margin is None:
            return None
        if self.margin_form == "relative":
            return abs(self.margin * mean_b) if np.isfinite(mean_b) else None
        return self.margin

    @property
    def within_arm(self) -> bool:
        """The same runs on both sides: one arm in two conditions or on two metrics."""
        return self.condition_b is not None or self.metric_b is not None

    @property
    def paired(self) -> bool:
        """Tested paired by seed: as declared, else exactly when the runs are the same."""
        return self.within_arm if self.pairing is None else self.pairing

    def keys(self) -> tuple[tuple[str, str, str], tuple[str, str, str]]:
        """The (metric, arm, condition) of a's values and of b's in `ExperimentResults.scalars`."""
        condition = self.condition or ""
        return (self.metric, self.a, condition), (
            self.metric_b or self.metric,
            self.b,
            self.condition_b or condition,
        )

    def side_names(self) -> tuple[str, str]:
        """What tells the two sides apart: the arms, or (paired) b's metric and condition."""
        if not self.within_arm:
            return self.a, self.b
        a, b = self.keys()
        differ = [i for i in (0, 2) if a[i] != b[i]] or [1]
        return ", ".join(a[i] for i in differ), ", ".join(b[i] for i in differ)


@dataclass(frozen=True)
class ThesisValue:
    """A number the thesis reports, to sit beside ours."""

    arm: str
    metric: str
    condition: str | None
    value: float
    source: str  # "Table 2.5"


@dataclass(frozen=True)
class ExperimentResults:
    """Per-run values of one experiment at one scale.

    `scalars[(metric, arm, condition)]` is an (n_seeds,) float array aligned with `seeds`
    (NaN for a run or condition not finished); `curves[(metric, arm, condition)]` is
    (n_seeds, L). `condition` is "" for training metrics.
    """

    name: str
    description: str
    source: str
    scale: str
    arms: tuple[Arm, ...]
    seeds: tuple[int, ...]
    conditions: tuple[Condition, ...]
    comparisons: tuple[Comparison, ...]
    thesis: tuple[ThesisValue, ...] = ()
    control: str | None = None  # the no-fault condition that `fault_effect` is measured against
    looks: tuple[int, ...] = ()  # seeds per arm at each look of an adaptive run; () = one look
    steps_per_run: float = 0.0  # simulated steps of one run (training + conditions), for costs
    scalars: dict[tuple[str, str, str], np.ndarray] = field(default_factory=dict)
    curves: dict[tuple[str, str, str], np.ndarray] = field(default_factory=dict)

    def scalar(self, metric: str, arm: str, condition: str | None = None) -> np.ndarray:
        return self.scalars[(metric, arm, condition or "")]

    def curve(self, metric: str, arm: str, condition: str | None = None) -> np.ndarray:
        return self.curves[(metric, arm, condition or "")]

    def finished(self, arm: str) -> np.ndarray:
        """Per seed, whether `arm`'s run finished: trained (a task run: tested) and every
        condition implemented. A value these results lack counts as unfinished."""
        tested = ("test_return", arm, "") in self.scalars
        keys = [("test_return" if tested else "final_best_fitness", arm, "")]
        keys += [("mean_reward", arm, c.name) for c in self.conditions]
        missing = np.full(len(self.seeds), np.nan)
        return np.logical_and.reduce([np.isfinite(self.scalars.get(k, missing)) for k in keys])
