"""What `gnp-lab tune` searches and on which seeds: the search space of each brain, declared as
data (one table per brain), and the tuning seeds, a range no test or experiment seed is in.

Nothing here imports Optuna, Gymnasium or the simulator: the tables are read by the tuner
(`app.tune.study`), the docs and the tests.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Any, Literal, get_args

Brain = Literal["gnp", "fracnetics"]
BRAINS: tuple[Brain, ...] = get_args(Brain)


class TuneError(ValueError):
    """A tuning request that cannot be run (bad budget, bad storage, bad preset): one line."""


# --- seeds ------------------------------------------------------------------------------------

TUNING_SEEDS = range(700_000_000, 720_000_000)
"""Every seed tuning uses, run seeds and episode seeds alike. Experiments' run seeds are small
(0..~10,000, and fracnetics' episode seeds run seed + g above them) and their test episodes
start at 1,000,000 (`[task] first_test_seed`); tests/app/tune/test_tune_seeds.py checks every
shipped spec against this range."""

FIRST_RUN_SEED = TUNING_SEEDS.start
"""A trial's r-th run (of `--seeds R`) has run seed FIRST_RUN_SEED + r, the same in every trial
(common random numbers: trials differ in their settings only). fracnetics' episode seeds are
run seed + g (g < 1,000,000 generations), inside the range too."""

FIRST_VALIDATION_SEED = TUNING_SEEDS.start + 10_000_000
"""The K validation episodes that score a trial's elite: seeds FIRST_VALIDATION_SEED..+K-1."""

MAX_RUN_SEEDS = 1000
MAX_VALIDATION_EPISODES = 10_000


def run_seeds(count: int) -> tuple[int, ...]:
    """The run seeds of each trial (`--seeds`)."""
    return tuple(range(FIRST_RUN_SEED, FIRST_RUN_SEED + count))


def validation_seeds(count: int) -> tuple[int, ...]:
    """The validation episode seeds of each trial (`--validation`)."""
    return tuple(range(FIRST_VALIDATION_SEED, FIRST_VALIDATION_SEED + count))


# --- the search space -------------------------------------------------------------------------

Kind = Literal["float", "int", "categorical", "share"]


@dataclass(frozen=True)
class Param:
    """One searched setting.

    `path` is where the value goes: a `RunConfig` key (`section.key`) for GNP, a
    `FracneticsSettings` field (`fracnetics.key`) for fracnetics. A `share` is drawn in 0..1 and
    stored as that share of the setting `of` (e.g. ε_min = share × ε_max, so min ≤ max always).
    `fixed` are settings that come with it (e.g. the schedule "changing" its ε needs);
    `excludes` the settings which, fixed by the study, leave it out of the space; `methods`
    the GNP methods it acts in (all when empty); `discrete_only` for tasks whose action is
    Discrete; `crisp_only` for studies whose judgment is crisp."""

    path: str
    kind: Kind
    low: float = 0.0
    high: float = 1.0
    log: bool = False
    choices: tuple[Any, ...] = ()
    of: str = ""
    fixed: tuple[tuple[str, Any], ...] = ()
    excludes: tuple[str, ...] = ()
    methods: tuple[str, ...] = ()
    discrete_only: bool = False
    crisp_only: bool = False
    why: str = ""

    @property
    def name(self) -> str:
        """Optuna's name of the parameter (its path; a share's is path + "_share")."""
        return f"{self.path}_share" if self.kind == "share" else self.path


_CHANGING = (("training.schedule", "changing"),)
_RATES = (
    "training.schedule",
    "training.epsilon",
    "training.alpha",
    "training.epsilon_max",
    "training.epsilon_min",
    "training.alpha_max",
    "training.alpha_min",
    "training.schedule_n",
)
"""A study that fixes any ε/α setting (`--set training.epsilon=0.01`) searches none of them."""
_TOURNAMENTS = ("evolution.tournament_size", "fracnetics.tournament")

GNP_SPACE: tuple[Param, ...] = (
    Param("evolution.p_mutation", "float", 0.002, 0.2, log=True,
          why="P_m: 0.01 is the robot's for 1000 generations; tasks ran 30 (#45: 0.05-0.10 won)"),
    Param("evolution.p_crossover", "float", 0.0, 0.5, why="P_c, per node gene swap"),
    Param("evolution.tournament_size", "int", 2, 10, why="selection pressure"),
    Param("evolution.p_add_delete", "float", 0.0, 0.5,
          why="add/delete-node mutation per mutant: fracnetics' growing graphs (#45 item 2)"),
    Param("controller.n_judgment", "int", 8, 80, log=True, why="judgment nodes"),
    Param("controller.n_processing", "int", 2, 40, log=True, why="processing nodes"),
    Param("controller.n_sub", "int", 1, 4, why="sub nodes: 1 is a plain GNP (no choice to learn)"),
    Param("controller.q0", "float", -10.0, 10.0,
          why="initial Q: ±1/(1−γ) at γ = 0.9 spans tasks paying ±1 a step (#45: 0 is "
          "optimistic where steps pay −1)"),
    Param("controller.tie_break", "categorical", choices=("random", "first"),
          why="ε-greedy among equal maxima (first: learning off is deterministic)"),
    Param("controller.threshold_init", "categorical", choices=("uniform", "midpoint"),
          why="generation 0's judgments drawn, or each at its feature's midpoint (#45 item 2)"),
    Param("controller.skip_reward", "categorical", choices=("zero", "step"), methods=("CS",),
          why="what a credit skip ending a step earns (CS): Eq. 5.3's zero, or the step's"),
    Param("controller.processing_output", "categorical", choices=("parameter", "function"),
          discrete_only=True,
          why="a processing node's parameter read in action bins, or its function the action"),
    Param("controller.judgment_branches", "int", 2, 4, crisp_only=True,
          why="branches of a judgment node: k equal bins of β..α (fracnetics' k-way judgment)"),
    Param("training.epsilon_max", "float", 0.0, 0.3, fixed=_CHANGING, excludes=_RATES,
          why="ε at generation 0 (Eq. 4.1)"),
    Param("training.epsilon_min", "share", of="training.epsilon_max", excludes=_RATES,
          why="ε at the last generation, as a share of ε at generation 0"),
    Param("training.alpha_max", "float", 0.0, 1.0, fixed=_CHANGING, excludes=_RATES,
          why="α at generation 0"),
    Param("training.alpha_min", "share", of="training.alpha_max", excludes=_RATES,
          why="α at the last generation, as a share of α at generation 0"),
    Param("training.schedule_n", "float", 0.5, 4.0, log=True, excludes=_RATES,
          why="exponent n of Eq. 4.1-4.2"),
)  # fmt: skip
"""GNP's search space (RL/BS/CS alike; the method, judgment and population are the study's)."""

FRACNETICS_SPACE: tuple[Param, ...] = (
    Param("fracnetics.jn", "int", 1, 4, why="judgment nodes per feature"),
    Param("fracnetics.pn", "int", 1, 4, why="processing nodes per action"),
    Param("fracnetics.d_max", "int", 5, 30, why="most judgments per decision"),
    Param("fracnetics.max_consecutive_p", "int", 1, 20, why="maxConsecutiveP"),
    Param("fracnetics.tournament", "int", 2, 10, why="tournament size N"),
    Param("fracnetics.add_del", "float", 0.0, 1.0, why="callAddDelNodes' share"),
    Param("fracnetics.crossover", "float", 0.0, 0.5, why="uniform crossover probability"),
    Param("fracnetics.edge_inner", "float", 0.005, 0.3, log=True, why="edge mutation, inner"),
    Param("fracnetics.edge_start", "float", 0.0, 0.2, why="edge mutation, start node"),
    Param("fracnetics.boundary_uniform", "float", 0.0, 0.2,
          why="callBoundaryMutationUniform's probability (0: as if not called)"),
)  # fmt: skip
"""fracnetics' search space: the settings its notebooks tune per task (app.tasks.fracnetics_arm)
; its observation bounds stay its documented ones."""

SPACES: dict[Brain, tuple[Param, ...]] = {"gnp": GNP_SPACE, "fracnetics": FRACNETICS_SPACE}


def space(
    brain: Brain,
    fixed: Mapping[str, Any] = MappingProxyType({}),
    population: int | None = None,
    method: str | None = None,
    discrete: bool = True,
    fuzzy: bool = False,
) -> list[Param]:
    """The parameters searched for `brain`: its table less the settings the study fixes
    (`--set`: a fixed setting leaves the space, and so do the parameters it `excludes`) and
    those of other methods than the study's (`methods`), for Discrete actions only on
    another task, or for crisp judgment only in a `fuzzy` study; a tournament no larger than
    the population."""
    params = []
    for p in SPACES[brain]:
        if p.path in fixed or set(fixed) & set(p.excludes):
            continue
        if p.methods and method is not None and method not in p.methods:
            continue
        if p.discrete_only and not discrete:
            continue
        if p.crisp_only and fuzzy:
            continue
        if population is not None and p.path in _TOURNAMENTS:
            p = replace(p, high=min(p.high, population))
        params.append(p)
    return params


def nested(values: dict[str, Any]) -> dict[str, Any]:
    """{"a.b": 1} as {"a": {"b": 1}}."""
    out: dict[str, Any] = {}
    for path, value in values.items():
        *sections, key = path.split(".")
        target = out
        for section in sections:
            target = target.setdefault(section, {})
        target[key] = value
    return out


def settings_of(params: list[Param], drawn: dict[str, Any]) -> dict[str, Any]:
    """The flat settings (`path`: value) of one trial's drawn values (Optuna's names), shares
    resolved and fixed companions added."""
    values: dict[str, Any] = {}
    for p in params:
        if p.name not in drawn:
            continue
        values.update(p.fixed)
        if p.kind != "share":
            values[p.path] = drawn[p.name]
    for p in params:
        if p.kind == "share" and p.name in drawn and p.of in values:
            values[p.path] = float(drawn[p.name]) * float(values[p.of])
    return values
