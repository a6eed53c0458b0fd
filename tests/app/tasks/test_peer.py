"""GNP beside fracnetics (issue #34 item 3): the fracnetics arm (seeded, the same episode budget
as ours), one run of a task experiment for either brain, task experiments through the engine
(an in-process Dask cluster, resumable), and bad task experiments in one line."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from experiment_fixtures import in_process_client

from app.experiments import ledger
from app.experiments.planning import plan
from app.experiments.runner import RunOptions, check_task, run_experiment
from app.experiments.spec import ExperimentError
from app.experiments.spec_loading import parse
from app.tasks.config import TaskRunConfig, TaskSettings, TaskTraining
from app.tasks.fracnetics_arm import DOCUMENTED, documented, train_fracnetics
from app.tasks.peer import PeerRun, read_peer, run_peer

TEST_SEEDS = (1_000_000, 1_000_001, 1_000_002)


def _tiny(seed: int) -> dict[str, Any]:
    return train_fracnetics(
        "CartPole-v1", documented("CartPole-v1"), 6, 3, seed, 50, TEST_SEEDS
    ).__dict__


def test_fracnetics_arm_is_seeded_and_lives_the_budget() -> None:
    a, b, c = _tiny(5), _tiny(5), _tiny(6)
    assert a["fitness"].shape == (3, 6)  # one episode per individual per generation
    assert a["test_returns"].shape == (len(TEST_SEEDS),)
    np.testing.assert_array_equal(a["fitness"], b["fitness"])
    np.testing.assert_array_equal(a["test_returns"], b["test_returns"])
    assert not np.array_equal(a["fitness"], c["fitness"])
    assert (a["fitness"] >= 1).all() and (a["fitness"] <= 50).all()  # capped at 50 steps


def test_every_documented_setting_fits_its_task() -> None:
    import gymnasium as gym

    for task, settings in DOCUMENTED.items():
        env = gym.make(task)
        assert isinstance(env.observation_space, gym.spaces.Box)
        assert isinstance(env.action_space, gym.spaces.Discrete)
        assert settings.jnf == env.observation_space.shape[0] == len(settings.obs_low)
        assert settings.pnf == env.action_space.n  # one processing function per action
        env.close()


def _peer(brain: str, seed: int = 2) -> PeerRun:
    run = TaskRunConfig(
        seed=seed,
        task=TaskSettings(id="CartPole-v1"),
        training=TaskTraining(population=6, generations=3, steps=40),
    )
    settings = documented("CartPole-v1") if brain == "fracnetics" else None
    return PeerRun(brain=brain, run=run, fracnetics=settings, test_seeds=TEST_SEEDS)  # type: ignore[arg-type]


@pytest.mark.parametrize("brain", ["gnp", "fracnetics"])
def test_a_run_of_either_brain_has_the_same_budget_and_tests(brain: str, tmp_path: Path) -> None:
    peer = _peer(brain)
    result = run_peer(peer, tmp_path / "run.h5")
    assert result.finished and result.generations_done == 3
    assert result.best_curve.shape == (3,)
    assert result.test_returns is not None and result.test_returns.shape == (3,)
    assert PeerRun.model_validate_json(result.peer_json) == peer
    again = run_peer(peer, tmp_path / "run.h5")  # finished: left as it is
    np.testing.assert_array_equal(again.test_returns, result.test_returns)
    twin = run_peer(peer, tmp_path / "twin.h5")  # the same seed, the same run
    np.testing.assert_array_equal(twin.best_curve, result.best_curve)
    np.testing.assert_array_equal(twin.test_returns, result.test_returns)


def _spec(**extra: Any) -> dict[str, Any]:
    data: dict[str, Any] = {
        "name": "tiny-peer",
        "description": "tiny",
        "source": "test",
        "kind": "beyond",
        "preset": "quick",
        "seeds": 2,
        "first_seed": 40,
        "task": {"id": "CartPole-v1", "test_seeds": 3},
        "config": {"training": {"steps": 30, "epsilon": 0.01}},
        "arms": [
            {
                "name": "GNP",
                "label": "GNP (no learning)",
                "config": {
                    "controller": {"method": "RL", "fuzzy": False},
                    "training": {"epsilon": 0.0, "alpha": 0.0},
                },
            },
            {
                "name": "RL",
                "label": "GNP-RL",
                "config": {"controller": {"method": "RL", "fuzzy": False}},
            },
            {"name": "fracnetics", "label": "fracnetics", "brain": "fracnetics"},
        ],
        "comparisons": [
            {
                "name": "rl-vs-fracnetics",
                "a": "RL",
                "b": "fracnetics",
                "metric": "test_return",
                "direction": "greater",
                "source": "hypothesis",
                "margin": 5.0,
                "margin_source": "test",
                "paired": False,
            },
            {
                "name": "training",
                "a": "GNP",
                "b": "fracnetics",
                "metric": "final_best_return",
                "direction": "greater",
                "source": "hypothesis",
                "family": "exploratory",
            },
        ],
        "scales": {"smoke": {"config": {"training": {"population": 5, "generations": 2}}}},
    }
    data.update(extra)
    return data


def test_a_task_experiment_runs_through_the_engine_and_resumes(tmp_path: Path) -> None:
    spec = parse(_spec(), "tiny")
    tasks = plan(spec, "smoke", tmp_path)
    assert [t.name for t in tasks][:2] == ["GNP-seed40", "GNP-seed41"]
    for task in tasks:  # every arm: the same episode budget and the same test seeds
        peer = PeerRun.model_validate_json(task.task_json)
        assert (peer.run.training.population, peer.run.training.generations) == (5, 2)
        assert peer.test_seeds == (1_000_000, 1_000_001, 1_000_002)
    with in_process_client() as client:
        options = RunOptions(client=client, quiet=True)
        results = run_experiment(spec, "smoke", tmp_path, options=options)
        for arm in ("GNP", "RL", "fracnetics"):
            for metric in ("final_best_return", "test_return"):
                assert np.isfinite(results.scalar(metric, arm)).all()
            assert results.curve("best_fitness_curve", arm).shape == (2, 2)
        stamps = {t.path: Path(t.path).stat().st_mtime_ns for t in tasks}
        again = run_experiment(spec, "smoke", tmp_path, options=options)
    assert {t.path: Path(t.path).stat().st_mtime_ns for t in tasks} == stamps  # nothing rerun
    for key, values in results.scalars.items():
        np.testing.assert_array_equal(again.scalars[key], values)
    assert len(ledger.finished(spec, "smoke", results)) == len(tasks)
    gnp_run = read_peer(tasks[0].path)
    assert gnp_run.test_returns is not None
    assert gnp_run.run.training.epsilon_alpha(0) == (0.0, 0.0)  # learning off


def test_a_foreign_run_file_is_refused(tmp_path: Path) -> None:
    spec = parse(_spec(), "tiny")
    task = plan(spec, "smoke", tmp_path)[0]
    other = _peer("gnp", seed=task.seed)
    run_peer(other, task.path)
    with pytest.raises(ExperimentError, match="another config"):
        run_experiment(spec, "smoke", tmp_path, options=RunOptions(quiet=True))


def _broken(change: Any) -> str:
    data = copy.deepcopy(_spec())
    change(data)
    with pytest.raises(ExperimentError) as error:
        parse(data, "tiny")
    return str(error.value)


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        (lambda d: d.pop("task"), "brain 'fracnetics' needs a task"),
        (lambda d: d["task"].update(id="Pendulum-v1"), "fracnetics documents no settings"),
        (
            lambda d: d["comparisons"][0].update(metric="mean_reward", condition="x"),
            "measures final_best_return or test_return",
        ),
        (
            lambda d: d.update(conditions=[{"name": "x", "label": "x"}]),
            "no conditions or control",
        ),
        (lambda d: d["arms"][2].update(brain="ppo"), "brain"),
        (lambda d: d["task"].update(test_seeds=0), "test_seeds"),
        (  # fracnetics' tournament of 5 would never return
            lambda d: d["scales"]["smoke"]["config"]["training"].update(population=4),
            "smaller than its tournament",
        ),
    ],
)
def test_a_bad_task_experiment_is_one_line(change: Any, needle: str) -> None:
    message = _broken(change)
    assert needle in message and "\n" not in message


def test_a_task_metric_needs_a_task() -> None:
    data = _spec()
    data.pop("task")
    data["arms"] = data["arms"][:2]
    data["comparisons"] = [{**data["comparisons"][1], "b": "RL", "family": "primary"}]
    with pytest.raises(ExperimentError, match="needs a task") as error:
        parse(data, "tiny")
    assert "\n" not in str(error.value)


def test_an_unknown_task_is_one_line_before_any_run() -> None:
    spec = parse(_spec(task={"id": "NoSuchTask-v9"}, arms=_spec()["arms"][:2],
                       comparisons=[]), "tiny")  # fmt: skip
    with pytest.raises(ExperimentError, match="unknown task") as error:
        check_task(spec)
    assert "\n" not in str(error.value)
    json.dumps(str(error.value))
