"""Lives of a batch of individuals, any brain family: the unit of training's work.

A family that learns online (GNP: its Q tables change in place) lives a copy of its
individuals; one that does not (a net) lives them as they are. Individual i of a generation
always lives in the same world (the fixed shards, see `shards`), and a robot's life does not
depend on its world's other robots (see docs/decisions.md), so results do not depend on the
number of workers.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

import sim
from app.brains.contract import BrainFamily
from app.brains.registry import family_of
from app.loop.recording import Trajectory, TrajectoryRecorder
from app.loop.rollout import Batch, rollout
from app.loop.seeds import LifeSeeds
from app.settings.arenas import arena_of, new_world
from app.settings.config import CFrom, RunConfig, TrainingSettings


@dataclass(frozen=True)
class Lives:
    """Outcome of N lives: fitness (Eq. 2.8) and the mean per step of every reward term."""

    fitness: np.ndarray  # (N,)
    terms: np.ndarray  # (N, len(sim.TERM_NAMES))


def _live(
    batch: Batch,
    recorded: Any,
    seeds: LifeSeeds,
    steps: int,
    redraw_every: int,
    epsilon: float,
    alpha: float,
    learn: bool,
    record: bool,
) -> tuple[Lives, Trajectory | None]:
    recorder = TrajectoryRecorder(batch.size, steps, recorded) if record else None
    outcome = rollout(
        batch,
        steps,
        epsilon,
        alpha,
        learn=learn,
        recorder=recorder,
        episode_starts=seeds.starts,
        redraw_every=redraw_every,
    )
    means = outcome.term_sums / steps
    lives = Lives(fitness=means[:, 0].copy(), terms=means)
    if recorder is None:
        return lives, None
    return lives, recorder.trajectory(seeds.starts[:, 0])


def live(
    world: sim.World,
    family: BrainFamily,
    individuals: Any,
    seeds: LifeSeeds,
    steps: int,
    redraw_every: int,
    epsilon: float,
    alpha: float,
    record: bool = False,
    c_from: CFrom = "true",
) -> tuple[Lives, Trajectory | None]:
    """Let N individuals live `steps` steps in `world`; those of a family that learns online
    learn into `individuals` in place.

    Each life starts at its first start pose; with `redraw_every` > 0 the robot is moved to its
    next start pose every `redraw_every` steps and the controller starts a new episode (its
    learning, random stream and the world's streams carry on). `c_from`: the readings the
    reward's C is judged from (see `Batch`).
    """
    world.reset(world.arena.start_poses[seeds.starts[:, 0]], seeds=seeds.world)
    batch = Batch(world, family.controllers(individuals, seeds.engine), c_from)
    learn = family.learns_online
    if not learn:  # nothing reads ε and α then; the file records them as NaN
        epsilon = alpha = 0.0
    recorded = family.trace_layout
    return _live(batch, recorded, seeds, steps, redraw_every, epsilon, alpha, learn, record)


def make_world(config: RunConfig, n: int) -> sim.World:
    """A training world of `n` robots for `config`."""
    training = config.training
    return new_world(
        arena_of(training.arena),
        n=n,
        seed=config.seed,
        noise_sigma=training.noise_sigma,
        control_period=training.control_period,
        physics=training.physics,
        noise_stream=training.noise_stream,
    )


def shards(training: TrainingSettings) -> list[slice]:
    """The fixed split of the population into shards of about `shard_size` robots.

    Shards are the unit of work: a worker owns a contiguous run of whole shards and lives them
    in one world. A robot's life does not depend on its world's other robots (see
    docs/decisions.md), so results do not depend on the number of workers.
    """
    count = max(1, math.ceil(training.population / training.shard_size))
    bounds = np.linspace(0, training.population, count + 1).round().astype(int)
    return [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)]


def owned(training: TrainingSettings, workers: int) -> list[slice]:
    """The individuals each of `workers` workers lives: contiguous runs of whole shards."""
    parts = shards(training)
    bounds = np.linspace(0, len(parts), workers + 1).round().astype(int)
    return [slice(parts[a].start, parts[b - 1].stop) for a, b in itertools.pairwise(bounds)]


# --- a shard's lives, any family -------------------------------------------------------------


class ShardLives:
    """The lives of a fixed set of individuals, in one persistent world (built on first use)."""

    def __init__(self, config: RunConfig) -> None:
        self._config = config
        self.family = family_of(config)
        self._world: sim.World | None = None

    def run(
        self, individuals: Any, seeds: LifeSeeds, epsilon: float, alpha: float, record: bool
    ) -> tuple[Lives, Any, Trajectory | None]:
        """Lives of `individuals` (left as they are): with the individuals after them (what
        they learned, or themselves) and, with `record`, the trajectory."""
        if self._world is None:
            self._world = make_world(self._config, len(seeds.world))
        training = self._config.training
        after = self.family.for_life(individuals)
        lives, trajectory = live(
            self._world,
            self.family,
            after,
            seeds,
            training.steps,
            training.redraw_every,
            epsilon,
            alpha,
            record=record,
            c_from=self._config.reward.c_from,
        )
        return lives, after, trajectory


def concat_lives(parts: list[Lives]) -> Lives:
    """Lives of consecutive individuals, one after the other."""
    return Lives(
        fitness=np.concatenate([p.fitness for p in parts]),
        terms=np.concatenate([p.terms for p in parts]),
    )
