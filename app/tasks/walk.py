"""What a task run's elite does inside its graph, step by step (issue #45).

A replay gives an episode's return; `walk_episode` also counts, from gnp's trace of every
step, how often the walk ran a processing node (the only way the brain changes its action),
how many node visits and credit skips it made, and which actions it took. It lives the episode
in Gymnasium's own env through `gnp.step`, one step at a time, so it is slow beside the compiled
replay, and its return is the replay's (tested). Found with it: the tuned Fuzzy CS elites' greedy
walk runs no processing node at all on MountainCar and Acrobot (docs/decisions.md, "Why tuned CS
tests at the floor").
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import gnp
from app.tasks.common import TestProtocol
from app.tasks.config import TaskRunConfig, make_env
from app.tasks.store import read_task_run


@dataclass(frozen=True)
class WalkSummary:
    """One episode of an individual, seen from inside its graph.

    Attributes:
        episode_return: the episode's return.
        steps: its length in env steps.
        acting_steps: steps in which a processing node ran (not skipped through its credit
            branch); in the others every output kept its value.
        visits: node visits, the start node left out.
        skips: credit skips among them (CS; 0 for RL and BS).
        actions: how many steps took each action (Discrete tasks; empty for Box ones).
    """

    episode_return: float
    steps: int
    acting_steps: int
    visits: int
    skips: int
    actions: dict[int, int]


def walk_individual(
    config: TaskRunConfig,
    cfg: gnp.GnpConfig,
    individual: gnp.Population,
    seed: int,
    epsilon: float,
    alpha: float,
    learn: bool,
) -> WalkSummary:
    """Live one episode of the one-individual population `individual` (left unchanged) from
    `seed` (the env's and the controller stream's, as a replay does), at most the run's cap."""
    adapter = config.adapter
    clone = gnp.take(individual, np.zeros(1, np.intp))
    state = gnp.init_state(cfg, 1, [seed])
    env = make_env(config.task.id)
    try:
        obs, _ = env.reset(seed=seed)
        reward = np.zeros(1)
        total, steps, acting, visits, skips = 0.0, 0, 0, 0, 0
        actions: Counter[int] = Counter()
        for _ in range(config.training.steps):
            readings = adapter.observe(np.asarray(obs)[None, :])
            commands, trace = gnp.step(
                cfg, clone, state, readings, reward, epsilon, alpha, learn, trace=True
            )
            assert trace is not None
            count = int(trace.count[0])
            node, skipped = trace.node[0, :count], trace.skipped[0, :count]
            acting += int(np.any((node > cfg.n_judgment) & (skipped != 1)))
            visits += int(np.count_nonzero(node > 0))
            skips += int(np.count_nonzero(skipped == 1))
            action = adapter.act(commands)[0]
            if adapter.kind == "discrete":
                actions[int(action)] += 1
            obs, r, terminated, truncated, _ = env.step(action)
            total += float(r)
            steps += 1
            reward = np.full(1, float(r))
            if terminated or truncated:
                break
    finally:
        env.close()
    return WalkSummary(total, steps, acting, visits, skips, dict(sorted(actions.items())))


def walk_episode(
    path: str | Path,
    seed: int,
    protocol: TestProtocol = "greedy",
    generation: int | None = None,
) -> WalkSummary:
    """`walk_individual` of a run's generation best (default: the last) under a test protocol:
    "greedy" (ε = 0, Sarsa frozen) or "as-trained" (its generation's ε and α, Sarsa on), the
    episode `protocol_episodes` lives from `seed`."""
    run = read_task_run(path)
    cfg, individual = run.best_genome(generation)
    g = run.generation_done - 1 if generation is None else generation
    greedy = protocol == "greedy"
    epsilon = 0.0 if greedy else float(run.epsilon[g])
    return walk_individual(
        run.config, cfg, individual, seed, epsilon, float(run.alpha[g]), learn=not greedy
    )
