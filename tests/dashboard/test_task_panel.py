"""A task run in a dashboard on a server of its own (no browser): listed as a task run, loaded,
replayed; a damaged file or a task whose extra is missing is one line on the page."""

from __future__ import annotations

import shutil
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from page_helpers import DEMO, dashboard_in_process, until
from test_task_replay import tiny_task_config

from app.cli import main
from app.dashboard import tab_task
from app.phases.generations import GenerationSummary
from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, train_task
from app.tasks.fracnetics_arm import documented
from app.tasks.peer import PeerRun, run_peer
from gnp.config import JUDGMENT


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny CartPole run, a copy with a damaged config, and one whose task needs Box2D."""
    directory = tmp_path_factory.mktemp("task-panel-runs")
    good = directory / "cartpole.h5"
    train_task(tiny_task_config(), good)
    shutil.copyfile(good, directory / "damaged.h5")
    with h5py.File(directory / "damaged.h5", "r+") as handle:
        handle.attrs["config"] = "{not json"
    shutil.copyfile(good, directory / "lander.h5")
    with h5py.File(directory / "lander.h5", "r+") as handle:
        config = str(handle.attrs["config"]).replace("CartPole-v1", "LunarLander-v3")
        handle.attrs["config"] = config
        handle.attrs["task"] = "LunarLander-v3"
    return directory


@pytest.fixture(scope="module")
def board(runs: Path) -> Iterator[Any]:
    with dashboard_in_process(runs) as dashboard:
        yield dashboard


def test_gnp_lab_runs_lists_a_task_run(runs: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["runs", "--runs-dir", str(runs)]) == 0
    lines = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()[1:]}
    assert "task CartPole-v1" in lines["cartpole"] and "3/3" in lines["cartpole"]
    assert "finished" in lines["cartpole"] and "unreadable" not in lines["cartpole"]
    assert "unreadable: task run:" in lines["damaged"]


def test_the_page_lists_loads_and_replays_a_task_run(board: Any) -> None:
    assert "| cartpole | task CartPole-v1 | 3/3 |" in board.runs.table.content
    assert "cartpole" in board.runs.run.options and "cartpole" not in board.compare.run_a.options
    board.status.guarded(None, lambda: board.runs.load("cartpole"))
    assert board.task.active and board.status.text.startswith("replaying the best of generation 2")
    assert board.plots.fitness_points == 3
    steps = board.task.replay.t + 100 * board.task.replay.episode
    until(lambda: board.task.replay.t + 100 * board.task.replay.episode > steps + 5)
    until(lambda: board.task.frames > 2)
    assert board.plots.show_line.startswith("on show: task CartPole-v1 · generation 2")
    # A node clicked in the graph is the task brain's, named in the status line.
    with board.lock:
        kinds = board.task.replay.cfg.node_type
        judgment = int(np.flatnonzero(kinds == JUDGMENT)[0])
        board._inspect(judgment)
    assert board.status.text.startswith(f"CartPole-v1 brain: node {judgment} · J f")
    assert board.graph_view.selected == judgment


def test_a_damaged_file_or_a_missing_extra_is_one_line(board: Any) -> None:
    board.status.guarded(None, lambda: board.runs.load("lander"))
    assert board.status.text.startswith("⚠ task 'LunarLander-v3' cannot be made")
    assert "\n" not in board.status.text and "Traceback" not in board.status.text
    board.status.guarded(None, lambda: board.runs.load("damaged"))
    assert board.status.text.startswith("⚠ ")
    assert "\n" not in board.status.text


def test_the_panel_exports_the_task_run(board: Any, runs: Path) -> None:
    board.status.guarded(None, lambda: board.runs.load("cartpole"))
    with board.lock:
        out = board.task.export()
    assert out == runs / "exports" / "cartpole-g2"
    assert sorted(p.name for p in out.iterdir()) == ["controller.json", "fitness.csv"]
    assert board.status.text == f"exported task run cartpole to {out}"


def test_a_run_loaded_while_written_is_followed_to_its_end(board: Any, runs: Path) -> None:
    """A run on show before it finished gains its generations on the plot and the summary as
    its writer (here a thread held after generation 0) writes them; the replay carries on."""
    release, written = threading.Event(), threading.Event()

    def hold(summary: GenerationSummary) -> None:
        if summary.generation == 0:
            written.set()
            assert release.wait(60)

    out = runs / "growing.h5"
    writer = threading.Thread(target=train_task, args=(tiny_task_config(seed=2), out, hold))
    writer.start()
    try:
        assert written.wait(60)
        board.status.guarded(None, lambda: board.runs.load("growing"))
        assert board.task.active and board.plots.fitness_points == 1
        assert "1/3 generations (unfinished: followed" in board.task.summary.content
    finally:
        release.set()
        writer.join(60)
    until(lambda: board.plots.fitness_points == 3)
    until(lambda: "3/3 generations," in board.task.summary.content)
    assert "unfinished" not in board.task.summary.content and board.task.active
    with board.lock:  # the run finished: nothing more is read
        assert board.task._unfinished is None


@pytest.mark.parametrize("settled", [False, True])
def test_an_unchanged_stamp_is_trusted_only_once_settled(
    board: Any, runs: Path, monkeypatch: pytest.MonkeyPatch, settled: bool
) -> None:
    """Two writes in one tick of the file system's clock leave the same stamp: while the file
    has not settled, the run is read again at each poll even though its stamp is unchanged
    (here every stamp is one constant); once settled, an unchanged stamp means no read."""
    release, written = threading.Event(), threading.Event()

    def hold(summary: GenerationSummary) -> None:
        if summary.generation == 0:
            written.set()
            assert release.wait(60)

    monkeypatch.setattr(tab_task, "stamp", lambda _path: (1, 1, 1, 1))
    monkeypatch.setattr(tab_task, "settled", lambda _mark: settled)
    out = runs / f"same-stamp-{settled}.h5"
    writer = threading.Thread(target=train_task, args=(tiny_task_config(seed=3), out, hold))
    writer.start()
    try:
        assert written.wait(60)
        board.status.guarded(None, lambda: board.runs.load(out.stem))
        assert board.plots.fitness_points == 1
    finally:
        release.set()
        writer.join(60)
    if settled:
        with board.lock:
            for _ in range(5):
                board.task.follow()
        assert board.plots.fitness_points == 1  # the same settled stamp: not read
    else:
        until(lambda: board.plots.fitness_points == 3)


def test_an_experiments_task_run_is_replayed_and_a_fracnetics_run_is_one_line(
    board: Any, runs: Path
) -> None:
    """The Experiments tab's *Load run* on a task experiment: our arm's run replays in the task
    panel; a fracnetics arm's file (returns and tests, no individual) is one line, nothing
    changes."""
    folder = runs / "experiments" / "gnp-vs-fracnetics-cartpole" / "small"
    folder.mkdir(parents=True)
    run = TaskRunConfig(
        seed=3,
        task=TaskSettings(id="CartPole-v1"),
        training=TaskTraining(population=6, generations=2, steps=40),
    )
    for brain in ("gnp", "fracnetics"):
        settings = documented("CartPole-v1") if brain == "fracnetics" else None
        peer = PeerRun(brain=brain, run=run, fracnetics=settings, test_seeds=(7, 8))
        run_peer(peer, folder / f"{brain}-seed3.h5")
    board.status.guarded(None, lambda: board.runs.load("cartpole"))  # another run on show
    board.status.guarded(None, lambda: board.experiments.show_run(folder / "gnp-seed3.h5"))
    name = "experiments/gnp-vs-fracnetics-cartpole/small/gnp-seed3"
    assert board.status.text == (
        f"replaying the best of generation 1 of task run {name} on CartPole-v1"
    )
    assert board.task.active and board.task.name == name and board.plots.fitness_points == 2
    board.status.guarded(None, lambda: board.experiments.show_run(folder / "fracnetics-seed3.h5"))
    assert board.status.text.startswith(
        "⚠ experiments/gnp-vs-fracnetics-cartpole/small/fracnetics-seed3 is a fracnetics arm's "
        "run: its returns and test only, no individual to replay"
    )
    assert board.task.name == name and board.task.active  # nothing changed


def test_the_robots_charts_name_no_robot_run_while_a_task_run_is_on_show(
    board: Any, runs: Path
) -> None:
    shutil.copyfile(DEMO, runs / "demo.h5")
    board.status.guarded(None, lambda: board.runs.load("demo"))
    plots = board.plots
    assert plots.reward.title == "Reward per step · demo"
    assert plots.implementation.title.startswith("Implementation phase · demo/")
    board.status.guarded(None, lambda: board.runs.load("cartpole"))
    assert board.task.active
    assert plots.reward.title == "Reward per step (robots on show)"
    assert plots.implementation.title == "Implementation phase"
    assert plots.implementation_line == "implementation: the robot's (none for CartPole-v1)"
    board.status.guarded(None, lambda: board.runs.load("demo"))  # the robot back: its charts
    assert plots.reward.title == "Reward per step · demo" and not board.task.active
    assert plots.implementation.title.startswith("Implementation phase · demo/")
