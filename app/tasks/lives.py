"""Lives of any brain family's individuals on a Gymnasium task, all of a batch stepping together.

Each individual lives one episode (capped at a number of steps) in its own environment of a
batch env, driven by its family's controllers (`BrainFamily.controllers`) through the task's
adapter (features scaled to readings, commands to actions; `app.tasks.spaces`); its fitness is
the episode's return. Its environment starts from its own seed, and its controller draws from
its own stream, so its life is the same whatever else is in the batch.

`live` is the one path of every family: the controllers step the whole batch each step; an
individual whose episode ended stops counting (its return and length are kept, its actions are
ignored, its reward is 0), and one that learns online (`app.loop.rollout.OnlineLearner`, given
ε, α and `learn`) is kept as it was when its episode ended (a copy taken then, after the
terminal update of a `TerminalLearner`, GNP's Sarsa, if the task terminated it). A family may
have lives of its own on tasks, keyed by its name in `FAMILY_LIVES` and reached through
`live`: GNP's (`app.tasks.gnp_lives`), which step only the individuals still in their episode,
end a terminated one with the terminal Sarsa update, and on CartPole, MountainCar and Acrobot
(`app.tasks.dynamics.FAST_TASKS`) run every individual's whole episode in one compiled call on
the lab's twins of their envs (bit for bit Gymnasium's, tested step for step), 4-60 times
faster (bench/tasks.py).

The environments (`BatchEnv`): a task with a compiled twin (`dynamics.FAST_TASKS`: CartPole,
MountainCar, Acrobot, Pendulum) and no observation faults steps the lab's twins, every
environment of the batch in one compiled call per step ("twin", `dynamics.step_live`), each
env's steps counted to its time limit as Gymnasium's `TimeLimit` counts them; so do every
family without lives of its own (CMA-ES, NEAT) and GNP on Pendulum, whose action is a Box
(bench/batch_twin.py). Any other task, and a batch with observation faults, go through
Gymnasium: the batch steps through the task's own vector env (`make_vec(...,
"vector_entry_point")`) where the lab knows how to start each of its environments from its own
seed (`START_STATES`: CartPole, whose vector env draws every start state from one stream
otherwise), else through `SyncVectorEnv` reset with one seed per environment; `twins=False`
takes this path for a task with a twin too. The vector env's autoreset of an environment whose
episode ended is ignored; the batch ends when every episode has.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from app.brains.contract import BrainFamily, TerminalLearner
from app.brains.gnp_brain import GnpFamily
from app.loop.rollout import OnlineLearner
from app.tasks import dynamics
from app.tasks.faults import ObservationFault, ObservationFaults
from app.tasks.spaces import TaskAdapter


def _cartpole_starts(env: Any, seeds: np.ndarray) -> np.ndarray:
    """CartPoleEnv.reset(seed=s)'s start state for every s, written into the vector env."""
    unwrapped = env.unwrapped
    unwrapped.state = np.stack(
        [np.random.default_rng(int(s)).uniform(-0.05, 0.05, size=(4,)) for s in seeds], axis=1
    )
    return np.asarray(unwrapped.state.T.astype(np.float32))


#: Task ids whose shipped vector env the lab starts per environment: id → writer of the start
#: states of seeds (the single env's `reset(seed=s)`), returning the first observations.
START_STATES: dict[str, Callable[[Any, np.ndarray], np.ndarray]] = {
    "CartPole-v0": _cartpole_starts,
    "CartPole-v1": _cartpole_starts,
}


@dataclass(frozen=True)
class FaultPlan:
    """Observation faults for every environment of a batch: the schedule, and each
    environment's `random` stream seed (`seeds[i]`)."""

    faults: tuple[ObservationFault, ...]
    seeds: tuple[int, ...]


