"""A task run's episodes and test (issue #45): test protocols (greedy, as trained), the elite
chosen on K validation episodes, shared episode seeds per generation, and task experiments
that report a test return per protocol."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from experiment_fixtures import in_process_client
from test_peer import _spec

import gnp
from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.experiments.runner import RunOptions, run_experiment
from app.experiments.spec_loading import parse
from app.tasks.config import TaskRunConfig, TaskSettings, TaskTraining
from app.tasks.peer import PeerRun, read_peer, run_peer
from app.tasks.training import (
    elite_generation,
    generation_lives,
    protocol_episodes,
    train_task,
    validation_seeds,
)

TEST_SEEDS = (1_000_000, 1_000_001, 1_000_002, 1_000_003)


def _run(**training: Any) -> TaskRunConfig:
    controller = training.pop("controller", {})
    return TaskRunConfig(
        seed=5,
        task=TaskSettings(id="CartPole-v1"),
        brain=GnpSettings(controller=ControllerSettings(method="RL", fuzzy=False, **controller)),
        training=TaskTraining(population=8, generations=4, steps=120, **training),
    )


def test_a_greedy_test_freezes_the_elite_and_a_learning_off_elite_tests_the_same_either_way(
    tmp_path: Path,
) -> None:
    # learning off (ε = α = 0) with ties to the first sub node: one fixed policy
    off = _run(epsilon=gnp.Schedule.fixed(0.0), alpha=gnp.Schedule.fixed(0.0))
    off = off.model_copy(
        update={
            "brain": off.brain.model_copy(
                update={
                    "controller": off.brain.controller.model_copy(update={"tie_break": "first"})
                }
            )
        }
    )
    result = run_peer(PeerRun(run=off, test_seeds=TEST_SEEDS), tmp_path / "off.h5")
    assert result.protocol_returns is not None
    np.testing.assert_array_equal(
        result.protocol_returns["greedy"], result.protocol_returns["as-trained"]
    )
    # learning on: the greedy test leaves the Q tables as training ended them
    on = _run(epsilon=gnp.Schedule.fixed(0.2), test_protocol="greedy")
    path = run_peer(PeerRun(run=on, test_seeds=TEST_SEEDS), tmp_path / "on.h5")
    assert path.test_returns is not None and path.protocol_returns is not None
    np.testing.assert_array_equal(path.test_returns, path.protocol_returns["greedy"])
    greedy = protocol_episodes(tmp_path / "on.h5", TEST_SEEDS, None, "greedy")
    trained = protocol_episodes(tmp_path / "on.h5", TEST_SEEDS, None, "as-trained")
    from app.tasks.store import read_task_run

    _, elite = read_task_run(tmp_path / "on.h5").best_genome()
    for i in range(len(TEST_SEEDS)):
        np.testing.assert_array_equal(greedy.learned.q_ss[i], elite.q_ss[0])
    assert any(not np.array_equal(trained.learned.q_ss[i], elite.q_ss[0]) for i in range(4))


def test_a_file_tested_before_the_protocols_reads_as_trained_only(tmp_path: Path) -> None:
    result = run_peer(PeerRun(run=_run(), test_seeds=TEST_SEEDS), tmp_path / "run.h5")
    assert result.protocol_returns is not None
    with h5py.File(tmp_path / "run.h5", "r+") as handle:
        del handle["test/returns_greedy"], handle["test/returns_as_trained"]
    old = read_peer(tmp_path / "run.h5")
    assert old.protocol_returns is None and old.finished
    np.testing.assert_array_equal(old.test_returns, result.protocol_returns["as-trained"])


def test_validation_seeds_are_keyed_and_apart_from_test_seeds() -> None:
    seeds = validation_seeds(5, 50)
    assert seeds == validation_seeds(5, 50) != validation_seeds(6, 50)
    assert validation_seeds(5, 10) == seeds[:10]
    assert all(2**31 <= s < 2**32 for s in seeds) and len(set(seeds)) == 50


@pytest.mark.parametrize("protocol", ["as-trained", "greedy"])
def test_the_elite_is_the_generation_best_with_the_highest_validation_mean(
    protocol: str, tmp_path: Path
) -> None:
    one = train_task(_run(test_protocol=protocol), tmp_path / "one.h5")
    assert elite_generation(one) == 3  # K = 1: the last generation's best, as before
    path = train_task(_run(test_protocol=protocol, validation_episodes=6), tmp_path / "k.h5")
    chosen = elite_generation(path)
    seeds = validation_seeds(5, 6)
    means = [
        np.mean(protocol_episodes(path, seeds, g, protocol).returns)  # type: ignore[arg-type]
        for g in range(4)
    ]
    assert means[chosen] == max(means)
    assert chosen == max(g for g in range(4) if means[g] == max(means))


def test_shared_episodes_give_every_individual_of_a_generation_the_same_episode() -> None:
    config = _run(
        epsilon=gnp.Schedule.fixed(0.0),
        alpha=gnp.Schedule.fixed(0.0),
        controller={"tie_break": "first"},
    )
    cfg = config.gnp_config()
    clones = gnp.take(gnp.init_population(cfg, 1, np.random.default_rng(2)), np.zeros(8, int))
    own = generation_lives(config, clones, 1, 0.0, 0.0).returns
    shared_config = config.model_copy(
        update={"training": config.training.model_copy(update={"shared_episodes": True})}
    )
    shared = generation_lives(shared_config, clones, 1, 0.0, 0.0).returns
    assert len(set(shared.tolist())) == 1  # one policy, one episode: one return
    assert len(set(own.tolist())) > 1  # one policy, eight start states


def test_a_task_experiment_reports_a_test_return_per_protocol(tmp_path: Path) -> None:
    data = _spec()
    data["task"] = {
        "id": "CartPole-v1",
        "test_seeds": 3,
        "test_protocol": "greedy",
        "validation_episodes": 2,
        "shared_episodes": True,
    }
    data["comparisons"][0]["metric"] = "test_return_greedy"
    data["comparisons"][1]["metric"] = "test_return_as_trained"
    spec = parse(data, "tiny")
    with in_process_client() as client:
        results = run_experiment(
            spec, "smoke", tmp_path, options=RunOptions(client=client, quiet=True)
        )
    for arm in ("GNP", "RL", "fracnetics"):
        for metric in ("test_return", "test_return_greedy", "test_return_as_trained"):
            assert np.isfinite(results.scalar(metric, arm)).all()
        np.testing.assert_array_equal(
            results.scalar("test_return", arm), results.scalar("test_return_greedy", arm)
        )
    np.testing.assert_array_equal(
        results.scalar("test_return_greedy", "fracnetics"),
        results.scalar("test_return_as_trained", "fracnetics"),
    )
    run = read_peer(next((tmp_path).rglob("RL-seed40.h5")))
    training = run.run.training
    assert (training.test_protocol, training.validation_episodes, training.shared_episodes) == (
        "greedy",
        2,
        True,
    )


def test_a_runs_identity_names_the_new_settings_only_when_set() -> None:
    from app.experiments.ledger import fingerprint
    from app.experiments.planning import plan

    base = plan(parse(_spec(), "tiny"), "smoke", "runs")[2]  # RL, seed 40
    assert '"q0"' not in base.task_json and '"test_protocol"' not in base.task_json
    assert '"p_add_delete"' not in base.task_json
    data = _spec()
    data["arms"][1]["config"]["controller"]["q0"] = -10.0
    tuned = plan(parse(data, "tiny"), "smoke", "runs")[2]
    data = _spec()
    data["task"]["validation_episodes"] = 3
    validated = plan(parse(data, "tiny"), "smoke", "runs")[2]
    data = _spec()
    data["arms"][1]["config"]["evolution"] = {"p_add_delete": 0.1}
    grown = plan(parse(data, "tiny"), "smoke", "runs")[2]
    assert '"p_add_delete":0.1' in grown.task_json
    assert base.name == tuned.name == validated.name == grown.name == "RL-seed40"
    assert len({fingerprint(r) for r in (base, tuned, validated, grown)}) == 4
    assert PeerRun.model_validate_json(tuned.task_json).run.brain.controller.q0 == -10.0


def test_emitting_the_function_gives_a_discrete_task_one_output_per_action() -> None:
    from app.tasks.common import TaskError

    emit = {"processing_output": "function"}
    for task, actions in (("CartPole-v1", 2), ("Acrobot-v1", 3)):
        config = TaskRunConfig(
            task=TaskSettings(id=task),
            brain=GnpSettings(controller=ControllerSettings(method="RL", **emit)),
        )
        assert config.gnp_config().n_outputs == actions
        assert TaskRunConfig(task=TaskSettings(id=task)).gnp_config().n_outputs == 1
    pendulum = TaskRunConfig(
        task=TaskSettings(id="Pendulum-v1"),
        brain=GnpSettings(controller=ControllerSettings(**emit)),
    )
    with pytest.raises(TaskError, match="needs a Discrete action"):
        pendulum.gnp_config()
