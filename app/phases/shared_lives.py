"""A GNP run's generations on the worker pool, its populations in shared memory, not the pipes.

The parent keeps one shared block per run (`SharedArrays`): the population to live, the
population after its lives (what it learned), the fitness and the reward terms. The workers
are sent only what to do (`RowsJob`, `EvolveJob`: a few numbers), never a population:

- lives: a worker draws its rows' seeds itself (keyed by (seed, generation, individual),
  `app.loop.seeds`), reads its rows, lives them in its persistent world and writes them back;
- evolution: `gnp.evolve` split in two, done by two workers at once, each writing its rows of
  the next population into the block (`evolve_part`), so the parent has no evolution to do
  between two generations' lives.

The parent is left copying a generation's fitness out and writing the run file, which
`app.phases.generations` overlaps with the next generation's lives. Bits do not change: a life
does not depend on its world's other robots, the seeds are keyed by individual, and the two
halves of evolution draw exactly what `gnp.evolve` draws
(tests/app/phases/test_shared_generations.py holds them to it).

Only a GNP population goes this way (its records are one block of memory); the nets' families,
whose individuals do not learn, keep the pipes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

import gnp
import sim
from app.brains.contract import Evolution
from app.brains.gnp_brain import GnpFamily, generation_epsilon_alpha
from app.brains.gnp_settings import gnp_settings
from app.brains.registry import family_of
from app.loop.seeds import evolution_rng, life_seeds, n_segments
from app.phases.lives import ShardLives, live, make_world
from app.settings.arenas import arena_of
from app.settings.config import RunConfig
from app.system.workers import Count, Layout, SharedArrays
from gnp.evolution import crossover, mutants, tournament
from gnp.population import Population, concat


@dataclass(frozen=True)
class RowsJob:
    """Live individuals `start`..`stop`−1 of `generation` (with ε, α) from the shared block."""

    start: int
    stop: int
    generation: int
    epsilon: float
    alpha: float


@dataclass(frozen=True)
class EvolveJob:
    """Write part `part` (0 or 1, see `evolve_part`) of the population after `generation`."""

    part: int
    generation: int


EVOLVE_PARTS = 2

#: Gives each job to the pool (job i to worker i mod the workers); their answers, in job order.
RunJobs = Callable[[list[Any]], list[Any]]


@dataclass(frozen=True)
class InBlock:
    """Individuals held in the shared block: a view of its records (not a copy).

    Valid until the workers next write those records: the loop copies what it keeps."""

    records: np.ndarray

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: self.records[name] for name in gnp.population.FIELDS}

    def take(self, rows: list[int]) -> Population:
        return Population.from_records(self.records, np.asarray(rows, np.intp))


def shared_layout(config: RunConfig) -> Layout | None:
    """The shared block of a run's generations, or None when its family does not use one."""
    if not isinstance(family_of(config), GnpFamily):
        return None
    cfg = gnp_settings(config).controller.gnp_config()
    records = gnp.population.record_dtype(cfg.n_sub, cfg.n_conn_branches, cfg.judgment_branches)
    n = config.training.population
    return {
        "population": ((n, cfg.n_nodes), records),
        "learned": ((n, cfg.n_nodes), records),
        "fitness": ((n,), np.float64),
        "terms": ((n, len(sim.TERM_NAMES)), np.float64),
    }


def evolve_part(
    cfg: gnp.GnpConfig,
    evo: gnp.EvolutionConfig,
    learned: np.ndarray,
    fitness: np.ndarray,
    generation: int,
    n_generations: int,
    rng: np.random.Generator,
    part: int,
) -> tuple[int, Population | None]:
    """Part `part` of `gnp.evolve(cfg, learned, fitness, generation, n_generations, rng, evo)`,
    and the row it starts at: 0, the elites and the crossover offspring (rows 0..); 1, the
    mutants (the rows after them; None if there are none). `rng` is fresh, as `gnp.evolve`'s.

    Each part makes the same calls on the same stream as `gnp.evolve`: the mutants' part also
    draws the crossover's numbers (two tournaments and the swap mask, ~0.7 ms at 300), to
    reach its own in the one stream. `learned`: the population's records.
    """
    n = len(fitness)
    n_elite, n_cross, n_mut = evo.split(n)
    pairs = n_cross // 2
    size = evo.tournament_size

    def rows(index: np.ndarray) -> Population:  # gnp.take, without copying the whole first
        return Population.from_records(learned, np.asarray(index).astype(np.intp) % n)

    if part == 0:
        elite = np.argsort(-fitness, kind="stable")[:n_elite]
        parts = [rows(elite)]
        if n_cross:
            mothers = tournament(fitness, pairs, size, rng)
            fathers = tournament(fitness, pairs, size, rng)
            parts.append(crossover(rows(mothers), rows(fathers), evo.p_crossover, rng))
        return 0, concat(parts)
    if n_cross:
        tournament(fitness, pairs, size, rng)
        tournament(fitness, pairs, size, rng)
        rng.random((pairs, cfg.n_nodes))  # crossover's swap mask
    first = n_elite + 2 * pairs
    if not n_mut:
        return first, None
    parents = tournament(fitness, n_mut, size, rng)
    return first, mutants(cfg, rows(parents), generation, n_generations, rng, evo)


