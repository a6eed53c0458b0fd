"""Frozen configuration of the brain: graph shape, learning method, evolution, schedules."""

from __future__ import annotations

from functools import cached_property
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from gnp.methods import TRAITS, Method, MethodTraits

#: Node types (Table 2.1 of the thesis): NT_i.
START, JUDGMENT, PROCESSING = 0, 1, 2
#: Time units d_i charged per node type (Table 2.1); a credit skip costs 1 (docs/decisions.md,
#: "A credit skip costs one time unit").
NODE_COST = {START: 0, JUDGMENT: 1, PROCESSING: 5}
SKIP_COST = 1
#: Time units a controller may spend per world step.
STEP_BUDGET = 5
#: Sensors judged by judgment nodes (J0..J7) and wheels set by processing nodes (P0, P1): the
#: robot's (`sim.N_SENSORS`), the defaults of `n_inputs` and `n_outputs`. gnp does not import
#: sim, so it keeps its own copy; tests/app/design/test_sim_gnp_boundary.py ties the two.
N_SENSORS = 8
N_WHEELS = 2
RIGHT_WHEEL, LEFT_WHEEL = 0, 1
WHEEL_NAMES = ("P0 right", "P1 left")
"""A processing node's wheel, named by its function (0 = RIGHT_WHEEL, 1 = LEFT_WHEEL)."""
#: Parameter ranges: judgment β ≤ α in 0..1023, processing wheel speed in −10..10.
SENSOR_MAX = 1023
SPEED_MAX = 10
#: How a judgment sub node's {β, α} mutates (§2.3.3, Eq. 2.4): "joint" (one parameter: one P_m
#: draw, one ζ and one r for the pair) or "independent" (α and β each with their own P_m).
JudgmentPair = Literal["joint", "independent"]
#: Progress of Eq. 4.1–4.2 at generation g = 0..G−1: "last-generation-min" (g/(G−1), so the
#: first evaluated generation uses max and the last uses min) or "g-over-G" (g/G, as printed).
GenerationProgress = Literal["last-generation-min", "g-over-G"]
#: How ε-greedy breaks a tie among the maxima: "random" (uniformly, one more draw: the thesis's
#: reading, the robot's) or "first" (the lowest index, no draw: with ε = 0 a walk is then a
#: function of its inputs, so learning off (ε = α = 0) is a deterministic policy).
TieBreak = Literal["random", "first"]
#: What a credit skip (CS) that ends a world step earns: "zero" (Eq. 5.3 read literally: a skip
#: has no reward term; the robot's) or "step" (the step's reward, as any step's last visit).
SkipReward = Literal["zero", "step"]
#: How generation 0's judgment thresholds {β, α} are drawn: "uniform" (α in 1..1023, β in
#: 0..α−1: §2.3.3, the robot's) or "midpoint" (β = 511, α = 512: every judgment starts at its
#: feature's midpoint, the crisp threshold 511.5 halving the feature's range).
ThresholdInit = Literal["uniform", "midpoint"]
#: Generation 0's {β, α} under "midpoint": the crisp threshold (β + α)/2 = 511.5, the middle
#: of 0..1023, a fuzzy judgment's ramp one reading wide.
MIDPOINT_BETA, MIDPOINT_ALPHA = SENSOR_MAX // 2, SENSOR_MAX // 2 + 1
#: What a processing node sets: "parameter" (output f, its function, to its parameter in
#: −10..10: the robot's wheels) or "function" (output 0 to the centre of the f-th of
#: n_outputs equal bins of −10..10, its parameter unused: on a Discrete(n) task read in n bins,
#: with n_outputs = n, the node's function is the action).
ProcessingOutput = Literal["parameter", "function"]
#: Branches a judgment node may have (`GnpConfig.judgment_branches`): 2 is the thesis's.
MAX_JUDGMENT_BRANCHES = 8
BRANCH_NAMES = "ABCDEFGH"
"""Branch b's name (A = 0, the high side of a judgment), as files and pages write it."""
#: Bound on an initial Q value (Q tables are float32).
Q0_MAX = 1e6


class GnpError(ValueError):
    """Bad input to the gnp package (a genome, an array, an argument)."""


def judgment_name(fuzzy: bool) -> str:
    """How a controller judges, as runs, files and pages name it: "fuzzy" or "crisp"."""
    return "fuzzy" if fuzzy else "crisp"


