"""Training a neural brain (CMA-ES on an Elman net, or NEAT) into the same run files as GNP.

The lab is the GNP arm's: the same lives (`app.seeds.life_seeds`: start poses, noise streams),
fitness (Eq. 2.8, mean reward per step), arena, life time and budget in robot-steps (population ×
generations × steps, the optimiser's population being `training.population`). The optimiser
draws from a stream of its own (`app.seeds.optimiser_seed`); its state is a function of that
seed and of the fitness table the file holds, so a resume rebuilds it by replaying the told
fitness (no pickles) and checks it against the checkpointed population, bit for bit.
Individual i always lives at the same place of the same world (`app.training.shards`), so
results do not depend on the number of workers.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import time
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any, Protocol

import numpy as np

import neuro
import sim
from app.arenas import arena_of
from app.config import RunConfig
from app.neural import NeuralControllers, trace_layout
from app.recording import Trajectory, TrajectoryRecorder
from app.rollout import Batch, rollout
from app.seeds import LifeSeeds, life_seeds, n_segments, optimiser_seed
from app.store import RunFileError, RunReader, RunTemplate, RunWriter
from app.training import (
    GenerationSummary,
    Interrupted,
    Lives,
    ProgressCallback,
    TrainingError,
    _make_world,
    _owned,
    _stop_on_sigterm,
    _stop_requested,
    serve_lives,
    shards,
)
from neuro.cmaes import Cmaes
from neuro.neat_evolution import NeatSearch


class Optimiser(Protocol):
    def arrays(self) -> dict[str, np.ndarray]:
        """The generation to evaluate: nets with a leading population axis."""
        ...

    def tell(self, fitness: np.ndarray) -> None:
        """Its fitness; the optimiser moves on to the next generation."""
        ...


class _CmaesOptimiser:
    def __init__(self, config: RunConfig) -> None:
        assert config.neuro is not None
        self.net = neuro.ElmanConfig(hidden=config.neuro.hidden)
        self.es = Cmaes(
            self.net.n_params,
            config.neuro.sigma0,
            config.training.population,
            optimiser_seed(config.seed),
        )

    def arrays(self) -> dict[str, np.ndarray]:
        return neuro.from_flat(self.net, self.es.ask())

    def tell(self, fitness: np.ndarray) -> None:
        self.es.tell(fitness)


def make_optimiser(config: RunConfig) -> Optimiser:
    """A new optimiser for `config` (its `neuro` section set), at generation 0."""
    assert config.neuro is not None
    if config.neuro.optimiser == "cmaes":
        return _CmaesOptimiser(config)
    return NeatSearch(config.neuro.neat, config.training.population, optimiser_seed(config.seed))


def replay_optimiser(config: RunConfig, fitness: np.ndarray) -> Optimiser:
    """The optimiser after telling each row of `fitness` (g, population): a run's state after g
    generations, rebuilt without living anything."""
    optimiser = make_optimiser(config)
    for row in fitness:
        optimiser.arrays()
        optimiser.tell(row)
    return optimiser


# --- lives ----------------------------------------------------------------------------------


def live_nets(
    world: sim.World,
    net: neuro.NetConfig,
    arrays: dict[str, np.ndarray],
    seeds: LifeSeeds,
    steps: int,
    redraw_every: int,
    record: bool = False,
) -> tuple[Lives, Trajectory | None]:
    """N nets' lives of `steps` steps in `world` (as `app.training.live`, without learning)."""
    world.reset(world.arena.start_poses[seeds.starts[:, 0]], seeds=seeds.world)
    batch = Batch.driven_by(world, NeuralControllers(net, arrays))
    recorder = TrajectoryRecorder(batch.size, steps, trace_layout(net)) if record else None
    outcome = rollout(
        batch,
        steps,
        0.0,
        0.0,
        learn=False,
        recorder=recorder,
        episode_starts=seeds.starts,
        redraw_every=redraw_every,
    )
    means = outcome.term_sums / steps
    lives = Lives(fitness=means[:, 0].copy(), terms=means)
    if recorder is None:
        return lives, None
    return lives, recorder.trajectory(seeds.starts[:, 0])


class _NetLives:
    """The lives of a fixed set of individuals, in one persistent world (built on first use)."""

    def __init__(self, config: RunConfig) -> None:
        assert config.neuro is not None
        self._config = config
        self._net = config.neuro.net_config()
        self._world: sim.World | None = None

    def run(self, arrays: dict[str, np.ndarray], seeds: LifeSeeds) -> Lives:
        n = len(seeds.world)
        if self._world is None:
            self._world = _make_world(self._config, n)
        training = self._config.training
        lives, _ = live_nets(
            self._world, self._net, arrays, seeds, training.steps, training.redraw_every
        )
        return lives


def _worker_main(conn: Connection, config_json: str) -> None:
    serve_lives(conn, _NetLives(RunConfig.model_validate_json(config_json)).run)


