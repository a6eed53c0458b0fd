"""The training phase's one loop: generations of evaluate-then-evolve, for every brain family.

Each generation lives the population (`Evaluator`: in this process, or split over the worker
pool by fixed shards), writes its fitness and best genome, then asks the brain for the next
generation (GNP evolves the learned population; an optimiser is told the fitness) and
checkpoints it. What differs by family sits behind the brain contract (`app.brains`); the file,
the checkpoints, the resume, the elite's replay, the stop and pause are here, once.

Every random draw of an individual's life comes from `app.loop.seeds.life_seeds` (run seed,
generation, individual), and individual i always lives at the same place of the same world, so
a run gives bit-identical results on any number of workers, and a resumed run matches one never
interrupted.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import sim
from app.brains.contract import Evolution
from app.brains.registry import family_of
from app.loop.seeds import LifeSeeds, life_seeds, n_segments
from app.phases.lives import Lives, ShardLives, concat_lives, owned, shards
from app.settings.arenas import arena_of
from app.settings.config import RunConfig
from app.store import RunFileError, RunReader, RunTemplate, RunWriter
from app.system.workers import Handler, WorkerDied, WorkerPool, handling


class TrainingError(RuntimeError):
    """Training could not go on (a worker died, the run cannot start)."""


class Interrupted(Exception):
    """Training was stopped by Ctrl-C or SIGTERM after the last complete generation."""

    def __init__(self, generations_done: int) -> None:
        super().__init__(f"stopped after {generations_done} complete generation(s)")
        self.generations_done = generations_done


@dataclass(frozen=True)
class GenerationSummary:
    """What a progress display needs after each generation."""

    generation: int
    generations: int
    best_fitness: float
    mean_fitness: float
    seconds: float


ProgressCallback = Callable[[GenerationSummary], None]


# --- stop and pause -------------------------------------------------------------------------


@dataclass
class Control:
    """Stop and pause requests, read between generations (a run stops after a complete one).

    The CLI's run is stopped by Ctrl-C or SIGTERM (`stop_on_signals`: the main thread's signal
    sets `stopping` and raises KeyboardInterrupt); the dashboard's, run in a thread, by `stop`
    and `pause` here.
    """

    stopping: threading.Event = field(default_factory=threading.Event)
    running: threading.Event = field(default_factory=threading.Event)  # cleared: paused
    held: threading.Event = field(default_factory=threading.Event)  # set: waiting, paused

    def __post_init__(self) -> None:
        self.running.set()

    def stop(self) -> None:
        self.stopping.set()
        self.running.set()  # a paused run wakes up to stop

    def pause(self) -> None:
        """Hold the run before its next generation; nothing once a stop is asked for (the
        run stops rather than waits)."""
        if not self.stopping.is_set():
            self.running.clear()

    def resume(self) -> None:
        self.running.set()

    def checkpoint(self) -> None:
        """KeyboardInterrupt once a stop is asked for (before, or while, waiting paused)."""
        if self.stopping.is_set():
            raise KeyboardInterrupt
        if not self.running.is_set():
            self.held.set()
            self.running.wait()
            self.held.clear()
        if self.stopping.is_set():
            raise KeyboardInterrupt


@contextmanager
def stop_on_signals(control: Control) -> Iterator[None]:
    """Ctrl-C (SIGINT) and SIGTERM stop training: each raises KeyboardInterrupt, as Python's
    own SIGINT handler does, in the main thread (elsewhere signals are left alone).

    The request is also remembered in `control`: a KeyboardInterrupt raised while numba
    compiles can be swallowed inside llvmlite, and the loop then stops at the next generation.
    """

    def handler(signum: int, frame: Any) -> None:
        control.stopping.set()
        raise KeyboardInterrupt

    with handling(signal.SIGINT, handler), handling(signal.SIGTERM, handler):
        yield


# --- evaluation: in this process or on the worker pool ----------------------------------------


def _shard_worker(config_json: str) -> Handler:
    """A pool worker's state: the lives of its shards, in one persistent world."""
    lives = ShardLives(RunConfig.model_validate_json(config_json))

    def handle(job: tuple[Any, LifeSeeds, float, float], count: Any) -> tuple[Lives, Any]:
        individuals, seeds, epsilon, alpha = job
        result, after, _ = lives.run(individuals, seeds, epsilon, alpha, False)
        # Nets do not learn: they come back as they went (None), not piped back unchanged.
        return result, None if after is individuals else after

    return handle