def check_judgment_branches(fuzzy: bool, judgment_branches: int) -> None:
    """Raise ValueError for fuzzy judgment with more than 2 branches: the thesis's fuzzy
    judgment (Eq. 2.1–2.2) draws between two branches only."""
    if fuzzy and judgment_branches > 2:
        raise ValueError(
            f"judgment_branches = {judgment_branches} needs crisp judgment (fuzzy = false): "
            "fuzzy judgment has two branches"
        )


class GnpConfig(BaseModel):
    """Shape of every individual and the learning method (Tables 2.4, 3.1, 5.1).

    Node 0 is the start node, nodes 1..n_judgment are judgment nodes, the rest processing nodes.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    method: Method = Field(
        default="RL",
        description="RL: sub node selection only; BS: + branch connections; CS: + credit",
    )
    fuzzy: bool = Field(default=True, description="fuzzy (Eq. 2.1–2.2) or crisp judgment")
    n_judgment: int = Field(default=40, ge=1, le=16_000, description="judgment nodes")
    n_processing: int = Field(default=20, ge=1, le=16_000, description="processing nodes")
    n_sub: int = Field(default=2, ge=1, le=64, description="sub nodes m per node")
    n_branch: int = Field(
        default=2, ge=1, le=64, description="branch connections U per connection (BS)"
    )
    gamma: float = Field(default=0.9, ge=0.0, le=1.0, description="Sarsa discount rate γ")
    n_inputs: int = Field(
        default=N_SENSORS,
        ge=1,
        le=127,
        description="inputs judgment nodes judge (the robot's 8 sensors), each read in 0..1023",
    )
    n_outputs: int = Field(
        default=N_WHEELS,
        ge=1,
        le=127,
        description="outputs processing nodes set (the robot's 2 wheels), each in −10..10",
    )
    q0: float = Field(
        default=0.0,
        ge=-Q0_MAX,
        le=Q0_MAX,
        description="initial value of every Q table entry (Q_SS, Q_BS, Q_CS) of generation 0; "
        "below the returns a task pays (e.g. −1/(1−γ) where every step pays −1) an untried "
        "sub node is not preferred to a tried one",
    )
    tie_break: TieBreak = Field(
        default="random",
        description="ε-greedy among equal maxima: random (a draw) or first (the lowest index; "
        "learning off, ε = α = 0, is then deterministic)",
    )
    skip_reward: SkipReward = Field(
        default="zero",
        description="what a credit skip (CS) that ends a world step earns: zero (Eq. 5.3) or "
        "the step's reward (step); with zero, where steps pay less than 0 a controller that "
        "skips every node hides every reward and stops acting",
    )
    threshold_init: ThresholdInit = Field(
        default="uniform",
        description="generation 0's judgment thresholds: uniform (α in 1..1023, β below it) "
        "or midpoint (β = 511, α = 512: each judgment halves its feature's range)",
    )
    processing_output: ProcessingOutput = Field(
        default="parameter",
        description="what a processing node sets: output f (its function) to its parameter "
        "(parameter), or output 0 to the centre of the f-th of n_outputs equal bins of "
        "−10..10 (function: on a Discrete(n) task the function is the action)",
    )

    judgment_branches: int = Field(
        default=2,
        ge=2,
        le=MAX_JUDGMENT_BRANCHES,
        description="branches k of a judgment node: 2 (the thesis's A/B), or k > 2 (crisp only: "
        "k equal bins of β..α, fracnetics' k-way judgment; the highest bin takes branch A)",
    )

    @model_validator(mode="after")
    def _branches_judged(self) -> GnpConfig:
        check_judgment_branches(self.fuzzy, self.judgment_branches)
        return self

    @cached_property
    def n_nodes(self) -> int:
        """All nodes, the start node included."""
        return 1 + self.n_judgment + self.n_processing

    @property
    def judgment(self) -> str:
        """ "fuzzy" or "crisp" (`judgment_name`)."""
        return judgment_name(self.fuzzy)

    @property
    def traits(self) -> MethodTraits:
        """What the method does (`gnp.methods.TRAITS`)."""
        return TRAITS[self.method]

    @cached_property
    def n_conn_branches(self) -> int:
        """Size of the branch-connection axis of `conn` and `q_bs`: U for BS, else 1."""
        return self.traits.n_conn_branches(self.n_branch)

    @cached_property
    def node_type(self) -> np.ndarray:
        """(n_nodes,) int8: START, JUDGMENT or PROCESSING per node."""
        types = np.full(self.n_nodes, PROCESSING, dtype=np.int8)
        types[0] = START
        types[1 : 1 + self.n_judgment] = JUDGMENT
        types.setflags(write=False)
        return types

    def __eq__(self, other: object) -> bool:
        # By settings: pydantic's default compares __dict__, which also holds the cached
        # array above and cannot be compared with ==.
        return isinstance(other, GnpConfig) and self.model_dump() == other.model_dump()

    def __hash__(self) -> int:
        return hash(tuple(self.model_dump().items()))

    @property
    def io_defaults(self) -> bool:
        """Inputs and outputs are the robot's (8 sensors, 2 wheels)."""
        return self.n_inputs == N_SENSORS and self.n_outputs == N_WHEELS

    def task_settings(self) -> dict[str, object]:
        """The settings made for tasks (`TASK_SETTINGS`) that differ from their defaults: a
        controller document names only these, so the robot's documents read as before."""
        dump = self.model_dump()
        return {
            name: dump[name]
            for name in TASK_SETTINGS
            if dump[name] != type(self).model_fields[name].default
        }

    @property
    def max_visits_per_step(self) -> int:
        """Longest possible node sequence in one world step: the start node + 5 unit nodes."""
        return 1 + STEP_BUDGET // min(NODE_COST[JUDGMENT], SKIP_COST)


