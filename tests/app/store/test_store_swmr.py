"""A reader following a live SWMR writer never sees an error, a torn row, or time going back."""

from __future__ import annotations

import multiprocessing
import time
from pathlib import Path
from typing import NoReturn

import numpy as np
import pytest
from lab_fixtures import tiny_config

from app.store import History, RunFileError, RunReader, RunTemplate, RunWriter
from app.store import reader as reader_module
from sim import TERM_NAMES

POPULATION = 12
GENERATIONS = 4000
TIME_LIMIT = 20.0  # seconds, for the whole test
WRITING = 12.0  # seconds the writer writes (it starts in about 2 s)


def _template(generations: int) -> RunTemplate:
    # Genome arrays of a realistic size (a CS individual of 61 nodes): every generation rewrites
    # a compressed chunk of each, and every checkpoint the whole population, as training does.
    genome = _genome(0)
    trace = {"node": np.zeros((1, 6), np.int32), "count": np.zeros(1, np.int32)}
    return RunTemplate(tiny_config(generations=generations), genome, trace)


def _genome(value: int) -> dict[str, np.ndarray]:
    return {
        "q": np.full((1, 61, 2, 2), value, np.float32),
        "conn": np.full((1, 61, 2, 2, 1), value % 30000, np.int16),
    }


def _write_generations(path: str, generations: int, seconds: float) -> None:
    """Write generation g with every value equal to g, publishing each, as fast as possible."""
    deadline = time.monotonic() + seconds
    with RunWriter.create(path, _template(generations)) as writer:
        for g in range(generations):
            if time.monotonic() > deadline:
                break
            terms = dict.fromkeys(TERM_NAMES, float(g))
            genome = _genome(g)
            writer.write_generation(
                g,
                fitness=np.full(POPULATION, float(g)),
                best_terms=terms,
                mean_terms=terms,
                epsilon=float(g),
                alpha=float(g),
                best_genome=genome,
            )
            if g % 10 == 0:  # a whole-population rewrite every few generations, as training
                population = {k: np.repeat(v, POPULATION, axis=0) for k, v in genome.items()}
                writer.write_checkpoint(g + 1, population)
            writer.mark_done(g + 1)


@pytest.mark.slow
def test_a_reader_following_a_flushing_writer_sees_only_complete_rows(tmp_path: Path) -> None:
    path = tmp_path / "live.h5"
    start = time.monotonic()
    writer = multiprocessing.get_context("spawn").Process(
        target=_write_generations, args=(str(path), GENERATIONS, WRITING)
    )
    writer.start()
    try:
        while not path.exists():
            assert writer.exitcode is None, "the writer died before creating the file"
            assert time.monotonic() - start < TIME_LIMIT, "the writer never created the file"
            time.sleep(0.01)
        reads, seen = 0, 0
        with RunReader(path) as run:
            while time.monotonic() - start < TIME_LIMIT:
                writer_done = not writer.is_alive()  # before reading: then the read sees it all
                run.refresh()
                history = run.history()
                done = len(history.best_fitness)
                assert done >= seen, f"generations_done went back from {seen} to {done}"
                seen = done
                index = np.arange(done, dtype=float)
                assert np.array_equal(history.fitness, np.repeat(index[:, None], POPULATION, 1))
                for values in (
                    history.best_fitness,
                    history.mean_fitness,
                    history.epsilon,
                    history.alpha,
                ):
                    assert np.array_equal(values, index)
                assert np.array_equal(history.std_fitness, np.zeros(done))
                assert all(np.array_equal(v, index) for v in history.best_terms.values())
                if done and reads % 10 == 0:
                    assert run.best_genome_arrays(done - 1)["q"].max() == done - 1
                reads += 1
                if writer_done:
                    break
        writer.join(timeout=TIME_LIMIT)
        assert writer.exitcode == 0
        # Thousands of each on an idle machine; the floors only check that they overlapped.
        assert reads >= 300, f"only {reads} reads while the writer wrote {seen} generations"
        assert seen >= 300, f"the writer got only {seen} generations done"
        with RunReader(path) as run:  # the finished file holds every generation the writer did
            assert run.generations_done == seen
    finally:
        if writer.is_alive():
            writer.kill()
            writer.join()


def _live_file(tmp_path: Path) -> tuple[RunWriter, Path]:
    """A run file with a live SWMR writer (so readers open it in SWMR mode) and 2 generations."""
    path = tmp_path / "live.h5"
    writer = RunWriter.create(path, _template(generations=3))
    for g in range(2):
        terms = dict.fromkeys(TERM_NAMES, float(g))
        writer.write_generation(
            g,
            fitness=np.full(POPULATION, float(g)),
            best_terms=terms,
            mean_terms=terms,
            epsilon=0.1,
            alpha=0.1,
            best_genome=_genome(g),
        )
    writer.mark_done(2)
    return writer, path


def test_a_torn_read_is_retried_and_the_file_reopened(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    writer, path = _live_file(tmp_path)
    failures = iter([OSError("Can't read data (invalid dataset size, likely file corruption)")] * 5)
    read_rows = RunReader._history
    reopened: list[int] = []

    def torn_then_whole(self: RunReader) -> History:
        failure = next(failures, None)
        if failure is not None:
            raise failure
        return read_rows(self)

    monkeypatch.setattr(RunReader, "_history", torn_then_whole)
    reopen = RunReader._reopen

    def counted_reopen(self: RunReader) -> None:
        reopened.append(1)
        reopen(self)

    monkeypatch.setattr(RunReader, "_reopen", counted_reopen)
    with RunReader(path) as run:
        assert run.file.swmr_mode
        history = run.history()
    writer.close()
    assert np.array_equal(history.best_fitness, [0.0, 1.0])
    assert reopened == [1]  # five failures: the fifth read came after a reopen


def test_a_read_that_never_clears_is_a_run_file_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    writer, path = _live_file(tmp_path)
    monkeypatch.setattr(reader_module, "_PAUSES", (0.0,) * 6)

    def always_torn(_self: RunReader) -> NoReturn:
        raise OSError("Can't read data (invalid dataset size, likely file corruption)")

    monkeypatch.setattr(RunReader, "_history", always_torn)
    with RunReader(path) as run, pytest.raises(RunFileError, match="while it is being written"):
        run.history()
    writer.close()
