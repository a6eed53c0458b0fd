"""The training phase: generations of evaluate-then-evolve, split over persistent workers.

Every random draw of an individual's life (its start poses, the world's noise stream, the
controller's stream) comes from a `numpy.random.SeedSequence` keyed by (run seed, generation,
individual index), and evolution's Generator from (run seed, generation). No draw depends on
where an individual sits in a batch, and individual i always lives at the same place of the
same world (a fixed split into shards, see `shards`), so a run gives bit-identical results on
any number of worker processes, and a resumed run matches one never interrupted.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any, Protocol

import numpy as np

import gnp
import sim
from app.arenas import arena_of
from app.config import CFrom, RunConfig, TrainingSettings
from app.recording import Trajectory, TrajectoryRecorder
from app.rollout import Batch, rollout
from app.seeds import LifeSeeds, evolution_rng, init_rng, life_seeds, n_segments
from app.store import (
    RunReader,
    RunTemplate,
    RunWriter,
)


class TrainingError(RuntimeError):
    """Training could not go on (a worker died, the run cannot start)."""


class Interrupted(Exception):
    """Training was stopped by Ctrl-C or SIGTERM after the last complete generation."""

    def __init__(self, generations_done: int) -> None:
        super().__init__(f"stopped after {generations_done} complete generation(s)")
        self.generations_done = generations_done


def initial_population(config: RunConfig) -> gnp.Population:
    """Generation 0, drawn from (seed, init)."""
    return gnp.init_population(
        config.controller.gnp_config(), config.training.population, init_rng(config.seed)
    )


# --- one batch of lives ---------------------------------------------------------------------


@dataclass(frozen=True)
class Lives:
    """Outcome of N lives: fitness (Eq. 2.8) and the mean per step of every reward term."""

    fitness: np.ndarray  # (N,)
    terms: np.ndarray  # (N, len(sim.TERM_NAMES))


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
    recorder = TrajectoryRecorder(pop.size, steps, cfg) if record else None
    outcome = rollout(
        batch,
        steps,
        epsilon,
        alpha,
        recorder=recorder,
        episode_starts=seeds.starts,
        redraw_every=redraw_every,
    )
    means = outcome.term_sums / steps
    lives = Lives(fitness=means[:, 0].copy(), terms=means)
    if recorder is None:
        return lives, None
    return lives, recorder.trajectory(seeds.starts[:, 0])


# --- evaluators: in-process or persistent worker processes ------------------------------------


class Evaluator(Protocol):
    def evaluate(
        self, pop: gnp.Population, seeds: LifeSeeds, epsilon: float, alpha: float
    ) -> tuple[Lives, gnp.Population]: ...

    def close(self) -> None: ...


def _make_world(config: RunConfig, n: int) -> sim.World:
    training = config.training
    return sim.World(
        arena_of(training.arena),
        n=n,
        seed=config.seed,
        noise_sigma=training.noise_sigma,
        control_period=training.control_period,
        physics=training.physics,
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


def _owned(training: TrainingSettings, workers: int) -> list[slice]:
    """The individuals each of `workers` workers lives: contiguous runs of whole shards."""
    parts = shards(training)
    bounds = np.linspace(0, len(parts), workers + 1).round().astype(int)
    return [slice(parts[a].start, parts[b - 1].stop) for a, b in itertools.pairwise(bounds)]


class _Lives:
    """The lives of a fixed set of individuals, in one persistent world (built on first use)."""

    def __init__(self, config: RunConfig) -> None:
        self._config = config
        self._cfg = config.controller.gnp_config()
        self._world: sim.World | None = None

    def run(
        self, pop: gnp.Population, seeds: LifeSeeds, epsilon: float, alpha: float
    ) -> tuple[Lives, gnp.Population]:
        """Lives of `pop` (left as it is); returns them with the population that learned."""
        if self._world is None:
            self._world = _make_world(self._config, pop.size)
        training = self._config.training
        learned = pop.copy()
        lives, _ = live(
            self._world,
            self._cfg,
            learned,
            seeds,
            training.steps,
            training.redraw_every,
            epsilon,
            alpha,
            c_from=self._config.reward.c_from,
        )
        return lives, learned


class LocalEvaluator:
    """Evaluates the whole population in this process, in one world."""

    def __init__(self, config: RunConfig) -> None:
        self._lives = _Lives(config)

    def evaluate(
        self, pop: gnp.Population, seeds: LifeSeeds, epsilon: float, alpha: float
    ) -> tuple[Lives, gnp.Population]:
        return self._lives.run(pop, seeds, epsilon, alpha)

    def close(self) -> None:
        pass


def serve_lives(conn: Connection, run: Callable[..., Any]) -> None:
    """A worker process's loop: live each job `conn` brings with `run`, until None arrives.

    Ctrl-C and SIGTERM reach the whole process group: the main process decides, and stops
    workers itself; a worker whose parent died sees its pipe close and exits.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    try:
        while True:
            job = conn.recv()
            if job is None:
                break
            conn.send(run(*job))
    except (EOFError, BrokenPipeError, KeyboardInterrupt):
        pass


