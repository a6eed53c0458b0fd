"""Training any brain family on a Gymnasium task, and replaying a trained individual.

Built on the lab's own pieces: the generation loop is the robot's
(`app.phases.generations.run_generations`, with `TaskLab` as the lab: lives in the task's
environments, generations in a task run file) and the population evolves as its family's
(`TaskRunConfig.family`: `first`, `advance`, `rebuild` of the brain contract; GNP's generation 0
drawn from (seed, init), evolved by `gnp.evolve` with the Generator of (seed, generation); a
net's optimiser drawing from its own stream): lives that learn online do so with the task's ε
and α, fixed or scheduled (NaN in the file for a family that does not learn online), and every
life's random inputs are keyed by (seed, generation, individual) (`app.loop.seeds.life_seeds`;
with `shared_episodes` every individual of a generation lives individual 0's episode). A run is
a function of its config and seed, and a resumed run matches one never interrupted.

The final elite (`elite_generation`) is the last generation's best, or with K =
`validation_episodes` > 1 the generation best (of every generation) whose mean return over K
validation episodes is the highest; it lives its episodes under the run's `test_protocol`
(`protocol_episodes`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from app.brains.contract import Evolution
from app.loop.seeds import life_seeds
from app.phases.generations import (
    Control,
    GenerationSummary,
    Interrupted,
    Lived,
    ProgressCallback,
    run_generations,
    stop_on_signals,
)
from app.store import RunFileError, RunWriter
from app.system.memory import COPIES, check_memory
from app.tasks.common import TaskError, is_task_run
from app.tasks.config import TaskRunConfig, TestProtocol
from app.tasks.faults import ObservationFault
from app.tasks.lives import BatchEnv, FaultPlan, TaskLives, batch_env, live
from app.tasks.store import read_task_run, task_run_config

# What callers of task training meet, imported from their rooms.
__all__ = [
    "GenerationSummary",
    "Interrupted",
    "elite_generation",
    "protocol_episodes",
    "resume_task",
    "train_task",
]


class TaskEvolution:
    """A family's evolution on a task: its own (`first`, `rebuild`), a generation's ε and α the
    task's (`TaskTraining.epsilon_alpha`) for a family that learns online, NaN for one that
    does not (as robot runs record them)."""

    def __init__(self, config: TaskRunConfig, evolution: Evolution) -> None:
        self._training, self._evolution = config.training, evolution
        self._learns = config.family.learns_online

    def epsilon_alpha(self, generation: int) -> tuple[float, float]:
        if not self._learns:
            return float("nan"), float("nan")
        return self._training.epsilon_alpha(generation)

    def individuals(self) -> Any:
        return self._evolution.individuals()

    def arrays(self, individuals: Any) -> dict[str, np.ndarray]:
        return self._evolution.arrays(individuals)

    def advance(self, learned: Any, fitness: np.ndarray, generation: int) -> dict[str, np.ndarray]:
        return self._evolution.advance(learned, fitness, generation)


def first_population(config: TaskRunConfig) -> Any:
    """Generation 0's individuals (the family's `first`)."""
    return config.family.first().individuals()


def generation_lives(
    config: TaskRunConfig,
    individuals: Any,
    generation: int,
    epsilon: float,
    alpha: float,
    env: BatchEnv | None = None,
) -> TaskLives:
    """The lives of `individuals` (generation `generation`) on the task."""
    family = config.family
    n = family.size(individuals)
    seeds = life_seeds(config.seed, generation, np.arange(n), 1, 1)
    world = np.full(n, seeds.world[0]) if config.training.shared_episodes else seeds.world
    own = env is None
    batch = batch_env(family, config.task.id, n, config.adapter) if env is None else env
    try:
        return live(
            family, config.adapter, batch, individuals, world, seeds.engine,
            epsilon, alpha, config.training.steps,
        )  # fmt: skip
    finally:
        if own:
            batch.close()


class TaskLab:
    """A task's lab for the one generation loop: lives in the task's environments (one batch
    env for the whole run), generations in its run file (a task run, `RunWriter`), a
    checkpoint every generation."""

    def __init__(self, writer: RunWriter, config: TaskRunConfig) -> None:
        self.writer, self.config = writer, config
        self.generations = config.training.generations
        self._env = batch_env(
            config.family, config.task.id, config.training.population, config.adapter
        )

    def live(self, individuals: Any, generation: int, epsilon: float, alpha: float) -> Lived:
        lives = generation_lives(self.config, individuals, generation, epsilon, alpha, self._env)
        return Lived(fitness=lives.returns, after=lives.learned, steps=int(lives.lengths.sum()))

    def write(
        self,
        generation: int,
        lived: Lived,
        epsilon: float,
        alpha: float,
        best_genome: dict[str, np.ndarray],
    ) -> None:
        self.writer.write_generation(
            generation,
            fitness=lived.fitness,
            epsilon=epsilon,
            alpha=alpha,
            best_genome=best_genome,
            env_steps=lived.steps,
        )

    def checkpoint(self, next_generation: int, arrays: dict[str, np.ndarray]) -> None:
        self.writer.write_checkpoint(next_generation, arrays)

    def last(self, individuals: Any, lived: Lived, epsilon: float, alpha: float) -> None:
        pass  # a task run keeps no elite's life

    def done(self, generations_done: int) -> None:
        self.writer.mark_done(generations_done)
        if generations_done == self.generations:
            self.writer.finish()

    def close(self) -> None:
        try:
            self._env.close()
        finally:
            self.writer.close()


def train_task(
    config: TaskRunConfig,
    out: str | Path,
    progress: ProgressCallback | None = None,
    control: Control | None = None,
) -> Path:
    """Train `config` into a new task run file `out`.

    Raises:
        TaskError: the task cannot be run by the brain family.
        RunFileError: `out` exists or cannot be created.
        Interrupted: Ctrl-C / SIGTERM / a stop; the file holds every complete generation.
    """
    family = config.family  # a bad task or brain fails before any file is made
    population = config.training.population
    check_memory(
        population * COPIES * individual_bytes(config), f"{population} individuals", TaskError
    )
    control = control or Control()
    with stop_on_signals(control):  # a stop before generation 0's checkpoint leaves no file
        evolution = TaskEvolution(config, family.first())
        template = replace(family.run_template(), task_config=config.model_dump_json())
        writer = RunWriter.create(out, template)
        try:
            writer.write_checkpoint(0, evolution.arrays(evolution.individuals()))
            writer.mark_done(0)
        except BaseException:  # Ctrl-C, a full disk: no file without its first checkpoint
            writer.close()
            Path(out).unlink(missing_ok=True)
            raise
        run_generations(TaskLab(writer, config), evolution, 0, progress, control)
    return writer.path


def resume_task(
    path: str | Path, progress: ProgressCallback | None = None, control: Control | None = None
) -> Path:
    """Continue an interrupted task run from its checkpoint (as `train_task`); a file of the old
    task run format is rewritten into the run format first (`RunWriter.resume`).

    Raises:
        RunFileError: not a resumable task run (a robot run, finished, no checkpoint).
    """
    if not is_task_run(path):
        raise RunFileError(f"{path} is not a task run")
    writer, generation, arrays = RunWriter.resume(path)
    try:
        assert writer.task_config is not None  # a task run's writer has it
        config = task_run_config(Path(path), writer.task_config)
        fitness = writer.fitness(generation)
        evolution = TaskEvolution(config, config.family.rebuild(generation, arrays, fitness))
    except BaseException:
        writer.close()
        raise
    lab = TaskLab(writer, config)
    run_generations(lab, evolution, generation, progress, control or Control())
    return writer.path


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
    `epsilon` is given (0: greedy; both unused by a family that does not learn online). Each
    episode is the one `replay_task` lives from its seed."""
    run = read_task_run(path)
    individual = run.best_individual(generation)
    g = run.generation_done - 1 if generation is None else generation
    config = run.config
    family, adapter = config.family, config.adapter
    n = len(seeds)
    plan = FaultPlan(faults, tuple(int(s) for s in seeds)) if faults else None
    env = batch_env(family, config.task.id, n, adapter, plan)
    eps = float(run.epsilon[g]) if epsilon is None else epsilon
    clones = family.copies(individual, n)
    try:
        return live(
            family, adapter, env, clones, seeds, seeds, eps, float(run.alpha[g]),
            config.training.steps, learn,
        )  # fmt: skip
    finally:
        env.close()