class Evaluator:
    """Lives a generation: in this process (one worker, `local`), else on a pool of `workers`
    processes (at most one per shard), each owning a contiguous run of whole shards.

    `stopping`, when set, drops the generation under way (KeyboardInterrupt).
    """

    def __init__(
        self,
        config: RunConfig,
        workers: int,
        local: bool = True,
        stopping: threading.Event | None = None,
    ) -> None:
        self._local: ShardLives | None = None
        self._pool: WorkerPool | None = None
        self._stopping = stopping
        self.family = family_of(config)
        workers = max(1, min(workers, len(shards(config.training))))
        if workers == 1 and local:
            self._local = ShardLives(config)
            return
        self._owned = owned(config.training, workers)
        self._pool = WorkerPool(workers, _shard_worker, (config.model_dump_json(),))

    def evaluate(
        self, individuals: Any, seeds: LifeSeeds, epsilon: float, alpha: float
    ) -> tuple[Lives, Any]:
        """The lives of `individuals` (left as they are) and the individuals after them."""
        if self._local is not None:
            lives, after, _ = self._local.run(individuals, seeds, epsilon, alpha, False)
            return lives, after
        assert self._pool is not None
        family = self.family
        jobs = [
            (family.take(individuals, np.arange(part.start, part.stop)), seeds.take(part),
             epsilon, alpha)
            for part in self._owned
        ]  # fmt: skip
        stopping = self._stopping
        try:
            results = self._pool.map(jobs, stopping.is_set if stopping is not None else None)
        except WorkerDied as error:
            raise TrainingError(str(error)) from None
        afters = [r[1] for r in results]
        after = individuals if afters[0] is None else family.concat(afters)  # None: unchanged
        return concat_lives([r[0] for r in results]), after

    def close(self) -> None:
        if self._pool is not None:
            self._pool.close()

    def __enter__(self) -> Evaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --- the loop -------------------------------------------------------------------------------


def _elite(
    config: RunConfig, individuals: Any, best: int, seeds: LifeSeeds, epsilon: float, alpha: float
) -> Any:
    """Live the best individual's evaluation again, recording it. Alone in a world of its own
    it lives the same life as in its worker's world, bit for bit (lives do not depend on
    their world's other robots)."""
    alone = ShardLives(config)
    one = slice(best, best + 1)
    the_best = alone.family.take(individuals, [best])
    _, _, trajectory = alone.run(the_best, seeds.take(one), epsilon, alpha, True)
    assert trajectory is not None
    return trajectory