class RowsWorker:
    """A worker's side: lives the rows it is told of, in one persistent world, and writes its
    part of the next population."""

    def __init__(self, config: RunConfig, spec: tuple[str, Layout]) -> None:
        self.config = config
        self.block = SharedArrays.attach(spec)
        self.lives = ShardLives(config)  # the pipes' jobs (`app.phases.generations`)
        self.family = self.lives.family
        self._world: sim.World | None = None
        self._world_rows = 0
        self.cfg = gnp_settings(config).controller.gnp_config()
        training = config.training
        self._segments = n_segments(training.steps, training.redraw_every)
        self._n_starts = len(arena_of(training.arena).start_poses)

    def __call__(self, job: RowsJob | EvolveJob, _count: Count) -> None:
        # A `Handler`: its progress callback is unused, a job reports when it returns.
        if isinstance(job, EvolveJob):
            self.evolve(job)
            return
        config, block = self.config, self.block
        rows = slice(job.start, job.stop)
        seeds = life_seeds(
            config.seed,
            job.generation,
            np.arange(job.start, job.stop),
            self._segments,
            self._n_starts,
        )
        if self._world is None or self._world_rows != job.stop - job.start:
            # built once: a worker is given the same rows every generation
            self._world = make_world(config, job.stop - job.start)
            self._world_rows = job.stop - job.start
        # `ShardLives.run` without its copy: this one, out of the block, is what lives learn into
        after = Population.from_records(block["population"][rows])
        training = config.training
        lives, _ = live(
            self._world,
            self.family,
            after,
            seeds,
            training.steps,
            training.redraw_every,
            job.epsilon,
            job.alpha,
            c_from=config.reward.c_from,
        )
        block["learned"][rows] = after.records
        block["fitness"][rows] = lives.fitness
        block["terms"][rows] = lives.terms

    def evolve(self, job: EvolveJob) -> None:
        config, block = self.config, self.block
        first, part = evolve_part(
            self.cfg,
            gnp_settings(config).evolution,
            block["learned"],
            block["fitness"].copy(),
            job.generation,
            config.training.generations,
            evolution_rng(config.seed, job.generation),
            job.part,
        )
        if part is not None:
            block["population"][first : first + part.size] = part.records


class SharedEvolution:
    """A GNP run's population kept in the shared block and evolved by the workers: the
    `Evolution` the loop is given in place of `GnpEvolution` when generations go to the pool.

    `individuals()` and what `advance` returns are views of the block (`InBlock`): the loop
    copies what it keeps beyond the next generation's start (the best genome's row)."""

    def __init__(self, config: RunConfig, block: SharedArrays, run: RunJobs) -> None:
        """`run(jobs)`: each job given to the pool (job i to worker i mod workers), until done."""
        self._config, self._block, self._run = config, block, run
        self._rates = partial(generation_epsilon_alpha, config.training)

    def epsilon_alpha(self, generation: int) -> tuple[float, float]:
        return self._rates(generation)

    def individuals(self) -> InBlock:
        return InBlock(self._block["population"])

    def arrays(self, individuals: InBlock | Population) -> dict[str, np.ndarray]:
        if isinstance(individuals, InBlock):
            return individuals.arrays()
        return gnp.population_to_arrays(individuals)

    def advance(self, learned: Any, fitness: np.ndarray, generation: int) -> dict[str, np.ndarray]:
        fit = np.asarray(fitness, dtype=np.float64)
        if not np.all(np.isfinite(fit)):  # as gnp.evolve refuses it, before any worker starts
            raise gnp.GnpError("fitness must be finite")
        if not (isinstance(learned, InBlock) and learned.records is self._block["learned"]):
            self._block["learned"][...] = learned.records  # learned outside this block
        self._block["fitness"][...] = fit
        self._run([EvolveJob(part, generation) for part in range(EVOLVE_PARTS)])
        return self.individuals().arrays()


def shared_evolution(
    evolution: Evolution, config: RunConfig, block: SharedArrays, run: RunJobs
) -> Evolution:
    """`evolution` moved into the block (a GNP population; another family's is left as it
    is)."""
    individuals = evolution.individuals()
    if not isinstance(individuals, Population):
        return evolution
    block["population"][...] = individuals.records
    return SharedEvolution(config, block, run)
