"""The dashboard's replay of a task run, without a server: frames, returns, the graph's node."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import gnp
from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.brains.registry import run_kind
from app.dashboard.task_frame import cartpole_sketch
from app.dashboard.task_replay import (
    TaskReplay,
    TaskReplayRequest,
    action_captions,
    feature_captions,
)
from app.store import RunFileError, list_runs
from app.tasks import (
    ObservationFault,
    TaskError,
    TaskRunConfig,
    TaskSettings,
    TaskTraining,
    read_task_run,
    replay_task,
    train_task,
)
from app.views.genome import genome_view
from gnp import Schedule


def tiny_task_config(seed: int = 1) -> TaskRunConfig:
    """CartPole at a tiny size: 8 individuals, 3 generations, lives of at most 200 steps."""
    return TaskRunConfig(
        seed=seed,
        task=TaskSettings(id="CartPole-v1"),
        brain=GnpSettings(controller=ControllerSettings(method="CS", fuzzy=False)),
        training=TaskTraining(population=8, generations=3, steps=200, epsilon=Schedule.fixed(0.01)),
    )


@pytest.fixture(scope="module")
def task_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("task-runs") / "cartpole.h5"
    train_task(tiny_task_config(), path)
    return path


def test_the_first_episode_is_replay_tasks(task_run: Path) -> None:
    replay = TaskReplay(TaskReplayRequest(task_run, seed=7, greedy=True))
    expected = replay_task(task_run, seed=7, epsilon=0.0)
    replay.step(expected.length - 1)
    assert replay.episode == 0 and replay.t == expected.length - 1
    assert replay.episode_return == pytest.approx(expected.episode_return - 1.0)
    replay.step(1)  # the episode's last step: a new one starts from the next seed
    assert replay.returns == [pytest.approx(expected.episode_return)]
    assert (replay.episode, replay.seed, replay.t, replay.episode_return) == (1, 8, 0, 0.0)
    replay.close()


def test_frames_advance_and_the_return_accumulates(task_run: Path) -> None:
    replay = TaskReplay(TaskReplayRequest(task_run, seed=3))
    first = replay.frame()
    assert first.shape == (400, 600, 3) and first.dtype == np.uint8
    assert replay.advance(0.1) == 3  # 30 steps per second
    replay.step(5)
    assert replay.t == 8 and replay.episode_return == pytest.approx(8.0)  # CartPole: 1 a step
    assert not np.array_equal(replay.frame(), first)  # the cart or pole moved
    replay.playing = False
    assert replay.advance(1.0) == 0
    replay.close()


def test_the_graphs_current_node_follows_the_brain(task_run: Path) -> None:
    replay = TaskReplay(TaskReplayRequest(task_run, seed=2))
    replay.step(1)
    snap = replay.snapshot()
    assert snap.visits[0, 0] == 0  # the start node at an episode's first step
    assert snap.current_node == snap.visits[-1, 0] == replay.current_node
    replay.step(10)
    later = replay.snapshot()
    assert later.current_node == later.visits[-1, 0] == replay.current_node
    assert 0 < later.node_visits.sum() <= len(later.visits)  # this episode's visits
    # Every transition drawn is one of the genome's connections (the brain's own walk).
    edges = {(int(a), int(b)) for a, b in genome_view(replay.cfg, replay.population).edges}
    walked = zip(later.visits[:-1, 0], later.visits[1:, 0], strict=True)
    assert all((int(a), int(b)) in edges for a, b in walked if b != 0)  # 0: a new episode
    words = replay.node_words(later.current_node)
    assert words.startswith(f"node {later.current_node} · ")
    kinds = replay.cfg.node_type
    judgment = int(np.flatnonzero(kinds == gnp.config.JUDGMENT)[0])
    assert " · J f" in replay.node_words(judgment)
    processing = int(np.flatnonzero(kinds == gnp.config.PROCESSING)[0])
    assert " · P action " in replay.node_words(processing)
    replay.close()


def test_observation_faults_break_features(task_run: Path) -> None:
    fault = ObservationFault(step=2, features=(1, 3), mode="dead")
    replay = TaskReplay(TaskReplayRequest(task_run, seed=0, faults=(fault,)))
    assert replay.status().broken == ()
    replay.step(2)
    assert replay.status().broken == (1, 3)
    replay.close()
    with pytest.raises(TaskError, match=r"outside 0\.\.3"):
        TaskReplay(TaskReplayRequest(task_run, faults=(ObservationFault(0, (9,)),)))


def test_captions_name_features_and_actions() -> None:
    assert feature_captions("CartPole-v1", 4) == (
        "f0 cart x",
        "f1 cart v",
        "f2 pole θ",
        "f3 pole ω",
    )
    assert feature_captions("Other-v0", 2) == ("f0", "f1")
    assert action_captions("CartPole-v1", 1, True) == ("action (push ← | →)",)
    assert action_captions("Other-v0", 2, False) == ("a0", "a1")
    assert action_captions("Acrobot-v1", 3, True, per_action=True) == (
        "action 0",
        "action 1",
        "action 2",
    )


def test_a_run_whose_processing_nodes_emit_their_function_replays(tmp_path: Path) -> None:
    config = tiny_task_config().model_copy(update={"task": TaskSettings(id="Acrobot-v1")})
    config = config.model_copy(
        update={
            "brain": config.brain.model_copy(
                update={
                    "controller": config.brain.controller.model_copy(
                        update={"processing_output": "function"}
                    )
                }
            )
        }
    )
    path = train_task(config, tmp_path / "acrobot.h5")
    replay = TaskReplay(TaskReplayRequest(path, seed=3, greedy=True))
    expected = replay_task(path, seed=3, epsilon=0.0)
    replay.step(expected.length)
    assert replay.returns == [pytest.approx(expected.episode_return)]
    processing = np.flatnonzero(replay.cfg.node_type == gnp.config.PROCESSING)
    functions = replay.population.function[0, processing, 0]
    for node, f in zip(processing, functions, strict=True):
        assert replay.node_words(int(node)).startswith(f"node {node} · P action {f}")
    from app.dashboard.task_replay import captions
    from app.views.graph_layout import graph_layout

    outputs = captions(replay.cfg, replay.adapter, "Acrobot-v1")
    view = genome_view(replay.cfg, replay.population, None, outputs)
    layout = graph_layout(view.kinds, view.column_function, 100.0, 100.0, None, outputs)
    assert layout.positions.shape == (replay.cfg.n_nodes, 2)  # a column per action
    replay.close()


def test_the_sketch_draws_the_pole_where_it_leans() -> None:
    upright = cartpole_sketch(np.zeros(4))
    leaning = cartpole_sketch(np.array([0.0, 0.0, 0.3, 0.0]))
    assert upright.shape == (400, 600, 3)
    pole = np.all(upright == (202, 152, 101), axis=2)
    assert pole.any() and not np.array_equal(upright, leaning)
    # Leaning right (θ > 0): the pole's pixels high up are right of the cart's centre.
    top = np.all(leaning[:200] == (202, 152, 101), axis=2)
    assert np.flatnonzero(top.any(axis=0)).mean() > 300


def test_a_corrupt_or_foreign_file_is_one_line(task_run: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not hdf5")
    with pytest.raises(RunFileError, match="not an HDF5 file"):
        TaskReplay(TaskReplayRequest(bad))
    with pytest.raises(RunFileError, match=r"generations 0\.\.2, not 5"):
        TaskReplay(TaskReplayRequest(task_run, generation=5))


def test_the_catalogue_lists_a_task_run(task_run: Path) -> None:
    (summary,) = [s for s in list_runs(task_run.parent) if s.name == "cartpole"]
    assert summary.error is None and summary.task == "CartPole-v1"
    assert run_kind(summary) == "task CartPole-v1"
    assert (summary.generations_done, summary.generations, summary.finished) == (3, 3, True)
    assert summary.best_fitness == read_task_run(task_run).fitness.max()
