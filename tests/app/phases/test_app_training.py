"""Training: seeds, learning, determinism over worker counts, kill-and-resume, SWMR, SIGTERM."""

from __future__ import annotations

import contextlib
import itertools
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from lab_fixtures import assert_same_data, datasets, file_digest, tiny_config

import sim
from app.loop.seeds import life_seeds, n_segments
from app.phases.implementation import implement
from app.phases.lives import shards
from app.phases.training import resume, train
from app.settings.config import ImplementationSettings
from app.settings.loading import build_config, to_toml
from app.store import RunFileError, RunReader


@given(st.sets(st.integers(0, 500), min_size=1, max_size=20), st.integers(0, 3))
@settings(max_examples=25, deadline=None)
def test_life_seeds_depend_on_the_individual_not_the_batch(indices: set[int], gen: int) -> None:
    ordered = np.array(sorted(indices))
    everyone = life_seeds(5, gen, np.arange(501), 3, 10)
    some = life_seeds(5, gen, ordered, 3, 10)
    assert np.array_equal(some.world, everyone.world[ordered])
    assert np.array_equal(some.engine, everyone.engine[ordered])
    assert np.array_equal(some.starts, everyone.starts[ordered])
    assert some.starts.min() >= 0 and some.starts.max() < 10
    other_generation = life_seeds(5, gen + 1, ordered, 3, 10)
    assert not np.array_equal(some.world, other_generation.world)


