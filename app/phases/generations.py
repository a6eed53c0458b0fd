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

import contextlib
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

import sim
from app.brains.contract import Evolution
from app.phases.evaluation import Evaluator, nothing
from app.phases.evaluation import TrainingError as TrainingError  # where callers find it
from app.phases.lives import ShardLives
from app.phases.shared_lives import InBlock
from app.settings.arenas import arena_of
from app.settings.config import RunConfig
from app.store import RunFileError, RunReader, RunTemplate, RunWriter
from app.system.signals import Stopped, interrupted_by_signals, raise_interrupt


class Interrupted(Stopped):
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
    steps: int = 0  # steps lived: robot-steps, or a task's env-steps


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
    compiles can be swallowed inside llvmlite, and the loop then stops at the next generation
    (or, should the compiler fail in its place, its error is raised as KeyboardInterrupt).
    """

    def handler(signum: int, frame: Any) -> None:
        control.stopping.set()
        raise_interrupt(signum, frame)

    with interrupted_by_signals(handler):
        yield


# --- the loop -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Lived:
    """A generation's lives: fitness, the individuals after them (what they learned), what the
    run file keeps beside the fitness (`details`), and the steps they took."""

    fitness: np.ndarray  # (N,)
    after: Any
    details: Any = None
    steps: int = 0


class Lab(Protocol):
    """Where a run's generations are lived and written: the robot's worlds and run file
    (`RobotLab`), or a Gymnasium task's environments and task run file (`app.tasks`)."""

    generations: int

    def live(self, individuals: Any, generation: int, epsilon: float, alpha: float) -> Lived:
        """The lives of a generation's individuals (left as they are)."""
        ...

    def write(
        self,
        generation: int,
        lived: Lived,
        epsilon: float,
        alpha: float,
        best_genome: dict[str, np.ndarray],
    ) -> None:
        """Record a lived generation (not yet counted as done)."""
        ...

    def checkpoint(self, next_generation: int, arrays: dict[str, np.ndarray]) -> None:
        """The population `next_generation` starts from (the lab keeps it when it should)."""
        ...

    def last(self, individuals: Any, lived: Lived, epsilon: float, alpha: float) -> None:
        """After the last generation is written, before it is counted: what the lab keeps of
        the run's end (the robot: the final elite's life, re-lived and recorded)."""
        ...

    def done(self, generations_done: int) -> None:
        """Count the generations written as done; after the last one, its end is written."""
        ...

    def close(self) -> None: ...


def run_generations(
    lab: Lab,
    evolution: Evolution,
    start: int,
    progress: ProgressCallback | None,
    control: Control,
) -> None:
    """Generations `start`… of a run, for any brain family and either lab; closes the lab.

    A generation's records, the checkpoint of the next one and its count as done are written
    while the workers live the next generation (the robot's lab, `RobotLab`), so the file
    costs the workers no waiting; a stop, a pause or an error writes them before it takes
    effect, so the file holds every generation lived to its end, as before.

    Raises:
        Interrupted: a stop (Ctrl-C, SIGTERM, `control.stop`); the file holds every complete
            generation.
        TrainingError: a worker died.
    """
    done = start
    pending: Callable[[], None] | None = None  # a lived generation's writes, not yet made

    def flush() -> None:
        nonlocal pending
        if pending is not None:
            pending()  # idempotent: cut short, it writes the same rows again
            pending = None

    try:
        with stop_on_signals(control):  # nested in start/resume's: also when called on its own
            for generation in range(start, lab.generations):
                overlaps = isinstance(lab, RobotLab)
                if not overlaps or control.stopping.is_set() or not control.running.is_set():
                    flush()  # the file is complete before the run stops or waits
                control.checkpoint()
                began = time.perf_counter()
                epsilon, alpha = evolution.epsilon_alpha(generation)
                individuals = evolution.individuals()
                if isinstance(lab, RobotLab):
                    lived = lab.live(individuals, generation, epsilon, alpha, meanwhile=flush)
                else:
                    lived = lab.live(individuals, generation, epsilon, alpha)
                best = int(np.argmax(lived.fitness))
                stored = evolution.arrays(lived.after)
                # copied: with a shared block, the next generation's lives write over `stored`
                best_genome = {n: rows[best : best + 1].copy() for n, rows in stored.items()}
                if generation + 1 == lab.generations:
                    lab.write(generation, lived, epsilon, alpha, best_genome)
                    lab.last(individuals, lived, epsilon, alpha)
                    lab.done(generation + 1)
                    done = generation + 1
                    _report(progress, lab, generation, lived, best, began)
                    break
                arrays = evolution.advance(lived.after, lived.fitness, generation)

                def write(
                    generation: int = generation,
                    lived: Lived = lived,
                    params: tuple[float, float] = (epsilon, alpha),
                    best_genome: dict[str, np.ndarray] = best_genome,
                    arrays: dict[str, np.ndarray] = arrays,
                    best: int = best,
                    began: float = began,
                ) -> None:
                    nonlocal done
                    lab.write(generation, lived, *params, best_genome)
                    lab.checkpoint(generation + 1, arrays)
                    lab.done(generation + 1)
                    done = generation + 1
                    _report(progress, lab, generation, lived, best, began)

                pending = write
            flush()  # a run of no generation left (resumed at its end) has none
    except KeyboardInterrupt:
        with contextlib.suppress(KeyboardInterrupt):  # a second Ctrl-C: the file as it is
            flush()
        raise Interrupted(done) from None
    except BaseException:
        with contextlib.suppress(Exception):  # the error that stopped the run is the one told
            flush()
        raise
    finally:
        lab.close()


