"""GNP's own lives on a Gymnasium task (`app.tasks.lives.FAMILY_LIVES`), as before #46 item 2.

Only the individuals still in their episode step: the rest go on in a population of their own
(`gnp.take`), so an ended individual keeps what it learned in its episode; an episode that
terminates (not one truncated by a time limit or the cap) ends with the terminal Sarsa update
(`gnp.end_episode`). On a discrete task with a compiled twin (`app.tasks.dynamics.FAST_TASKS`)
the whole batch lives in one compiled call (`dynamics.lives`), the same lives bit for bit; on
Pendulum-v1 (a Box action) it steps the batch env, a batch of twins ("twin" mode).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

import gnp
from app.brains.contract import BrainFamily
from app.tasks import dynamics
from app.tasks.lives import BatchEnv, TaskLives, idle_actions
from app.tasks.spaces import TaskAdapter


def family_lives(
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
) -> TaskLives:
    """`app.tasks.lives.live` of the GNP family (its `graph_config` is the brain's config)."""
    cfg = family.graph_config
    assert cfg is not None, f"{family.name} has no GNP config"
    return live(
        cfg, adapter, env, individuals, env_seeds, engine_seeds, epsilon, alpha, max_steps,
        learn,
    )  # fmt: skip


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
    if env.fast is not None:
        returns, lengths = dynamics.lives(
            env.fast, cfg, adapter, learned, state, np.asarray(env_seeds), epsilon, alpha,
            max_steps, learn,
        )  # fmt: skip
        return TaskLives(returns=returns, lengths=lengths, learned=learned)
    obs = env.reset(np.asarray(env_seeds))
    returns = np.zeros(n)
    lengths = np.zeros(n, np.int64)
    alive = np.arange(n)  # individuals still in their episode
    part, part_state = learned, state  # their population and engine state
    reward = np.zeros(n)
    actions = idle_actions(adapter, n)
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