def protocol_episodes(
    path: str | Path, seeds: Sequence[int], generation: int | None, protocol: TestProtocol
) -> TaskLives:
    """`replay_episodes` of a generation's best under a test protocol: "as-trained" (its
    generation's ε and α, Sarsa on) or "greedy" (ε = 0, Sarsa frozen, so α does nothing); the
    same lives for a family that does not learn online."""
    if protocol == "greedy":
        return replay_episodes(path, seeds, generation, learn=False, epsilon=0.0)
    return replay_episodes(path, seeds, generation)


_VALIDATION_TAG = 0x76616C69  # "vali": the validation seeds' own stream


def validation_seeds(seed: int, episodes: int) -> tuple[int, ...]:
    """The K validation episode seeds of a run, keyed by its seed: in 2^31..2^32 − 1, so never a
    task experiment's test seed (below 2^31) and, but by a chance of 2^−31 each, never a
    training episode's (`life_seeds` draws those in 0..2^63 − 1)."""
    states = np.random.SeedSequence([seed, _VALIDATION_TAG]).generate_state(episodes, np.uint32)
    return tuple(int(s) | 2**31 for s in states)


def elite_generation(path: str | Path) -> int:
    """The generation whose best is the run's final elite: the last, or with K =
    `validation_episodes` > 1 the one whose best has the highest mean return over the run's K
    validation episodes under its `test_protocol` (the latest of equal means)."""
    run = read_task_run(path)
    training = run.config.training
    last = run.generation_done - 1
    if training.validation_episodes <= 1 or last < 0:
        return last
    seeds = validation_seeds(run.config.seed, training.validation_episodes)
    means = [
        float(np.mean(protocol_episodes(path, seeds, g, training.test_protocol).returns))
        for g in range(run.generation_done)
    ]
    return max(range(len(means)), key=lambda g: (means[g], g))


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


EPISODE_BYTES = 64 * 1024
"""Memory an episode of a replayed batch takes beside its clone: its environment and records
(a generous bound for the classic-control tasks)."""


def individual_bytes(config: TaskRunConfig) -> int:
    """Bytes of one individual's arrays (its family's `genome_layout`: GNP's genome and Q
    tables, a net's weights)."""
    layout = config.family.genome_layout
    return sum(int(np.prod(shape)) * np.dtype(dtype).itemsize for shape, dtype in layout.values())


def check_episodes_memory(config: TaskRunConfig, episodes: int) -> None:
    """Refuse replaying `episodes` episodes at once if their clones and environments cannot be
    held in this machine's memory.

    Raises:
        TaskError: one line giving the memory needed and available.
    """
    needed = episodes * (individual_bytes(config) + EPISODE_BYTES)
    check_memory(needed, f"{episodes} episodes at once", TaskError)