def _report(
    progress: ProgressCallback | None,
    lab: Lab,
    generation: int,
    lived: Lived,
    best: int,
    began: float,
) -> None:
    if progress is not None:
        progress(
            GenerationSummary(
                generation=generation,
                generations=lab.generations,
                best_fitness=float(lived.fitness[best]),
                mean_fitness=float(lived.fitness.mean()),
                seconds=time.perf_counter() - began,
                steps=lived.steps,
            )
        )


class RobotLab:
    """The robot's lab: lives in the arena's worlds (`Evaluator`: this process or the worker
    pool), generations in a run file; the final elite re-lived alone and recorded. Alone in a
    world of its own it lives the same life as in its worker's world, bit for bit (lives do not
    depend on their world's other robots)."""

    def __init__(self, writer: RunWriter, evaluator: Evaluator) -> None:
        self.writer, self.evaluator = writer, evaluator
        self.config = writer.config
        self.generations = self.config.training.generations
        self._generation = -1
        self._elite: Any = None

    def live(
        self,
        individuals: Any,
        generation: int,
        epsilon: float,
        alpha: float,
        meanwhile: Callable[[], None] = nothing,
    ) -> Lived:
        """As `Lab.live`; `meanwhile()` is called while the workers live them."""
        training = self.config.training
        self._generation = generation
        lives, after = self.evaluator.evaluate_generation(
            individuals, generation, epsilon, alpha, meanwhile
        )
        steps = training.population * training.steps
        return Lived(fitness=lives.fitness, after=after, details=lives.terms, steps=steps)

    def write(
        self,
        generation: int,
        lived: Lived,
        epsilon: float,
        alpha: float,
        best_genome: dict[str, np.ndarray],
    ) -> None:
        best = int(np.argmax(lived.fitness))
        terms = lived.details
        self.writer.write_generation(
            generation,
            fitness=lived.fitness,
            best_terms=dict(zip(sim.TERM_NAMES, terms[best], strict=True)),
            mean_terms=dict(zip(sim.TERM_NAMES, terms.mean(axis=0), strict=True)),
            epsilon=epsilon,
            alpha=alpha,
            best_genome=best_genome,
        )

    def checkpoint(self, next_generation: int, arrays: dict[str, np.ndarray]) -> None:
        if next_generation % self.config.training.checkpoint_every == 0:
            self.writer.write_checkpoint(next_generation, arrays)

    def last(self, individuals: Any, lived: Lived, epsilon: float, alpha: float) -> None:
        best = int(np.argmax(lived.fitness))
        alone = ShardLives(self.config)
        seeds = self.evaluator.seeds(self._generation, np.array([best]))  # keyed by individual
        if isinstance(individuals, InBlock):
            the_best = individuals.take([best])
        else:
            the_best = alone.family.take(individuals, [best])
        _, _, trajectory = alone.run(the_best, seeds, epsilon, alpha, True)
        assert trajectory is not None
        self._elite = (best, trajectory)

    def done(self, generations_done: int) -> None:
        self.writer.mark_done(generations_done)
        if generations_done == self.generations and self._elite is not None:
            self.writer.write_elite(generations_done - 1, self._elite[1])

    def close(self) -> None:
        self.writer.close()


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
        run_generations(RobotLab(writer, evaluator), evaluator.adopt(brain), 0, progress, control)
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
        lab = RobotLab(writer, evaluator)
        run_generations(lab, evaluator.adopt(brain), generation, progress, control)
    return writer.path
