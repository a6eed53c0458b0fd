"""Env-steps reported per arm (issue #45, DESIGN §4): a task run of either brain records the
env-steps each generation's episodes took and each test episode's length; a file written
before them still reads; a task experiment harvests `training_env_steps`."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import h5py
import numpy as np
import pytest
from experiment_fixtures import in_process_client
from legacy_task_files import write_old_task_run
from test_peer import _spec

from app.experiments.harvest import collect
from app.experiments.planning import plan
from app.experiments.report_page import write_report
from app.experiments.runner import RunOptions, run_experiment
from app.experiments.spec_loading import parse
from app.phases.generations import Interrupted
from app.tasks.common import is_task_run
from app.tasks.config import TEST_PROTOCOLS, TaskRunConfig, TaskSettings, TaskTraining
from app.tasks.fracnetics_arm import StepCounter, documented
from app.tasks.peer import PeerRun, read_peer, run_peer
from app.tasks.store import read_task_run
from app.tasks.training import resume_task, train_task

TEST_SEEDS = (1_000_000, 1_000_001, 1_000_002)


def _peer(brain: str) -> PeerRun:
    run = TaskRunConfig(
        seed=3,
        task=TaskSettings(id="CartPole-v1"),
        training=TaskTraining(population=6, generations=2, steps=60),
    )
    settings = documented("CartPole-v1") if brain == "fracnetics" else None
    return PeerRun(brain=brain, run=run, fracnetics=settings, test_seeds=TEST_SEEDS)  # type: ignore[arg-type]


def _fitness(path: Path) -> np.ndarray:
    if is_task_run(path):  # a GNP run
        return read_task_run(path).fitness
    with h5py.File(path, "r") as handle:  # a fracnetics run
        return np.asarray(handle["history/fitness"][()])


def _before_env_steps(path: Path) -> None:
    """Make `path` a file of before #45: an old-format task run without env-steps (a GNP
    run), a fracnetics run without them."""
    if is_task_run(path):
        old = write_old_task_run(path, path.with_suffix(".old"), env_steps=False)
        old.replace(path)
        return
    with h5py.File(path, "r+") as handle:
        del handle["history/env_steps"]


@pytest.mark.parametrize("brain", ["gnp", "fracnetics"])
def test_a_run_records_the_env_steps_of_every_generation_and_test_episode(
    brain: str, tmp_path: Path
) -> None:
    result = run_peer(_peer(brain), tmp_path / "run.h5")
    # CartPole pays 1 a step: a generation's env-steps are the sum of its episodes' returns
    fitness = _fitness(tmp_path / "run.h5")
    assert result.env_steps is not None and result.env_steps.dtype == np.int64
    np.testing.assert_array_equal(result.env_steps, fitness.sum(axis=1).astype(np.int64))
    assert result.training_env_steps == int(fitness.sum())
    assert 6 * 2 <= result.training_env_steps <= 6 * 2 * 60  # capped at 60 steps an episode
    assert result.test_lengths is not None and set(result.test_lengths) == set(TEST_PROTOCOLS)
    assert result.protocol_returns is not None
    for protocol, lengths in result.test_lengths.items():
        assert lengths.shape == (len(TEST_SEEDS),)
        np.testing.assert_array_equal(lengths, result.protocol_returns[protocol])
    if brain == "gnp":  # the task run's own reader agrees
        run = read_task_run(tmp_path / "run.h5")
        np.testing.assert_array_equal(run.env_steps, result.env_steps)


def test_the_step_counter_counts_each_episode_and_changes_nothing() -> None:
    plain, counted = gym.make("CartPole-v1"), StepCounter(gym.make("CartPole-v1"))
    for seed in (1, 2):
        a, _ = plain.reset(seed=seed)
        b, _ = counted.reset(seed=seed)
        np.testing.assert_array_equal(a, b)
        for _ in range(5 + seed):
            np.testing.assert_array_equal(plain.step(0)[0], counted.step(0)[0])
    np.testing.assert_array_equal(counted.take(), [6, 7])
    assert counted.take().size == 0


def test_a_file_written_before_env_steps_still_reads(tmp_path: Path) -> None:
    for brain in ("gnp", "fracnetics"):
        path = tmp_path / f"{brain}.h5"
        result = run_peer(_peer(brain), path)
        _before_env_steps(path)
        with h5py.File(path, "r+") as handle:
            for protocol in TEST_PROTOCOLS:
                del handle["test/lengths_" + protocol.replace("-", "_")]
        old = read_peer(path)
        assert old.finished and old.env_steps is None and old.test_lengths is None
        assert old.training_env_steps is None
        np.testing.assert_array_equal(old.test_returns, result.test_returns)
        if brain == "gnp":
            assert read_task_run(path).env_steps is None


def test_a_resumed_run_records_the_same_env_steps_and_an_old_one_none(tmp_path: Path) -> None:
    config = _peer("gnp").run.model_copy(
        update={"training": TaskTraining(population=6, generations=3, steps=60)}
    )
    whole = read_task_run(train_task(config, tmp_path / "whole.h5"))

    def stop_after_one(_summary: object) -> None:
        raise KeyboardInterrupt

    for name, old in (("cut.h5", False), ("old.h5", True)):
        cut = tmp_path / name
        with pytest.raises(Interrupted):
            train_task(config, cut, stop_after_one)
        if old:  # begun before #45, in the old format: its generations' env-steps unknown
            _before_env_steps(cut)
            assert read_task_run(cut).legacy
        resume_task(cut)
        run = read_task_run(cut)
        np.testing.assert_array_equal(run.fitness, whole.fitness)
        assert not run.legacy  # resumed in the run format
        if old:
            assert run.env_steps is None
        else:
            np.testing.assert_array_equal(run.env_steps, whole.env_steps)


def test_a_task_experiment_harvests_reports_and_claims_training_env_steps(tmp_path: Path) -> None:
    data = _spec()
    data["comparisons"].append(
        {
            "name": "cost",
            "a": "RL",
            "b": "fracnetics",
            "metric": "training_env_steps",
            "direction": "less",
            "source": "DESIGN §4",
            "family": "exploratory",
        }
    )
    spec = parse(data, "tiny")
    runs = tmp_path / "runs"
    with in_process_client() as client:
        results = run_experiment(spec, "smoke", runs, options=RunOptions(client=client, quiet=True))
    for task in plan(spec, "smoke", runs):
        total = read_peer(task.path).training_env_steps
        row = results.seeds.index(task.seed)
        assert total == results.scalar("training_env_steps", task.arm)[row] > 0
    index = write_report(results, tmp_path / "report")
    page = index.read_text()
    assert "Arms: test return and env-steps" in page and "env-steps in training" in page
    report = json.loads((tmp_path / "report" / "report.json").read_text())
    claim = next(c for c in report["comparisons"] if c["name"] == "cost")
    assert claim["verdict"] == "exploratory" and claim["a"]["mean"] is not None
    assert "training_env_steps" in (tmp_path / "report" / "values.csv").read_text()
    # files before #45 (no env-steps) and no claim naming it: no column, no section
    unclaimed = parse(_spec(), "tiny")
    for task in plan(unclaimed, "smoke", runs):
        _before_env_steps(Path(task.path))
    old = collect(unclaimed, "smoke", runs)
    assert not any(key[0] == "training_env_steps" for key in old.scalars)
    assert "env-steps" not in write_report(old, tmp_path / "old").read_text()


def test_a_finished_runs_line_names_its_env_steps_when_it_has_them() -> None:
    from app.experiments.progress import outcome_line

    outcome = {"arm": "RL", "seed": 4, "final_best_fitness": 60.0, "test_return": 12.5}
    assert outcome_line(outcome) == "RL seed 4: final best return 60.0; test return 12.5"
    line = outcome_line({**outcome, "training_env_steps": 12345})
    assert line.endswith("test return 12.5; 12,345 env-steps in training")