def _worker_main(conn: Connection, config_json: str) -> None:
    serve_lives(conn, _Lives(RunConfig.model_validate_json(config_json)).run)


class ProcessEvaluator:
    """Persistent `spawn` worker processes, each living a contiguous run of shards in one world.

    Populations cross the pipes as themselves (their records, see `gnp.Population`): they are
    validated where they come from files, not on every hand-off.
    """

    def __init__(self, config: RunConfig, workers: int) -> None:
        self._owned = _owned(config.training, workers)
        context = multiprocessing.get_context("spawn")
        self._busy = False
        self._conns: list[Connection] = []
        self._procs: list[Any] = []
        for _ in self._owned:
            parent, child = context.Pipe()
            proc = context.Process(
                target=_worker_main, args=(child, config.model_dump_json()), daemon=True
            )
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)

    def evaluate(
        self, pop: gnp.Population, seeds: LifeSeeds, epsilon: float, alpha: float
    ) -> tuple[Lives, gnp.Population]:
        self._busy = True
        try:
            for conn, part in zip(self._conns, self._owned, strict=True):
                conn.send(
                    (
                        gnp.take(pop, np.arange(part.start, part.stop)),
                        seeds.take(part),
                        epsilon,
                        alpha,
                    )
                )
            results = [conn.recv() for conn in self._conns]
        except (EOFError, OSError):
            codes = [proc.exitcode for proc in self._procs]
            raise TrainingError(f"a worker process died (exit codes {codes})") from None
        self._busy = False
        lives = Lives(
            fitness=np.concatenate([r[0].fitness for r in results]),
            terms=np.concatenate([r[0].terms for r in results]),
        )
        return lives, gnp.concat([r[1] for r in results])

    def close(self) -> None:
        busy = self._busy  # interrupted mid-generation: the workers' results are not wanted
        for conn in self._conns:
            with contextlib.suppress(BrokenPipeError, OSError):
                conn.send(None)
        for proc in self._procs:
            proc.join(timeout=0 if busy else 5)
            if proc.is_alive():
                proc.kill()
                proc.join()
        for conn in self._conns:
            conn.close()


def make_evaluator(config: RunConfig, workers: int) -> Evaluator:
    """In-process for one worker, else persistent worker processes (at most one per shard)."""
    workers = max(1, min(workers, len(shards(config.training))))
    return LocalEvaluator(config) if workers == 1 else ProcessEvaluator(config, workers)


def default_workers() -> int:
    """One worker per core."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


# --- the loop -------------------------------------------------------------------------------


@dataclass(frozen=True)
class GenerationSummary:
    """What a progress display needs after each generation."""

    generation: int
    generations: int
    best_fitness: float
    mean_fitness: float
    seconds: float


ProgressCallback = Callable[[GenerationSummary], None]


_stop_requested = threading.Event()  # set by SIGTERM; a run stops at the next chance


@contextmanager
def _stop_on_sigterm() -> Iterator[None]:
    """Turn SIGTERM into KeyboardInterrupt (as Ctrl-C) while training, in the main thread.

    The request is also remembered: a KeyboardInterrupt raised while numba compiles can be
    swallowed inside llvmlite, and the loop then stops at the next generation all the same.
    """
    try:
        previous = signal.getsignal(signal.SIGTERM)

        def handler(signum: int, frame: Any) -> None:
            _stop_requested.set()
            raise KeyboardInterrupt

        signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def generation_epsilon_alpha(training: TrainingSettings, generation: int) -> tuple[float, float]:
    """(ε, α) of a generation: fixed, or Eq. 4.1-4.2."""
    eps_schedule, alpha_schedule = training.schedules()
    return gnp.epsilon_alpha_over_generations(
        eps_schedule, alpha_schedule, generation, training.generations, training.schedule_progress
    )


def _train_from(
    writer: RunWriter,
    start: int,
    pop: gnp.Population,
    workers: int,
    progress: ProgressCallback | None,
) -> None:
    config = writer.config
    training = config.training
    cfg = config.controller.gnp_config()
    arena = arena_of(training.arena)
    segments = n_segments(training.steps, training.redraw_every)
    everyone = np.arange(training.population)
    evaluator = make_evaluator(config, workers)
    done = start
    try:
        with _stop_on_sigterm():  # nested in train/resume's: also when called on its own
            for generation in range(start, training.generations):
                if _stop_requested.is_set():
                    raise KeyboardInterrupt
                began = time.perf_counter()
                epsilon, alpha = generation_epsilon_alpha(training, generation)
                seeds = life_seeds(
                    config.seed, generation, everyone, segments, len(arena.start_poses)
                )
                lives, learned = evaluator.evaluate(pop, seeds, epsilon, alpha)
                best = int(np.argmax(lives.fitness))
                writer.write_generation(
                    generation,
                    fitness=lives.fitness,
                    best_terms=dict(zip(sim.TERM_NAMES, lives.terms[best], strict=True)),
                    mean_terms=dict(zip(sim.TERM_NAMES, lives.terms.mean(axis=0), strict=True)),
                    epsilon=epsilon,
                    alpha=alpha,
                    best_genome=gnp.population_to_arrays(gnp.take(learned, [best])),
                )
                last = generation + 1 == training.generations
                if last:
                    elite_life = _replay(config, cfg, pop, best, seeds, epsilon, alpha)
                else:
                    pop_next = gnp.evolve(
                        cfg,
                        learned,
                        lives.fitness,
                        generation,
                        training.generations,
                        evolution_rng(config.seed, generation),
                        config.evolution,
                    )
                    if (generation + 1) % training.checkpoint_every == 0:
                        writer.write_checkpoint(generation + 1, gnp.population_to_arrays(pop_next))
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
                    writer.write_elite(generation, elite_life)
                else:
                    pop = pop_next
    except KeyboardInterrupt:
        raise Interrupted(done) from None
    finally:
        evaluator.close()
        writer.close()


def _replay(
    config: RunConfig,
    cfg: gnp.GnpConfig,
    pop: gnp.Population,
    best: int,
    seeds: LifeSeeds,
    epsilon: float,
    alpha: float,
) -> Trajectory:
    """Live the best individual's evaluation again, recording it. Alone in a world of its own
    it lives the same life as in its worker's world, bit for bit (lives do not depend on
    their world's other robots)."""
    training = config.training
    _, trajectory = live(
        _make_world(config, 1),
        cfg,
        gnp.take(pop, [best]),
        seeds.take(slice(best, best + 1)),
        training.steps,
        training.redraw_every,
        epsilon,
        alpha,
        record=True,
        c_from=config.reward.c_from,
    )
    assert trajectory is not None
    return trajectory


