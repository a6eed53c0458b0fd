"""Lives of GNP individuals on a Gymnasium task, all of a batch stepping together.

Each individual lives one episode (capped at a number of steps) in its own environment of a
vector env, learning online by Sarsa as its method says; its fitness is the episode's return.
Its environment starts from its own seed, and its controller draws from its own stream, so its
life is the same whatever else is in the batch: a batch equals one-by-one lives with the single
environment (`gymnasium.make(task)` reset with the same seed; tested).

The batch steps through the task's own vector env (`make_vec(..., "vector_entry_point")`) where
the lab knows how to start each of its environments from its own seed (`START_STATES`:
CartPole, whose vector env draws every start state from one stream otherwise), else through
`SyncVectorEnv` reset with one seed per environment. An individual whose episode ended stops
acting (the vector env's autoreset of its environment is ignored); the batch ends when every
episode has. An episode that terminates (not one truncated by a time limit or the cap) ends
with the terminal Sarsa update (`gnp.end_episode`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import gnp
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
    """n environments of `task` stepping together (see the module docstring)."""

    def __init__(
        self, task: str, n: int, adapter: TaskAdapter, faults: FaultPlan | None = None
    ) -> None:
        spec = gym.spec(task)
        self.n = n
        self._start = START_STATES.get(task) if faults is None else None
        self.env: gym.vector.VectorEnv
        self._sync: gym.vector.SyncVectorEnv | None = None
        if self._start is not None and spec.vector_entry_point is not None:
            self.env = gym.make_vec(task, num_envs=n, vectorization_mode="vector_entry_point")
            self.mode = "vector_entry_point"
        else:
            self._start = None
            makers = [_maker(task, adapter, faults, i) for i in range(n)]
            self.env = self._sync = gym.vector.SyncVectorEnv(makers)
            self.mode = "sync"

    def reset(self, seeds: np.ndarray) -> np.ndarray:
        """Start environment i as the single env's `reset(seed=seeds[i])`; (n, d) observations."""
        if self._start is not None:
            self.env.reset(seed=0)
            return self._start(self.env, seeds)
        assert self._sync is not None
        obs, _ = self._sync.reset(seed=[int(s) for s in seeds])
        return np.asarray(obs)

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(observations, rewards, terminated, done: terminated or truncated) after one step of
        every environment."""
        obs, reward, terminated, truncated, _ = self.env.step(actions)
        done = np.logical_or(terminated, truncated)
        rewards = np.asarray(reward, dtype=np.float64)
        return np.asarray(obs), rewards, np.asarray(terminated, dtype=bool), done

    def close(self) -> None:
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
    """What a batch of lives gave: each individual's return and length, and the population
    after its lives (Q tables learned)."""

    returns: np.ndarray
    lengths: np.ndarray
    learned: gnp.Population


def _idle_actions(adapter: TaskAdapter, n: int) -> np.ndarray:
    if adapter.kind == "discrete":
        return np.full(n, adapter.action_start, dtype=adapter.action_dtype)
    return np.tile(adapter.act_low, (n, 1)).astype(adapter.action_dtype)


def live(
    cfg: gnp.GnpConfig,
    adapter: TaskAdapter,
    env: BatchEnv,
    pop: gnp.Population,
    env_seeds: Sequence[int] | np.ndarray,
    engine_seeds: Sequence[int] | np.ndarray,
    epsilon: float,
    alpha: float,
    max_steps: int,
    learn: bool = True,
) -> TaskLives:
    """One episode per individual of `pop` (left unchanged), at most `max_steps` steps each."""
    n = pop.size
    if env.n != n:
        raise ValueError(f"the batch has {env.n} environments for {n} individuals")
    learned = gnp.take(pop, np.arange(n))  # learns in place; `pop` stays as it was
    state = gnp.init_state(cfg, n, np.asarray(engine_seeds, dtype=np.uint64))
    obs = env.reset(np.asarray(env_seeds))
    returns = np.zeros(n)
    lengths = np.zeros(n, np.int64)
    alive = np.arange(n)  # individuals still in their episode
    part, part_state = learned, state  # their population and engine state
    reward = np.zeros(n)
    actions = _idle_actions(adapter, n)
    for _ in range(max_steps):
        readings = adapter.observe(obs[alive])
        commands, _ = gnp.step(cfg, part, part_state, readings, reward, epsilon, alpha, learn)
        actions[alive] = adapter.act(commands)
        obs, rewards, terminated, done = env.step(actions)
        returns[alive] += rewards[alive]
        lengths[alive] += 1
        ended = done[alive]
        if learn and terminated[alive].any():  # a terminal state: Sarsa without a successor
            gnp.end_episode(cfg, part, part_state, rewards[alive], alpha, terminated[alive])
        reward = rewards[alive][~ended]
        if ended.any():
            if part is not learned:
                learned.records[alive[ended]] = part.records[ended]
            keep = np.flatnonzero(~ended)
            alive = alive[keep]
            if alive.size == 0:
                break
            part = gnp.take(part, keep)  # the rest go on in a population of their own
            part_state = gnp.EngineState(
                walk=part_state.walk[keep], wheels=part_state.wheels[keep], rng=part_state.rng[keep]
            )
    if alive.size and part is not learned:
        learned.records[alive] = part.records
    return TaskLives(returns=returns, lengths=lengths, learned=learned)
