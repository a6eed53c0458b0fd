"""Lives of a batch of individuals, either brain family: the unit of training's work.

A GNP individual learns online (its Q tables change in place), a net does not. Individual i of
a generation always lives in the same world (the fixed shards, see `shards`), and a robot's
life does not depend on its world's other robots (see docs/decisions.md), so results do not
depend on the number of workers.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

import gnp
import neuro
import sim
from app.arenas import arena_of, new_world
from app.config import CFrom, RunConfig, TrainingSettings
from app.neural import Individual, NeuralControllers, trace_layout
from app.recording import Trajectory, TrajectoryRecorder
from app.rollout import Batch, rollout
from app.seeds import LifeSeeds


@dataclass(frozen=True)
class Lives:
    """Outcome of N lives: fitness (Eq. 2.8) and the mean per step of every reward term."""

    fitness: np.ndarray  # (N,)
    terms: np.ndarray  # (N, len(sim.TERM_NAMES))


def _live(
    world: sim.World,
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
    cfg: gnp.GnpConfig,
    pop: gnp.Population,
    seeds: LifeSeeds,
    steps: int,
    redraw_every: int,
    epsilon: float,
    alpha: float,
    record: bool = False,
    c_from: CFrom = "true",
) -> tuple[Lives, Trajectory | None]:
    """Let N individuals live `steps` steps in `world`, learning online (Q tables in place).

    Each life starts at its first start pose; with `redraw_every` > 0 the robot is moved to its
    next start pose every `redraw_every` steps and the controller starts a new episode (its Q
    tables, random stream and the world's streams carry on). `c_from`: the readings the
    reward's C is judged from (see `Batch`).
    """
    world.reset(world.arena.start_poses[seeds.starts[:, 0]], seeds=seeds.world)
    batch = Batch(world, cfg, pop, seeds.engine, c_from)
    return _live(world, batch, cfg, seeds, steps, redraw_every, epsilon, alpha, True, record)


def live_nets(
    world: sim.World,
    net: neuro.NetConfig,
    arrays: dict[str, np.ndarray],
    seeds: LifeSeeds,
    steps: int,
    redraw_every: int,
    record: bool = False,
) -> tuple[Lives, Trajectory | None]:
    """N nets' lives of `steps` steps in `world` (as `live`, without learning)."""
    world.reset(world.arena.start_poses[seeds.starts[:, 0]], seeds=seeds.world)
    batch = Batch.driven_by(world, NeuralControllers(net, arrays))
    recorded = trace_layout(net)
    return _live(world, batch, recorded, seeds, steps, redraw_every, 0.0, 0.0, False, record)


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


# --- either family behind one interface -------------------------------------------------------


class ShardLives(Protocol):
    """The lives of a fixed set of individuals, in one persistent world (built on first use)."""

    def run(
        self, individuals: Any, seeds: LifeSeeds, epsilon: float, alpha: float, record: bool
    ) -> tuple[Lives, Any, Trajectory | None]:
        """Lives of `individuals` (left as they are): with the individuals after them (GNP
        learned; nets as they were) and, with `record`, the trajectory."""
        ...


class _GnpLives:
    def __init__(self, config: RunConfig) -> None:
        self._config = config
        self._cfg = config.controller.gnp_config()
        self._world: sim.World | None = None

    def run(
        self,
        individuals: gnp.Population,
        seeds: LifeSeeds,
        epsilon: float,
        alpha: float,
        record: bool = False,
    ) -> tuple[Lives, gnp.Population, Trajectory | None]:
        if self._world is None:
            self._world = make_world(self._config, individuals.size)
        training = self._config.training
        learned = individuals.copy()
        lives, trajectory = live(
            self._world,
            self._cfg,
            learned,
            seeds,
            training.steps,
            training.redraw_every,
            epsilon,
            alpha,
            record=record,
            c_from=self._config.reward.c_from,
        )
        return lives, learned, trajectory


class _NetLives:
    def __init__(self, config: RunConfig) -> None:
        assert config.neuro is not None
        self._config = config
        self._net = config.neuro.net_config()
        self._world: sim.World | None = None

    def run(
        self,
        individuals: dict[str, np.ndarray],
        seeds: LifeSeeds,
        epsilon: float,
        alpha: float,
        record: bool = False,
    ) -> tuple[Lives, dict[str, np.ndarray], Trajectory | None]:
        if self._world is None:
            self._world = make_world(self._config, len(seeds.world))
        training = self._config.training
        lives, trajectory = live_nets(
            self._world,
            self._net,
            individuals,
            seeds,
            training.steps,
            training.redraw_every,
            record=record,
        )
        return lives, individuals, trajectory


def shard_lives(config: RunConfig) -> ShardLives:
    """The lives of `config`'s brain family (a `neuro` section: nets, else GNP)."""
    return _GnpLives(config) if config.neuro is None else _NetLives(config)


def take(individuals: Individual, rows: np.ndarray | list[int]) -> Individual:
    """The individuals at `rows` of a population of either family."""
    if isinstance(individuals, gnp.Population):
        return gnp.take(individuals, rows)
    return neuro.take(individuals, rows)


def concat(parts: list[Any]) -> Any:
    """Populations of either family, one after the other."""
    if isinstance(parts[0], gnp.Population):
        return gnp.concat(parts)
    return neuro.concat(parts)


def concat_lives(parts: list[Lives]) -> Lives:
    """Lives of consecutive individuals, one after the other."""
    return Lives(
        fitness=np.concatenate([p.fitness for p in parts]),
        terms=np.concatenate([p.terms for p in parts]),
    )
