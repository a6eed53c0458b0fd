"""Training GNP on a Gymnasium task, and replaying a trained individual.

The same generation as the robot's (`app.phases.training`): generation 0 drawn from (seed, init),
lives that learn online with ε and α fixed or scheduled, the learned population evolved by
`gnp.evolve` with the Generator of (seed, generation), every life's random inputs keyed by
(seed, generation, individual) (`app.loop.seeds.life_seeds`). A run is a function of its config
and seed, and a resumed run matches one never interrupted.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import gnp
from app.loop.seeds import evolution_rng, init_rng, life_seeds
from app.tasks.config import TaskRunConfig
from app.tasks.faults import ObservationFault
from app.tasks.lives import BatchEnv, FaultPlan, TaskLives, live
from app.tasks.store import TaskRunWriter, read_task_run


@dataclass(frozen=True)
class TaskGeneration:
    """What a progress display needs after each generation."""

    generation: int
    generations: int
    best_return: float
    mean_return: float
    env_steps: int
    seconds: float


TaskProgress = Callable[[TaskGeneration], None]


def first_population(config: TaskRunConfig) -> gnp.Population:
    """Generation 0, drawn from (seed, init)."""
    return gnp.init_population(
        config.gnp_config(), config.training.population, init_rng(config.seed)
    )


def generation_lives(
    config: TaskRunConfig, pop: gnp.Population, generation: int, env: BatchEnv | None = None
) -> TaskLives:
    """The lives of `pop` (generation `generation`) on the task."""
    cfg = config.gnp_config()
    adapter = config.adapter
    n = pop.size
    seeds = life_seeds(config.seed, generation, np.arange(n), 1, 1)
    epsilon, alpha = config.training.epsilon_alpha(generation)
    own = env is None
    batch = BatchEnv(config.task.id, n, adapter) if env is None else env
    try:
        return live(
            cfg, adapter, batch, pop, seeds.world, seeds.engine, epsilon, alpha,
            config.training.steps,
        )  # fmt: skip
    finally:
        if own:
            batch.close()


def _run(
    writer: TaskRunWriter, pop: gnp.Population, start: int, progress: TaskProgress | None
) -> Path:
    config = writer.config
    training = config.training
    cfg = config.gnp_config()
    env = BatchEnv(config.task.id, training.population, config.adapter)
    try:
        for generation in range(start, training.generations):
            began = time.perf_counter()
            lives = generation_lives(config, pop, generation, env)
            best = int(np.argmax(lives.returns))
            epsilon, alpha = training.epsilon_alpha(generation)
            writer.write_generation(
                generation,
                lives.returns,
                epsilon,
                alpha,
                gnp.population_to_arrays(gnp.take(lives.learned, [best])),
            )
            if generation + 1 < training.generations:
                pop = gnp.evolve(
                    cfg,
                    lives.learned,
                    lives.returns,
                    generation,
                    training.generations,
                    evolution_rng(config.seed, generation),
                    config.evolution,
                )
                writer.write_checkpoint(generation + 1, gnp.population_to_arrays(pop))
            writer.mark_done(generation + 1)
            if progress is not None:
                progress(
                    TaskGeneration(
                        generation=generation,
                        generations=training.generations,
                        best_return=float(lives.returns[best]),
                        mean_return=float(lives.returns.mean()),
                        env_steps=int(lives.lengths.sum()),
                        seconds=time.perf_counter() - began,
                    )
                )
    finally:
        env.close()
        writer.close()
    return writer.path


def train_task(
    config: TaskRunConfig, out: str | Path, progress: TaskProgress | None = None
) -> Path:
    """Train `config` into a new task run file `out`.

    Raises:
        TaskError: the task cannot be run by GNP.
        RunFileError: `out` exists or cannot be created.
    """
    config.gnp_config()  # a bad task fails before any file is made
    pop = first_population(config)
    writer = TaskRunWriter.create(out, config)
    try:
        writer.write_checkpoint(0, gnp.population_to_arrays(pop))
        writer.mark_done(0)
    except BaseException:  # Ctrl-C, a full disk: no file without its first checkpoint
        writer.close()
        Path(out).unlink(missing_ok=True)
        raise
    return _run(writer, pop, 0, progress)


def resume_task(path: str | Path, progress: TaskProgress | None = None) -> Path:
    """Continue an interrupted task run from its checkpoint."""
    writer, generation, arrays = TaskRunWriter.resume(path)
    pop = gnp.population_from_arrays(writer.config.gnp_config(), arrays)
    return _run(writer, pop, generation, progress)


@dataclass(frozen=True)
class Replay:
    """One replayed episode: its return and length."""

    episode_return: float
    length: int


def replay_episodes(
    path: str | Path,
    seeds: Sequence[int],
    generation: int | None = None,
    faults: tuple[ObservationFault, ...] = (),
    learn: bool = True,
    epsilon: float | None = None,
) -> TaskLives:
    """Live a generation's best individual (default: the last) again, one episode per seed, all
    at once (a clone per seed): episode i starts from `seeds[i]`, which also seeds its
    controller's stream and its faults' `random` draws. ε and α are the generation's unless
    `epsilon` is given (0: greedy). Each episode is the one `replay_task` lives from its seed."""
    run = read_task_run(path)
    cfg, individual = run.best_genome(generation)
    g = run.generation_done - 1 if generation is None else generation
    config = run.config
    adapter = config.adapter
    n = len(seeds)
    plan = FaultPlan(faults, tuple(int(s) for s in seeds)) if faults else None
    env = BatchEnv(config.task.id, n, adapter, plan)
    eps = float(run.epsilon[g]) if epsilon is None else epsilon
    clones = gnp.take(individual, np.zeros(n, np.intp))
    try:
        return live(
            cfg, adapter, env, clones, seeds, seeds, eps, float(run.alpha[g]),
            config.training.steps, learn,
        )  # fmt: skip
    finally:
        env.close()


def replay_task(
    path: str | Path,
    seed: int,
    generation: int | None = None,
    faults: tuple[ObservationFault, ...] = (),
    learn: bool = True,
    epsilon: float | None = None,
) -> Replay:
    """One episode of `replay_episodes`, from `seed`."""
    lives = replay_episodes(path, [seed], generation, faults, learn, epsilon)
    return Replay(float(lives.returns[0]), int(lives.lengths[0]))
