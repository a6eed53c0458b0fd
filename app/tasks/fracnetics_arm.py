"""fracnetics (GNP in C++, github.com/fracnetics, 4.0.0) as an arm of a task experiment, trained
through its own library with its documented settings.

Its documented settings are its example notebooks': CartPole-v1 (examples/cartPole.ipynb) and
MountainCar-v0 (examples/mountainCar.ipynb). It documents none for Acrobot-v1: there the
CartPole pattern is taken with Acrobot's observation bounds (the space's) and its three actions
(`DOCUMENTED`; docs/decisions.md, "GNP beside fracnetics"). Population and generations are the
experiment's, the same episode budget as every arm's: one episode per individual per generation
(fracnetics' `gymnasium(..., seeds=[seed + g])`: every individual of generation g starts from
episode seed `seed + g`, its examples' scheme). Its population lives in C++ and is not written
to the run file: a fracnetics run stores its results only and is not resumable (a cut run
starts again; runs are short). Its env-steps are counted where they are spent: its library steps
the env it is given, which is wrapped in `StepCounter` (one count per `step`, one episode per
`reset`), so a run reports the env-steps of each generation and of each test episode. On the
tasks the lab has a compiled twin of (CartPole, MountainCar, Acrobot) the env it is handed is
that twin (`app.tasks.twin_env`: Gymnasium's env bit for bit, a step 5-25x cheaper), so a run
gives the same numbers for a fraction of the core-hours.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from app.tasks.common import TaskError
from app.tasks.twin_env import TASKS as TWIN_TASKS
from app.tasks.twin_env import TwinEnv


class FracneticsSettings(BaseModel):
    """fracnetics' settings of one task (its notebooks' names in the descriptions)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    jn: int = Field(ge=1, description="judgment nodes per judgment function (jn)")
    jnf: int = Field(ge=1, description="judgment functions: observation features (jnf)")
    pn: int = Field(ge=1, description="processing nodes per processing function (pn)")
    pnf: int = Field(ge=1, description="processing functions: discrete actions (pnf)")
    d_max: int = Field(ge=1, description="most judgments per decision (dMax)")
    max_consecutive_p: int = Field(ge=1, description="maxConsecutiveP")
    tournament: int = Field(ge=2, description="tournament size N")
    elite: int = Field(ge=0, description="elite kept E")
    add_del: float = Field(
        ge=0,
        description="callAddDelNodes' junk: the share of a network's unused nodes kept from "
        "deletion (junk DNA; at least one), not a probability",
    )
    crossover: float = Field(ge=0, le=1, description="uniform crossover probability")
    edge_inner: float = Field(ge=0, le=1, description="callEdgeMutation probInnerNodes")
    edge_start: float = Field(ge=0, le=1, description="callEdgeMutation probStartNode")
    boundary_uniform: float | None = Field(
        None, description="callBoundaryMutationUniform's probability (None: not called)"
    )
    obs_low: tuple[float, ...] = Field(description="setAllNodeBoundaries' minFeatures")
    obs_high: tuple[float, ...] = Field(description="setAllNodeBoundaries' maxFeatures")


_CARTPOLE = FracneticsSettings(
    jn=1, jnf=4, pn=2, pnf=2, d_max=10, max_consecutive_p=10, tournament=5, elite=1,
    add_del=1.0, crossover=0.05, edge_inner=0.05, edge_start=0.05, boundary_uniform=None,
    obs_low=(-4.8, -5.0, -0.418, -10.0), obs_high=(4.8, 5.0, 0.418, 10.0),
)  # fmt: skip

_MOUNTAINCAR = FracneticsSettings(
    jn=2, jnf=2, pn=3, pnf=3, d_max=20, max_consecutive_p=10, tournament=4, elite=1,
    add_del=0.5, crossover=0.1, edge_inner=0.05, edge_start=0.01, boundary_uniform=0.05,
    obs_low=(-1.2, -0.07), obs_high=(0.6, 0.07),
)  # fmt: skip

#: Its documented settings per task (Acrobot: the CartPole pattern, see the module docstring).
DOCUMENTED: dict[str, FracneticsSettings] = {
    "CartPole-v1": _CARTPOLE,
    "MountainCar-v0": _MOUNTAINCAR,
    "Acrobot-v1": _CARTPOLE.model_copy(
        update={
            "jnf": 6,
            "pnf": 3,
            "obs_low": (-1.0, -1.0, -1.0, -1.0, -4 * np.pi, -9 * np.pi),
            "obs_high": (1.0, 1.0, 1.0, 1.0, 4 * np.pi, 9 * np.pi),
        }
    ),
}


def documented(task: str) -> FracneticsSettings:
    """fracnetics' settings for `task`.

    Raises:
        TaskError: a task it documents no settings for.
    """
    if task not in DOCUMENTED:
        raise TaskError(
            f"fracnetics arm: no documented settings for {task!r}; "
            f"choose one of {', '.join(DOCUMENTED)}"
        )
    return DOCUMENTED[task]


