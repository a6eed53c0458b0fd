"""Following a training run's file as it is written (no viser server, no subprocess)."""

from __future__ import annotations

import queue
import re
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from app import store
from app.brains.registry import family_of
from app.dashboard.follower import FINISHED_RETRIES, TrainingFollower
from app.phases.training import GenerationSummary, train
from app.settings.config import RunConfig
from app.settings.loading import build_config

GENERATIONS = 3


def small_config() -> RunConfig:
    return build_config(
        {"seed": 5, "training": {"population": 6, "steps": 40, "generations": GENERATIONS}}
    )


class SteppedTraining:
    """`train` in a thread that halts after each generation until `next()` lets it go on."""

    def __init__(self, config: RunConfig, out: Path) -> None:
        self.completed: queue.Queue[int] = queue.Queue()
        self._go_on = threading.Semaphore(0)
        self._thread = threading.Thread(
            target=train, args=(config, out), kwargs={"progress": self._halt}, daemon=True
        )

    def _halt(self, summary: GenerationSummary) -> None:
        self.completed.put(summary.generation)
        self._go_on.acquire()

    def start(self) -> None:
        self._thread.start()

    def wait_for_generation(self) -> int:
        return self.completed.get(timeout=300)

    def next(self) -> None:
        self._go_on.release()

    def join(self) -> None:
        self._thread.join(timeout=300)
        assert not self._thread.is_alive()


@pytest.fixture
def stepped(tmp_path: Path) -> Iterator[tuple[SteppedTraining, TrainingFollower, Path]]:
    out = tmp_path / "run.h5"
    training = SteppedTraining(small_config(), out)
    follower = TrainingFollower(out, small_config())
    yield training, follower, out
    for _ in range(GENERATIONS):
        training.next()  # never leave the thread halted
    follower.close()


def test_each_generation_is_reported_once_and_its_best_put_on_show(
    stepped: tuple[SteppedTraining, TrainingFollower, Path],
) -> None:
    training, follower, out = stepped
    before = follower.poll("running")  # the file does not exist yet
    assert (before.generations, before.best, before.ended) == (0, None, False)
    assert before.describe() == "running · generation 0/3 · 0 s"

    training.start()
    for generation in range(GENERATIONS):
        assert training.wait_for_generation() == generation
        progress = follower.poll("running", elapsed=6.0 * (generation + 1))
        assert progress.generations == generation + 1
        assert progress.best is not None and progress.best.generation == generation
        assert (progress.best.life, progress.best.robot.label) == (40, "run")
        with store.RunReader(out) as reader:
            population = family_of(reader.config).best(reader, generation)
            history = reader.history()
        np.testing.assert_array_equal(progress.best.robot.population.conn, population.conn)
        assert progress.history is not None
        np.testing.assert_array_equal(progress.history.best_fitness, history.best_fitness)
        eta = 6.0 * (GENERATIONS - generation - 1)
        assert re.fullmatch(
            rf"running · generation {generation + 1}/3 · best [\d.]+ · mean [\d.]+ · "
            rf"{6 * (generation + 1)} s · ETA {eta:.0f} s",
            progress.describe(),
        )
        again = follower.poll("paused", elapsed=6.0 * (generation + 1))
        assert again.best is None, "a generation's best goes on show once"
        assert "ETA" not in again.describe() and not again.ended
        training.next()
    training.join()

    final = follower.poll("finished", elapsed=20.0)
    assert final.ended and final.generations == GENERATIONS and final.best is None
    assert final.fraction == 1.0
    assert final.describe().startswith("finished · generation 3/3 · best ")


def test_a_run_stopped_after_one_generation_ends_with_it(
    stepped: tuple[SteppedTraining, TrainingFollower, Path],
) -> None:
    training, follower, _ = stepped
    training.start()
    assert training.wait_for_generation() == 0
    # Stopped before the follower saw anything: the last read still reports the generation.
    progress = follower.poll("stopped", elapsed=3.0)
    assert progress.ended and progress.generations == 1
    assert progress.best is not None and progress.best.generation == 0
    assert progress.describe().startswith("stopped · generation 1/3")


def test_a_failed_run_reports_its_error(tmp_path: Path) -> None:
    follower = TrainingFollower(tmp_path / "never-written.h5", small_config())
    progress = follower.poll("failed", error="RunFileError: disk full")
    assert progress.ended and progress.generations == 0
    assert progress.describe() == "failed: RunFileError: disk full"


def test_a_finished_run_that_cannot_be_read_is_retried_then_given_up(tmp_path: Path) -> None:
    out = tmp_path / "torn.h5"
    out.write_bytes(b"not an HDF5 file yet")
    follower = TrainingFollower(out, small_config())
    states = [follower.poll("finished").ended for _ in range(FINISHED_RETRIES + 1)]
    assert states == [False] * FINISHED_RETRIES + [True]