class _Evaluator:
    """In this process (1 worker) or in persistent `spawn` workers owning whole shards."""

    def __init__(self, config: RunConfig, workers: int) -> None:
        workers = max(1, min(workers, len(shards(config.training))))
        self._local = _NetLives(config) if workers == 1 else None
        self._owned = _owned(config.training, workers)
        self._conns: list[Connection] = []
        self._procs: list[Any] = []
        if self._local is not None:
            return
        context = multiprocessing.get_context("spawn")
        for _ in self._owned:
            parent, child = context.Pipe()
            proc = context.Process(
                target=_worker_main, args=(child, config.model_dump_json()), daemon=True
            )
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)

    def evaluate(self, arrays: dict[str, np.ndarray], seeds: LifeSeeds) -> Lives:
        if self._local is not None:
            return self._local.run(arrays, seeds)
        try:
            for conn, part in zip(self._conns, self._owned, strict=True):
                rows = np.arange(part.start, part.stop)
                conn.send((neuro.take(arrays, rows), seeds.take(part)))
            results = [conn.recv() for conn in self._conns]
        except (EOFError, OSError):
            codes = [proc.exitcode for proc in self._procs]
            raise TrainingError(f"a worker process died (exit codes {codes})") from None
        return Lives(
            fitness=np.concatenate([r.fitness for r in results]),
            terms=np.concatenate([r.terms for r in results]),
        )

    def close(self) -> None:
        for conn in self._conns:
            with contextlib.suppress(BrokenPipeError, OSError):
                conn.send(None)
        for proc in self._procs:
            proc.join(timeout=1)
            if proc.is_alive():
                proc.kill()
                proc.join()
        for conn in self._conns:
            conn.close()


# --- the loop -------------------------------------------------------------------------------


def neural_template(config: RunConfig) -> RunTemplate:
    """The run file's shapes: one net's arrays, one step's activations of one net."""
    assert config.neuro is not None
    net = config.neuro.net_config()
    trace = {
        name: np.zeros((1, *shape), dtype) for name, (shape, dtype) in trace_layout(net).items()
    }
    return RunTemplate(config=config, genome=neuro.zeros(net, 1), trace=trace)


def _train_from(
    writer: RunWriter,
    optimiser: Optimiser,
    start: int,
    workers: int,
    progress: ProgressCallback | None,
) -> None:
    config = writer.config
    assert config.neuro is not None
    training = config.training
    net = config.neuro.net_config()
    n_starts = len(arena_of(training.arena).start_poses)
    segments = n_segments(training.steps, training.redraw_every)
    everyone = np.arange(training.population)
    evaluator = _Evaluator(config, workers)
    done = start
    try:
        with _stop_on_sigterm():
            for generation in range(start, training.generations):
                if _stop_requested.is_set():
                    raise KeyboardInterrupt
                began = time.perf_counter()
                arrays = optimiser.arrays()
                seeds = life_seeds(config.seed, generation, everyone, segments, n_starts)
                lives = evaluator.evaluate(arrays, seeds)
                best = int(np.argmax(lives.fitness))
                writer.write_generation(
                    generation,
                    fitness=lives.fitness,
                    best_terms=dict(zip(sim.TERM_NAMES, lives.terms[best], strict=True)),
                    mean_terms=dict(zip(sim.TERM_NAMES, lives.terms.mean(axis=0), strict=True)),
                    epsilon=float("nan"),  # no online learning
                    alpha=float("nan"),
                    best_genome=neuro.take(arrays, [best]),
                )
                last = generation + 1 == training.generations
                if last:
                    _, elite = live_nets(
                        _make_world(config, 1),
                        net,
                        neuro.take(arrays, [best]),
                        seeds.take(slice(best, best + 1)),
                        training.steps,
                        training.redraw_every,
                        record=True,
                    )
                else:
                    optimiser.tell(lives.fitness)
                    if (generation + 1) % training.checkpoint_every == 0:
                        writer.write_checkpoint(generation + 1, optimiser.arrays())
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
                    assert elite is not None
                    writer.write_elite(generation, elite)
    except KeyboardInterrupt:
        raise Interrupted(done) from None
    finally:
        evaluator.close()
        writer.close()


def train_neural(
    config: RunConfig,
    out: str | Path,
    *,
    workers: int = 1,
    progress: ProgressCallback | None = None,
) -> Path:
    """`app.training.train` for a config with a `neuro` section (same errors)."""
    arena_of(config.training.arena)
    _stop_requested.clear()
    with _stop_on_sigterm():
        optimiser = make_optimiser(config)
        writer = RunWriter.create(out, neural_template(config))
        try:
            writer.write_checkpoint(0, optimiser.arrays())
            writer.mark_done(0)
        except KeyboardInterrupt:
            writer.close()
            Path(out).unlink(missing_ok=True)
            raise
        _train_from(writer, optimiser, 0, workers, progress)
    return writer.path


def resume_neural(
    path: str | Path, *, workers: int = 1, progress: ProgressCallback | None = None
) -> Path:
    """`app.training.resume` for a neural run: the optimiser rebuilt from the told fitness.

    Raises:
        RunFileError: not resumable, or the replay does not give the checkpointed population
            (e.g. another pycma or neat-python version than the run's).
    """
    _stop_requested.clear()
    with _stop_on_sigterm():
        with RunReader(path) as run:
            fitness = run.history().fitness
        writer, generation, population = RunWriter.resume(path)
        try:
            optimiser = replay_optimiser(writer.config, fitness[:generation])
            rebuilt = optimiser.arrays()
        except KeyboardInterrupt:
            writer.close()
            raise Interrupted(generation) from None
        if sorted(rebuilt) != sorted(population) or not all(
            np.array_equal(rebuilt[k], population[k]) for k in rebuilt
        ):
            writer.close()
            raise RunFileError(
                f"{Path(path).name}: replaying the optimiser does not give the checkpointed "
                "population (another pycma or neat-python version?); it cannot be resumed"
            )
        _train_from(writer, optimiser, generation, workers, progress)
    return writer.path