def run_generations(
    writer: RunWriter,
    brain: Evolution,
    start: int,
    evaluator: Evaluator,
    progress: ProgressCallback | None,
    control: Control,
) -> None:
    """Generations `start`… of `writer`'s run; closes the writer.

    Raises:
        Interrupted: a stop (Ctrl-C, SIGTERM, `control.stop`); the file holds every complete
            generation.
        TrainingError: a worker died.
    """
    config = writer.config
    training = config.training
    n_starts = len(arena_of(training.arena).start_poses)
    segments = n_segments(training.steps, training.redraw_every)
    everyone = np.arange(training.population)
    done = start
    try:
        with stop_on_signals(control):  # nested in start/resume's: also when called on its own
            for generation in range(start, training.generations):
                control.checkpoint()
                began = time.perf_counter()
                epsilon, alpha = brain.epsilon_alpha(generation)
                individuals = brain.individuals()
                seeds = life_seeds(config.seed, generation, everyone, segments, n_starts)
                lives, after = evaluator.evaluate(individuals, seeds, epsilon, alpha)
                best = int(np.argmax(lives.fitness))
                writer.write_generation(
                    generation,
                    fitness=lives.fitness,
                    best_terms=dict(zip(sim.TERM_NAMES, lives.terms[best], strict=True)),
                    mean_terms=dict(zip(sim.TERM_NAMES, lives.terms.mean(axis=0), strict=True)),
                    epsilon=epsilon,
                    alpha=alpha,
                    best_genome=brain.arrays(evaluator.family.take(after, [best])),
                )
                last = generation + 1 == training.generations
                if last:
                    elite = _elite(config, individuals, best, seeds, epsilon, alpha)
                else:
                    arrays = brain.advance(after, lives.fitness, generation)
                    if (generation + 1) % training.checkpoint_every == 0:
                        writer.write_checkpoint(generation + 1, arrays)
                writer.mark_done(generation + 1)
                done = generation + 1
                if progress is not None:
                    progress(
                        GenerationSummary(
                            generation=generation,
                            generations=training.generations,
                            best_fitness=float(lives.fitness[best]),
                            mean_fitness=float(lives.fitness.mean()),
                            seconds=time.perf_counter() - began,
                        )
                    )
                if last:
                    writer.write_elite(generation, elite)
    except KeyboardInterrupt:
        raise Interrupted(done) from None
    finally:
        writer.close()


def start_run(
    config: RunConfig,
    out: str | Path,
    template: RunTemplate,
    first: Callable[[], Evolution],
    workers: int,
    local: bool,
    progress: ProgressCallback | None,
    control: Control | None = None,
) -> Path:
    """A new run file `out` of `config`: generation 0 from `first()`, then every
    generation (see `app.phases.training.train`)."""
    arena_of(config.training.arena)  # fail on a bad arena before creating the file
    control = control or Control()
    # Ctrl-C and SIGTERM stop training from the start: a stop before generation 0's checkpoint is in
    # the file leaves no file (KeyboardInterrupt), after it a resumable one (Interrupted).
    # The workers start before any file is open: a forked one holds none of this process's
    # (if the file cannot be created, those never given a job are killed at once on close).
    with (
        stop_on_signals(control),
        Evaluator(config, workers, local, control.stopping) as evaluator,
    ):
        brain = first()
        writer = RunWriter.create(out, template)
        try:
            writer.write_checkpoint(0, brain.arrays(brain.individuals()))
            writer.mark_done(0)
        except BaseException:  # Ctrl-C, a full disk: a file without its first checkpoint
            writer.close()
            Path(out).unlink(missing_ok=True)
            raise
        run_generations(writer, brain, 0, evaluator, progress, control)
    return writer.path


Rebuild = Callable[[int, dict[str, np.ndarray], np.ndarray], Evolution]
"""A population from a checkpoint: (generation, its arrays, the fitness of the generations
before it) → the population at that generation. Raises RunFileError when it cannot be rebuilt."""


def resume_run(
    path: str | Path,
    rebuild: Rebuild,
    workers: int,
    local: bool,
    progress: ProgressCallback | None,
    control: Control | None = None,
) -> Path:
    """Continue `path` from its last checkpoint (see `app.phases.training.resume`)."""
    control = control or Control()
    with RunReader(path) as run:
        config, fitness = run.config, run.history().fitness
    with (
        stop_on_signals(control),
        Evaluator(config, workers, local, control.stopping) as evaluator,
    ):
        writer, generation, arrays = RunWriter.resume(path)
        try:
            brain = rebuild(generation, arrays, fitness[:generation])
        except KeyboardInterrupt:
            writer.close()
            raise Interrupted(generation) from None
        except RunFileError as error:
            writer.close()
            raise RunFileError(f"{Path(path).name}: {error}") from None
        except BaseException:
            writer.close()
            raise
        run_generations(writer, brain, generation, evaluator, progress, control)
    return writer.path