@given(st.integers(2, 2000), st.integers(1, 300))
def test_shards_cover_the_population_in_order(population: int, shard_size: int) -> None:
    parts = shards(tiny_config(population=population, shard_size=shard_size).training)
    assert parts[0].start == 0 and parts[-1].stop == population
    assert all(a.stop == b.start for a, b in itertools.pairwise(parts))
    sizes = [p.stop - p.start for p in parts]
    assert max(sizes) <= shard_size and max(sizes) - min(sizes) <= 1
    assert len(parts) == -(-population // shard_size)


def test_segments() -> None:
    assert n_segments(1000, 0) == 1
    assert n_segments(2000, 500) == 4
    assert n_segments(2001, 500) == 5


def test_elite_replays_its_own_evaluation(finished_run: Path) -> None:
    with RunReader(finished_run) as run:
        elite = run.elite()
        assert elite is not None
        history = run.history()
        steps = run.config.training.steps
        assert elite.poses.shape == (1, steps, 3)
        assert elite.trace["node"].shape[:2] == (1, steps)
        # fitness (Eq. 2.8) is the sum of the per-step rewards over T, summed in step order
        assert np.cumsum(elite.reward[0])[-1] / steps == history.best_fitness[-1]
        # the trace starts at the start node and every step ends with a command
        assert elite.trace["node"][0, 0, 0] == 0
        assert np.all(elite.trace["count"][0] >= 1)
        assert np.all(np.abs(elite.commands) <= 10)


def test_redraw_moves_the_robot_to_its_next_start_pose(tmp_path: Path) -> None:
    path = tmp_path / "redraw.h5"
    train(tiny_config(generations=1, steps=40, redraw_every=20), path, workers=1)
    with RunReader(path) as run:
        elite = run.elite()
        assert elite is not None
        best = int(run.history().best_index[0])
    seeds = life_seeds(7, 0, np.array([best]), 2, 10)
    arena = sim.load_arena("training")
    # one control step moves a robot at most 75 mm/s × 0.064 s ≈ 4.8 mm from where it was put
    for segment, t in ((0, 0), (1, 20)):
        start = arena.start_poses[seeds.starts[0, segment]]
        assert np.hypot(*(elite.poses[0, t, :2] - start[:2])) < 6.0


def test_best_fitness_rises(tmp_path: Path) -> None:
    """A small run learns: fitness grows well above generation 0's."""
    path = tmp_path / "learn.h5"
    config = build_config(
        {"seed": 1, "training": {"population": 40, "steps": 300, "generations": 8}}
    )
    train(config, path, workers=1)
    with RunReader(path) as run:
        history = run.history()
    assert history.mean_fitness[-1] > 1.5 * history.mean_fitness[0]
    assert history.best_fitness[-3:].max() > history.best_fitness[0] + 0.05


def test_same_seed_same_file_for_any_worker_count(tmp_path: Path) -> None:
    config = tiny_config(population=10, generations=2)
    one, two, other = tmp_path / "one.h5", tmp_path / "two.h5", tmp_path / "other.h5"
    train(config, one, workers=1)
    train(config, two, workers=2)
    assert_same_data(one, two)
    train(build_config(config.model_dump(), {"seed": 8}), other, workers=1)
    assert not np.array_equal(
        datasets(one)["generations/fitness"], datasets(other)["generations/fitness"]
    )


def test_a_run_that_cannot_start_on_workers_fails_with_its_file_error(finished_run: Path) -> None:
    # The pool starts before the file is checked; its never-used workers are dropped at once.
    before = file_digest(finished_run)
    with pytest.raises(RunFileError, match="already exists; choose another --out"):
        train(tiny_config(), finished_run, workers=2, local=False)
    with pytest.raises(RunFileError, match="is a finished run; there is nothing to resume"):
        resume(finished_run, workers=2, local=False)
    assert file_digest(finished_run) == before


# --- a real training process: killed, stopped, followed while it writes --------------------


def _start_training(config_file: Path, out: Path, workers: int) -> subprocess.Popen[bytes]:
    command = [sys.executable, "-m", "app.cli", "train", "--config", str(config_file)]
    command += ["--out", str(out), "--workers", str(workers), "--quiet"]
    return subprocess.Popen(
        command, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, start_new_session=True
    )


def _follow_until(path: Path, done_at_least: int, process: subprocess.Popen[bytes]) -> list[int]:
    """Read the run in this process while the other writes; return the counts seen."""
    seen: list[int] = []
    deadline = time.monotonic() + 120
    reader = None
    while time.monotonic() < deadline:
        assert process.poll() is None, process.stderr.read() if process.stderr else b""
        if reader is None and path.exists():
            reader = RunReader(path)
        if reader is not None:
            reader.refresh()
            seen.append(reader.generations_done)
            reader.history()  # the rows it counts are readable
            if seen[-1] >= done_at_least:
                reader.close()
                return seen
        time.sleep(0.01)
    raise AssertionError(f"training did not reach {done_at_least} generations: {seen}")


LONG_GENERATIONS = 20


@pytest.fixture(scope="module")
def long_config(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(config file, the uninterrupted run of it)."""
    folder = tmp_path_factory.mktemp("long")
    # Generations long enough (16 × 1000 robot-steps) for a reader to follow a few of them
    # before the run ends, also on a fast engine.
    config = tiny_config(
        population=16, steps=1000, generations=LONG_GENERATIONS, checkpoint_every=2
    )
    config_file = folder / "long.toml"
    config_file.write_text(to_toml(config))
    reference = folder / "reference.h5"
    train(config, reference, workers=1)
    return config_file, reference


def test_sigkill_then_resume_matches_an_uninterrupted_run(
    tmp_path: Path, long_config: tuple[Path, Path]
) -> None:
    config_file, reference = long_config
    out = tmp_path / "killed.h5"
    process = _start_training(config_file, out, workers=2)
    try:
        seen = _follow_until(out, 5, process)
    finally:
        os.killpg(process.pid, signal.SIGKILL)  # the trainer and its workers, mid-generation
        process.wait()
    # SWMR: this process saw generations appear one by one while the other wrote them
    assert len(set(seen)) >= 3 and max(seen) < LONG_GENERATIONS
    with RunReader(out) as run:  # the killed file opens and holds what was complete
        assert 5 <= run.generations_done < LONG_GENERATIONS and not run.finished
        done = run.generations_done
        assert np.array_equal(
            run.history().fitness, datasets(reference)["generations/fitness"][:done]
        )
    resume(out, workers=1)
    assert_same_data(out, reference)
    with h5py.File(out, "r") as handle:  # closed cleanly: plain (non-SWMR) opens work again
        assert handle["progress/finished"][()] == 1


def test_sigterm_stops_cleanly_and_resumes(tmp_path: Path, long_config: tuple[Path, Path]) -> None:
    config_file, reference = long_config
    out = tmp_path / "stopped.h5"
    process = _start_training(config_file, out, workers=2)
    try:
        _follow_until(out, 3, process)
        os.killpg(process.pid, signal.SIGSTOP)  # a writer frozen mid-run: readers still read
        with RunReader(out) as run:
            paused_at = run.generations_done
        time.sleep(0.2)
        with RunReader(out) as run:
            assert run.generations_done == paused_at
        # a second writer is refused while the first lives, even paused, and nothing changes
        before = file_digest(out)
        with pytest.raises(RunFileError, match="being written by another gnp-lab process"):
            resume(out, workers=1)
        with pytest.raises(RunFileError, match="has not finished training"):
            implement(out, ImplementationSettings(steps=10, repeats=1))
        assert file_digest(out) == before
        os.killpg(process.pid, signal.SIGCONT)
        os.killpg(process.pid, signal.SIGTERM)
        _, stderr = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    message = stderr.decode()
    assert process.returncode == 130
    assert "Traceback" not in message
    assert f"gnp-lab train --resume {out}" in message
    with h5py.File(out, "r") as handle:  # closed cleanly
        done = int(handle["progress/generations_done"][()])
    assert 3 <= done < LONG_GENERATIONS
    resume(out, workers=2)
    assert_same_data(out, reference)


def test_a_stop_wins_over_a_pause() -> None:
    from app.phases.training import Control

    control = Control()
    control.stop()
    control.pause()  # too late: nothing to hold
    assert control.running.is_set()
    with pytest.raises(KeyboardInterrupt):
        control.checkpoint()
    # A stop left by SIGTERM's handler (`stopping` only) while paused: no wait first.
    paused = Control()
    paused.pause()
    paused.stopping.set()
    with pytest.raises(KeyboardInterrupt):
        paused.checkpoint()
    assert not paused.held.is_set()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_and_sigterm_leave_the_same_stop_request(sig: int) -> None:
    from app.phases.generations import stop_on_signals
    from app.phases.training import Control

    control = Control()
    before = signal.getsignal(sig)
    with pytest.raises(KeyboardInterrupt), stop_on_signals(control):
        signal.raise_signal(sig)
    assert control.stopping.is_set()  # remembered, should the interrupt be swallowed
    assert signal.getsignal(sig) is before


def test_an_error_after_a_swallowed_interrupt_stops_training_as_the_interrupt() -> None:
    """Should numba's compiler swallow the KeyboardInterrupt and fail in its place, the stop
    is still what is raised (and remembered in the control)."""
    from app.phases.generations import stop_on_signals
    from app.phases.training import Control

    control = Control()
    with pytest.raises(KeyboardInterrupt), stop_on_signals(control):
        with contextlib.suppress(KeyboardInterrupt):  # swallowed inside llvmlite
            signal.raise_signal(signal.SIGTERM)
        raise RuntimeError("no compiled object yet")
    assert control.stopping.is_set()


def test_a_stop_request_whose_interrupt_was_swallowed_still_stops(tmp_path: Path) -> None:
    """SIGTERM during numba's compilation can lose its KeyboardInterrupt inside llvmlite; the
    request it left stops the run at the next generation, resumable."""
    import app.phases.training as training

    out = tmp_path / "stopped.h5"

    control = training.Control()

    def swallowed_sigterm(_summary: training.GenerationSummary) -> None:
        control.stopping.set()  # what the handler does before its lost raise

    with pytest.raises(training.Interrupted) as stop:
        train(
            tiny_config(generations=3),
            out,
            workers=1,
            progress=swallowed_sigterm,
            control=control,
        )
    assert stop.value.generations_done == 1
    with RunReader(out) as run:
        assert run.generations_done == 1 and not run.finished
    resume(out, workers=1)  # a new run or resume starts without the old request
    with RunReader(out) as run:
        assert run.finished
