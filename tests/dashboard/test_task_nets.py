"""A net's task run on the dashboard (issue #46 item 2): its best replays on the task through the
brain contract, the episode `replay_task` lives, and the task panel draws its network (at the
task's sizes, captioned so) where GNP's graph would be."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from page_helpers import dashboard_in_process, until

import neuro
from app.brains.net_settings import NetSettings
from app.dashboard.network import io_captions
from app.dashboard.task_replay import TaskReplay, TaskReplayRequest
from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, replay_task, train_task

HIDDEN = 3


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny CartPole run of an Elman net evolved by CMA-ES."""
    directory = tmp_path_factory.mktemp("task-net-runs")
    config = TaskRunConfig(
        seed=2,
        task=TaskSettings(id="CartPole-v1"),
        brain=NetSettings(family="cmaes", hidden=HIDDEN),
        training=TaskTraining(population=8, generations=2, steps=120),
    )
    train_task(config, directory / "elman.h5")
    return directory


def test_the_first_episode_is_replay_tasks(runs: Path) -> None:
    path = runs / "elman.h5"
    expected = replay_task(path, seed=11)
    replay = TaskReplay(TaskReplayRequest(path, seed=11))
    assert replay.cfg is None and isinstance(replay.net, neuro.ElmanConfig)
    assert (replay.net.n_inputs, replay.net.n_outputs) == (4, 1)  # CartPole's features, 1 output
    replay.step(expected.length)
    assert replay.returns == [pytest.approx(expected.episode_return)]
    assert (replay.episode, replay.seed, replay.t) == (1, 12, 0)


def test_the_snapshot_carries_the_nets_activations(runs: Path) -> None:
    replay = TaskReplay(TaskReplayRequest(runs / "elman.h5", seed=3))
    replay.step(1)
    first = replay.snapshot()
    replay.step(1)
    second = replay.snapshot()
    assert first.activation.shape == (HIDDEN,)  # an Elman net's units: its hidden layer
    np.testing.assert_array_equal(second.context, first.activation)  # what t-1 held
    assert second.seen_readings.shape == (4,) and second.commands.shape == (1,)
    assert second.seen_readings.min() >= 0.0 and second.seen_readings.max() <= 1023.0
    assert not second.learns_online and first.method == "Elman"  # the family's label
    assert replay.node_words(0).startswith("cmaes: Elman net, 3 hidden · outputs ")


def test_captions_name_a_tasks_inputs_and_outputs() -> None:
    task_net = neuro.ElmanConfig(n_inputs=4, n_outputs=1, hidden=HIDDEN)
    assert io_captions(task_net) == ("inputs s0–s3", "outputs y0")
    assert io_captions(neuro.ElmanConfig(hidden=HIDDEN)) == ("IR in s0–s7", "wheels (left, right)")


@pytest.fixture(scope="module")
def board(runs: Path) -> Iterator[Any]:
    with dashboard_in_process(runs) as dashboard:
        yield dashboard


def test_the_panel_draws_the_nets_network(board: Any) -> None:
    assert "| elman | task CartPole-v1 (cmaes) | 2/2 |" in board.runs.table.content
    board.status.guarded(None, lambda: board.runs.load("elman"))
    assert board.task.active, board.status.text
    assert board.task.network.visible and not board.task.graph.visible
    drawn = board.task.network.drawn()
    assert drawn.nodes == 4 + HIDDEN + HIDDEN + 1  # inputs, context, hidden, output
    assert drawn.layers == "Elman · 4 in · 3 context t−1 · 3 hidden · 1 out · 24 weights"
    colours = board.task.network.node_colors.copy()
    until(lambda: board.task.replay.t > 5 or board.task.replay.episode > 0)
    until(lambda: not np.array_equal(board.task.network.node_colors, colours))  # live units
    assert board.plots.show_line.startswith("on show: task CartPole-v1 · generation 1")