TASK_SETTINGS = (
    "q0",
    "tie_break",
    "skip_reward",
    "threshold_init",
    "processing_output",
    "judgment_branches",
)
"""`GnpConfig` settings added for Gymnasium tasks (issue #45), each off by default (the robot's
runs, documents and bits as before)."""
EVOLUTION_TASK_SETTINGS = ("p_add_delete",)
"""`EvolutionConfig` settings added for Gymnasium tasks (issue #45), off by default likewise."""


class EvolutionConfig(BaseModel):
    """Evolution settings (Table 2.4); the population split scales with the population size."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    tournament_size: int = Field(default=7, ge=1, description="individuals per tournament")
    p_crossover: float = Field(default=0.1, ge=0.0, le=1.0, description="P_c: per node gene swap")
    p_mutation: float = Field(
        default=0.01, ge=0.0, le=1.0, description="P_m: per connection/function/param"
    )
    elite_fraction: float = Field(
        default=1 / 300, ge=0.0, le=1.0, description="elite share (≥ 1 kept)"
    )
    crossover_fraction: float = Field(
        default=120 / 300, ge=0.0, le=1.0, description="offspring share"
    )
    nonuniform_b: float = Field(
        default=2.0, gt=0.0, description="b of non-uniform mutation (Eq. 2.5)"
    )
    judgment_pair: JudgmentPair = Field(
        default="joint",
        description="judgment {β, α} mutates as one parameter (joint: P_m per sub node, one ζ "
        "and r) or as two (independent: P_m each)",
    )
    p_add_delete: float = Field(
        default=0.0,
        ge=0.0,
        le=1.0,
        description="per mutant, the probability of adding or deleting a node (½ each, "
        "fracnetics' growing graphs): delete redirects every connection into a reachable "
        "node, add connects an unreachable one with fresh genes; 0: off (the robot's)",
    )

    @model_validator(mode="after")
    def _fractions_fit(self) -> EvolutionConfig:
        if self.elite_fraction + self.crossover_fraction > 1.0:
            raise ValueError("elite_fraction + crossover_fraction must not exceed 1")
        return self

    def split(self, n: int) -> tuple[int, int, int]:
        """(elite, crossover, mutation) counts for a population of n (1/120/179 at n = 300)."""
        if n < 1:
            raise GnpError(f"population size must be ≥ 1, got {n}")
        n_elite = min(n, max(1, round(n * self.elite_fraction)))
        n_cross = 2 * round(n * self.crossover_fraction / 2)
        n_cross = min(n_cross, (n - n_elite) // 2 * 2)
        return n_elite, n_cross, n - n_elite - n_cross


class Schedule(BaseModel):
    """A learning parameter (ε or α) that is fixed or decays from `max` to `min` (Eq. 4.1–4.4).

    value = (max − min)·(1 − progress)^n + min, progress in [0, 1]. A fixed value has max = min.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    max: float = Field(default=0.1, ge=0.0, le=1.0, description="value at progress 0")
    min: float = Field(default=0.1, ge=0.0, le=1.0, description="value at progress 1")
    n: float = Field(default=1.0, gt=0.0, description="exponent n of Eq. 4.1–4.4")

    @classmethod
    def fixed(cls, value: float) -> Schedule:
        """A schedule that always returns `value`."""
        return cls(max=value, min=value)

    @model_validator(mode="after")
    def _ordered(self) -> Schedule:
        if self.min > self.max:
            raise ValueError(f"min ({self.min}) must not exceed max ({self.max})")
        return self