def run_template(config: RunConfig) -> RunTemplate:
    """The shapes and dtypes a run file of this config needs: one individual's genome and
    one step's trace of one controller."""
    cfg = config.controller.gnp_config()
    genome = {
        name: np.zeros((1, *shape), gnp.field_dtype(name))
        for name, shape in gnp.field_shapes(cfg).items()
    }
    trace = {
        name: np.zeros((1, *shape), gnp.TRACE_DTYPE)
        for name, shape in gnp.trace_shapes(cfg).items()
    }
    return RunTemplate(config=config, genome=genome, trace=trace)


def train(
    config: RunConfig,
    out: str | Path,
    *,
    workers: int = 1,
    progress: ProgressCallback | None = None,
) -> Path:
    """Run the training phase of `config` into a new run file `out`.

    Raises:
        RunFileError: `out` exists or cannot be created.
        Interrupted: Ctrl-C / SIGTERM; the file holds every completed generation.
        TrainingError: a worker process died.
    """
    if config.neuro is not None:  # a neural brain (CMA-ES, NEAT): app.neuro_training
        from app.neuro_training import train_neural

        return train_neural(config, out, workers=workers, progress=progress)
    arena_of(config.training.arena)  # fail on a bad arena before creating the file
    _stop_requested.clear()
    # SIGTERM stops training from the start: a stop before generation 0's checkpoint is in
    # the file leaves no file (KeyboardInterrupt), after it a resumable one (Interrupted).
    with _stop_on_sigterm():
        pop = initial_population(config)
        writer = RunWriter.create(out, run_template(config))
        try:
            writer.write_checkpoint(0, gnp.population_to_arrays(pop))
            writer.mark_done(0)
        except BaseException:  # Ctrl-C, a full disk: a file without its first checkpoint
            writer.close()
            Path(out).unlink(missing_ok=True)
            raise
        _train_from(writer, 0, pop, workers, progress)
    return writer.path


def resume(path: str | Path, *, workers: int = 1, progress: ProgressCallback | None = None) -> Path:
    """Continue an interrupted run from its last checkpoint; the result matches an
    uninterrupted run of the same config and seed.

    Raises:
        RunFileError: not a resumable run.
    """
    with RunReader(path) as run:
        neural = run.config.neuro is not None
    if neural:
        from app.neuro_training import resume_neural

        return resume_neural(path, workers=workers, progress=progress)
    _stop_requested.clear()
    with _stop_on_sigterm():
        writer, generation, arrays = RunWriter.resume(path)
        try:
            pop = gnp.population_from_arrays(writer.config.controller.gnp_config(), arrays)
        except KeyboardInterrupt:
            writer.close()
            raise Interrupted(generation) from None
        _train_from(writer, generation, pop, workers, progress)
    return writer.path