def arm_settings(task: str, overlay: dict[str, Any]) -> FracneticsSettings:
    """fracnetics' documented settings for `task` with `overlay`'s (e.g. a tuned preset's
    `[fracnetics]` table: `gnp-lab tune --brain fracnetics`).

    Raises:
        TaskError: a task it documents no settings for, or an overlay that is no settings of
            it (one line).
    """
    base = documented(task)
    if not overlay:
        return base
    unknown = sorted(set(overlay) - set(FracneticsSettings.model_fields))
    if unknown:
        raise TaskError(f"fracnetics settings: {', '.join(unknown)}: unknown setting")
    try:
        return FracneticsSettings.model_validate({**base.model_dump(), **overlay})
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise TaskError(f"fracnetics settings: {where}: {first['msg']}") from None


def check_population(settings: FracneticsSettings, population: int) -> None:
    """fracnetics' tournament draws N distinct individuals: with fewer it never returns.

    Raises:
        TaskError: a population smaller than the tournament.
    """
    if population < settings.tournament:
        raise TaskError(
            f"fracnetics arm: population {population} is smaller than its tournament "
            f"({settings.tournament}); give at least {settings.tournament} individuals"
        )


class StepCounter(gym.Wrapper):
    """The env as it is, counting its steps: `lengths` holds one entry per `reset` (an
    episode), the `step` calls made since it; `take()` hands them over and starts afresh."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.lengths: list[int] = []

    def reset(self, **kwargs: Any) -> Any:
        self.lengths.append(0)
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> Any:
        self.lengths[-1] += 1
        return self.env.step(action)

    def take(self) -> np.ndarray:
        """The episodes' lengths since the last `take` (int64)."""
        lengths, self.lengths = np.asarray(self.lengths, np.int64), []
        return lengths


@dataclass(frozen=True)
class FracneticsResult:
    """A fracnetics run: every individual's return per generation, the env-steps each
    generation spent, and the final elite's return and episode length on each test seed."""

    fitness: np.ndarray  # (G, N)
    test_returns: np.ndarray  # (K,)
    env_steps: np.ndarray  # (G,) int64: the steps of every episode of a generation
    test_lengths: np.ndarray  # (K,) int64


def train_fracnetics(
    task: str,
    settings: FracneticsSettings,
    population: int,
    generations: int,
    seed: int,
    max_steps: int,
    test_seeds: Sequence[int],
    progress: Callable[[int, float], None] | None = None,
    twin: bool = True,
) -> FracneticsResult:
    """Evolve fracnetics' population on `task` for `generations` (its loop, its operators),
    then live its final elite (the best of the last generation) one episode per test seed.

    `twin`: step the lab's compiled twin of the env where it has one (the same bits, 5-25x
    cheaper a step: `app.tasks.twin_env`); False steps `gymnasium.make(task)`."""
    import fracnetics as fn

    if not 0 <= seed < 2**31 - generations:
        raise TaskError(f"fracnetics arm: seed {seed} must fit its int episode seeds")
    s = settings
    check_population(s, population)
    lo, hi = list(s.obs_low), list(s.obs_high)
    pop = fn.Population(
        seed=seed, ni=population, jn=s.jn, jnf=s.jnf, pn=s.pn, pnf=s.pnf,
        fractalJudgment=False, nFeatureValues=[0] * s.jnf,
    )  # fmt: skip
    pop.setAllNodeBoundaries(lo, hi)
    env = StepCounter(TwinEnv(task) if twin and task in TWIN_TASKS else gym.make(task))
    fitness = np.zeros((generations, population))
    env_steps = np.zeros(generations, np.int64)
    try:
        for g in range(generations):
            pop.gymnasium(
                env, dMax=s.d_max, maxSteps=max_steps, maxConsecutiveP=s.max_consecutive_p,
                seeds=[seed + g],
            )  # fmt: skip
            fitness[g] = [ind.fitness for ind in pop.individuals]
            env_steps[g] = env.take().sum()
            if progress is not None:
                progress(g, float(fitness[g].max()))
            if g + 1 == generations:
                break
            pop.tournamentSelection(N=s.tournament, E=s.elite)
            pop.callAddDelNodes(lo, hi, s.add_del)
            pop.crossover(probability=s.crossover, type="uniform")
            pop.callEdgeMutation(probInnerNodes=s.edge_inner, probStartNode=s.edge_start)
            if s.boundary_uniform is not None:
                pop.callBoundaryMutationUniform(s.boundary_uniform)
        pop.individuals = [pop.individuals[int(np.argmax(fitness[-1]))]]
        pop.gymnasium(
            env, dMax=s.d_max, maxSteps=max_steps, maxConsecutiveP=s.max_consecutive_p,
            seeds=[int(t) for t in test_seeds],
        )  # fmt: skip
        test = np.asarray(pop.individuals[0].caseScores, dtype=np.float64)
        lengths = env.take()
    finally:
        env.close()
    return FracneticsResult(fitness, test, env_steps, lengths)
