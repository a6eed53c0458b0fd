"""Lives of a training generation: in this process, or on the worker pool.

`Evaluator` lives a generation in this process (one worker) or on a pool of processes, each
owning a contiguous run of whole shards (`app.phases.lives`); a GNP population goes to and from
the pool through shared memory and evolves there (`app.phases.shared_lives`), other families'
individuals through the pipes. Split from `app.phases.generations`, the loop that calls it.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from app.brains.contract import Evolution
from app.brains.registry import family_of
from app.loop.seeds import LifeSeeds, life_seeds, n_segments
from app.phases.lives import Lives, ShardLives, concat_lives, owned, shards
from app.phases.shared_lives import (
    EvolveJob,
    InBlock,
    RowsJob,
    RowsWorker,
    shared_evolution,
    shared_layout,
)
from app.settings.arenas import arena_of
from app.settings.config import RunConfig
from app.system.workers import Handler, Layout, SharedArrays, WorkerDied, WorkerPool


class TrainingError(RuntimeError):
    """Training could not go on (a worker died, the run cannot start)."""


def _shard_worker(config_json: str, spec: tuple[str, Layout] | None = None) -> Handler:
    """A pool worker's state: the lives of its shards, in one persistent world; with `spec`,
    also the jobs on a shared block (`app.phases.shared_lives`)."""
    config = RunConfig.model_validate_json(config_json)
    rows = RowsWorker(config, spec) if spec is not None else None
    lives = ShardLives(config) if rows is None else rows.lives

    def handle(job: Any, count: Any) -> tuple[Lives, Any] | None:
        if isinstance(job, RowsJob | EvolveJob):
            assert rows is not None
            return rows(job, count)
        individuals, seeds, epsilon, alpha = job
        result, after, _ = lives.run(individuals, seeds, epsilon, alpha, False)
        # Nets do not learn: they come back as they went (None), not piped back unchanged.
        return result, None if after is individuals else after

    return handle


def nothing() -> None:
    """The default `meanwhile`: nothing to do while the workers work."""
    pass


class Evaluator:
    """Lives a generation: in this process (one worker, `local`), else on a pool of `workers`
    processes (at most one per shard), each owning a contiguous run of whole shards. A GNP
    population goes to and from the workers through shared memory, and evolves there
    (`app.phases.shared_lives`, after `adopt`); other families' individuals go through the
    pipes.

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
        self._block: SharedArrays | None = None
        self._stopping = stopping
        self._config = config
        self.family = family_of(config)
        training = config.training
        self._segments = n_segments(training.steps, training.redraw_every)
        self._n_starts = len(arena_of(training.arena).start_poses)
        workers = max(1, min(workers, len(shards(training))))
        if workers == 1 and local:
            self._local = ShardLives(config)
            return
        self._owned = owned(training, workers)
        layout = shared_layout(config)
        try:
            # The block before the workers: they attach to it as they start.
            self._block = SharedArrays.create(layout) if layout is not None else None
            spec = self._block.spec if self._block is not None else None
            self._pool = WorkerPool(workers, _shard_worker, (config.model_dump_json(), spec))
        except BaseException:
            self.close()
            raise

    def adopt(self, evolution: Evolution) -> Evolution:
        """The run's population as this evaluator evolves it: in the shared block, by the
        workers, when it has one; else `evolution` itself."""
        if self._block is None:
            return evolution
        return shared_evolution(evolution, self._config, self._block, self._run)

    def seeds(self, generation: int, rows: np.ndarray) -> LifeSeeds:
        """The life seeds of individuals `rows` of `generation`."""
        return life_seeds(self._config.seed, generation, rows, self._segments, self._n_starts)

    def evaluate_generation(
        self,
        individuals: Any,
        generation: int,
        epsilon: float,
        alpha: float,
        meanwhile: Callable[[], None] = nothing,
    ) -> tuple[Lives, Any]:
        """The lives of a whole generation's `individuals` (left as they are) and the
        individuals after them; `meanwhile()` is called while the workers live them (in this
        process: before). With a shared block, the individuals after them are the block's
        (`InBlock`), valid until the next generation's lives."""
        block = self._block
        if block is None:
            everyone = np.arange(self._config.training.population)
            return self.evaluate(
                individuals, self.seeds(generation, everyone), epsilon, alpha, meanwhile
            )
        if not (isinstance(individuals, InBlock) and individuals.records is block["population"]):
            block["population"][...] = individuals.records
        self._run(
            [RowsJob(p.start, p.stop, generation, epsilon, alpha) for p in self._owned], meanwhile
        )
        lives = Lives(fitness=block["fitness"].copy(), terms=block["terms"].copy())
        return lives, InBlock(block["learned"])

    def evaluate(
        self,
        individuals: Any,
        seeds: LifeSeeds,
        epsilon: float,
        alpha: float,
        meanwhile: Callable[[], None] = nothing,
    ) -> tuple[Lives, Any]:
        """The lives of `individuals` (left as they are) and the individuals after them, through
        the pipes (or in this process)."""
        if self._local is not None:
            meanwhile()
            if self._stopping is not None and self._stopping.is_set():
                raise KeyboardInterrupt  # asked for meanwhile (by a progress display)
            lives, after, _ = self._local.run(individuals, seeds, epsilon, alpha, False)
            return lives, after
        family = self.family
        jobs = [
            (family.take(individuals, np.arange(part.start, part.stop)), seeds.take(part),
             epsilon, alpha)
            for part in self._owned
        ]  # fmt: skip
        results = self._gather(jobs, meanwhile)
        afters = [r[1] for r in results]
        after = individuals if afters[0] is None else family.concat(afters)  # None: unchanged
        return concat_lives([r[0] for r in results]), after

    def _gather(self, jobs: list[Any], meanwhile: Callable[[], None]) -> list[Any]:
        """Job i to worker i; `meanwhile()`; their answers."""
        return self._run(jobs, meanwhile)

    def _run(self, jobs: list[Any], meanwhile: Callable[[], None] = nothing) -> list[Any]:
        """Job i to worker i mod the workers; `meanwhile()`; the answers in job order."""
        pool = self._pool
        assert pool is not None
        stopping = self._stopping
        try:
            given: dict[int, list[int]] = {}
            for i, job in enumerate(jobs):
                pool.send(i % pool.size, job)
                given.setdefault(i % pool.size, []).append(i)
            meanwhile()
            out: dict[int, Any] = {}
            for worker, result in pool.gather(len(jobs), stopping.is_set if stopping else None):
                out[given[worker].pop(0)] = result
            return [out[i] for i in range(len(jobs))]
        except WorkerDied as error:
            raise TrainingError(str(error)) from None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.close()
            self._pool = None
        if self._block is not None:  # after the workers: none is left writing into it
            self._block.close()
            self._block = None

    def __enter__(self) -> Evaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