class BatchEnv:
    """n environments of `task` stepping together (see the module docstring), in one of four
    modes: "fast" (the lab's compiled twin of the env, `fast`, for lives that run it
    themselves, GNP's fused lives on a discrete task: no Gymnasium env is made and the batch
    env is never stepped; only with `fused`), "twin" (a batch of compiled twins, `twin`,
    stepped in one compiled call through `reset` and `step`), else Gymnasium's
    "vector_entry_point" or "sync" (`env`). Twins only with `twins` and without faults.

    In the "twin" mode an environment whose episode has ended is not stepped again until the
    next `reset`: it gives reward 0, not terminated, done (Gymnasium's vector env starts a new
    episode there instead; the lives ignore both)."""

    def __init__(
        self,
        task: str,
        n: int,
        adapter: TaskAdapter,
        faults: FaultPlan | None = None,
        twins: bool = True,
        fused: bool = True,
    ) -> None:
        spec = gym.spec(task)
        self.n = n
        self.adapter = adapter
        twin = dynamics.FAST_TASKS.get(task) if faults is None and twins else None
        self.fast: dynamics.FastTask | None = None
        self.twin: dynamics.FastTask | None = None
        self._start = START_STATES.get(task) if faults is None else None
        self.env: gym.vector.VectorEnv | None = None
        self._sync: gym.vector.SyncVectorEnv | None = None
        if twin is not None and fused and adapter.kind == "discrete" and not twin.box:
            self.fast, self.mode = twin, "fast"
        elif twin is not None:
            self.twin, self.mode = twin, "twin"
            self._state = np.zeros((n, twin.state_dim))
            self._obs = np.zeros((n, twin.obs_dim), np.float32)
            self._elapsed = np.full(n, -1, np.int64)  # no episode before a reset
            self._reward = np.zeros(n)
            self._terminated = np.zeros(n, np.bool_)
            self._done = np.zeros(n, np.bool_)
        elif self._start is not None and spec.vector_entry_point is not None:
            self.env = gym.make_vec(task, num_envs=n, vectorization_mode="vector_entry_point")
            self.mode = "vector_entry_point"
        else:
            self._start = None
            makers = [_maker(task, adapter, faults, i) for i in range(n)]
            self.env = self._sync = gym.vector.SyncVectorEnv(makers)
            self.mode = "sync"

    def reset(self, seeds: np.ndarray) -> np.ndarray:
        """Start environment i as the single env's `reset(seed=seeds[i])`; (n, d) observations."""
        if self.twin is not None:
            if len(seeds) != self.n:
                raise ValueError(f"{len(seeds)} seeds for a batch of {self.n} environments")
            self._state[:], self._obs[:] = dynamics.starts(self.twin, np.asarray(seeds))
            self._elapsed[:] = 0
            return self._obs.copy()
        assert self.env is not None, "a fast batch has no Gymnasium env"
        if self._start is not None:
            self.env.reset(seed=0)
            return self._start(self.env, seeds)
        assert self._sync is not None
        obs, _ = self._sync.reset(seed=[int(s) for s in seeds])
        return np.asarray(obs)

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(observations, rewards, terminated, done: terminated or truncated) after one step of
        every environment."""
        if self.twin is not None:
            dynamics.step_live(
                self.twin, self._state, self._twin_actions(actions), self._obs, self._reward,
                self._terminated, self._done, self._elapsed,
            )  # fmt: skip
            return self._obs.copy(), self._reward.copy(), self._terminated.copy(), self._done.copy()
        assert self.env is not None, "a fast batch has no Gymnasium env"
        obs, reward, terminated, truncated, _ = self.env.step(actions)
        done = np.logical_or(terminated, truncated)
        rewards = np.asarray(reward, dtype=np.float64)
        return np.asarray(obs), rewards, np.asarray(terminated, dtype=bool), done

    def _twin_actions(self, actions: np.ndarray) -> np.ndarray:
        """`actions` as the twins take them, refused where Gymnasium's env would take others
        (an action outside a Discrete space, a Box action of another dtype or shape)."""
        adapter = self.adapter
        if adapter.kind == "discrete":
            taken = np.asarray(actions)
            low, high = adapter.action_start, adapter.action_start + adapter.n_actions
            if taken.shape != (self.n,) or taken.min() < low or taken.max() >= high:
                raise ValueError(f"{self.n} actions in {low}..{high - 1} expected, got {taken}")
            return taken.astype(np.int64)
        taken = np.asarray(actions)
        if taken.dtype != np.float32 or taken.shape != (self.n, 1):
            raise ValueError(f"({self.n}, 1) float32 actions expected, got {taken.dtype} "
                             f"{taken.shape}")  # fmt: skip
        return np.ascontiguousarray(taken)

    def close(self) -> None:
        if self.env is not None:
            self.env.close()


def _maker(
    task: str, adapter: TaskAdapter, faults: FaultPlan | None, i: int
) -> Callable[[], gym.Env]:
    def make() -> gym.Env:
        env = gym.make(task)
        if faults is not None:
            env = ObservationFaults(
                env, faults.faults, adapter.obs_low, adapter.obs_high, faults.seeds[i]
            )
        return env

    return make


@dataclass(frozen=True)
class TaskLives:
    """What a batch of lives gave: each individual's return and length, and the individuals
    after their lives (the family's; what online learners learned in their episode)."""

    returns: np.ndarray
    lengths: np.ndarray
    learned: Any


def idle_actions(adapter: TaskAdapter, n: int) -> np.ndarray:
    """Actions of n individuals before they act (of those whose episode has ended)."""
    if adapter.kind == "discrete":
        return np.full(n, adapter.action_start, dtype=adapter.action_dtype)
    return np.tile(adapter.act_low, (n, 1)).astype(adapter.action_dtype)


class FamilyLives(Protocol):
    """A family's own lives on a task, with `live`'s arguments and result."""

    def __call__(
        self,
        family: BrainFamily,
        adapter: TaskAdapter,
        env: BatchEnv,
        individuals: Any,
        env_seeds: np.ndarray,
        engine_seeds: np.ndarray,
        epsilon: float,
        alpha: float,
        max_steps: int,
        learn: bool,
    ) -> TaskLives: ...


FAMILY_LIVES: dict[str, str] = {GnpFamily.name: "app.tasks.gnp_lives:family_lives"}
"""Families with lives of their own on tasks: name → "module:function" (a `FamilyLives`),
imported on first use."""


def family_lives(name: str) -> FamilyLives | None:
    """The lives of family `name` on tasks, if it has its own."""
    entry = FAMILY_LIVES.get(name)
    if entry is None:
        return None
    module, _, function = entry.partition(":")
    found: FamilyLives = getattr(importlib.import_module(module), function)
    return found


def batch_env(
    family: BrainFamily, task: str, n: int, adapter: TaskAdapter, faults: FaultPlan | None = None
) -> BatchEnv:
    """The batch env of `family`'s lives: the task's compiled twin where it has one and there
    are no faults, fused into the lives of a family with lives of its own (`FAMILY_LIVES`:
    GNP's, on a discrete task), else a batch of twins; Gymnasium's otherwise."""
    return BatchEnv(task, n, adapter, faults, fused=family.name in FAMILY_LIVES)


def live(
    family: BrainFamily,
    adapter: TaskAdapter,
    env: BatchEnv,
    individuals: Any,
    env_seeds: Sequence[int] | np.ndarray,
    engine_seeds: Sequence[int] | np.ndarray,
    epsilon: float,
    alpha: float,
    max_steps: int,
    learn: bool = True,
) -> TaskLives:
    """One episode per individual of `individuals` (left unchanged; the family's, bound to the
    task's `BrainIO`), at most `max_steps` steps each (see the module docstring)."""
    env_seeds, engine_seeds = np.asarray(env_seeds), np.asarray(engine_seeds, dtype=np.uint64)
    own = family_lives(family.name)
    if own is not None:
        return own(
            family, adapter, env, individuals, env_seeds, engine_seeds, epsilon, alpha,
            max_steps, learn,
        )  # fmt: skip
    return generic_lives(
        family, adapter, env, individuals, env_seeds, engine_seeds, epsilon, alpha, max_steps,
        learn,
    )  # fmt: skip


def generic_lives(
    family: BrainFamily,
    adapter: TaskAdapter,
    env: BatchEnv,
    individuals: Any,
    env_seeds: np.ndarray,
    engine_seeds: np.ndarray,
    epsilon: float,
    alpha: float,
    max_steps: int,
    learn: bool = True,
) -> TaskLives:
    """`live` through the contract alone: any family's controllers over the batch env."""
    n = env.n
    if len(engine_seeds) != n:
        raise ValueError(f"the batch has {n} environments for {len(engine_seeds)} individuals")
    lived = family.for_life(individuals)  # a copy if they learn: `individuals` stay as they were
    controllers = family.controllers(lived, engine_seeds)
    if controllers.size != n:
        raise ValueError(f"the batch has {n} environments for {controllers.size} individuals")
    if isinstance(controllers, OnlineLearner):
        controllers.set_rates(epsilon, alpha, learn)
    learner = family.learns_online
    ender = controllers if learner and isinstance(controllers, TerminalLearner) else None
    if env.mode == "fast":
        raise ValueError("a batch of compiled twins steps a family's own lives only")
    obs = env.reset(env_seeds)
    returns = np.zeros(n)
    lengths = np.zeros(n, np.int64)
    alive = np.ones(n, bool)
    ended_as: dict[int, Any] = {}  # a learner as its episode ended
    reward = np.zeros(n)
    actions = idle_actions(adapter, n)
    for _ in range(max_steps):
        commands, _ = controllers.act(adapter.observe(obs), reward, trace=False)
        commands = np.asarray(commands, dtype=np.float64)
        if commands.shape != (n, adapter.n_outputs):
            raise ValueError(
                f"brain family {family.name!r} gave commands of shape {commands.shape}; the "
                f"task takes ({n}, {adapter.n_outputs})"
            )
        actions[alive] = adapter.act(commands[alive])
        obs, rewards, terminated, done = env.step(actions)
        returns[alive] += rewards[alive]
        lengths[alive] += 1
        ended = alive & done
        finished = alive & terminated
        if ender is not None and finished.any():
            ender.end_episode(rewards, finished)  # e.g. Sarsa's terminal update
        if learner:
            for i in np.flatnonzero(ended):
                ended_as[int(i)] = family.take(lived, [int(i)])
        alive &= ~done
        if not alive.any():
            break
        reward = np.where(alive, rewards, 0.0)
    if learner and ended_as:
        # (not `get(i) or …`: a family's individuals need not have a truth value)
        rows = [ended_as[i] if i in ended_as else family.take(lived, [i]) for i in range(n)]
        lived = family.concat(rows)
    return TaskLives(returns=returns, lengths=lengths, learned=lived)
