"""A Gymnasium task run in the dashboard, in a real browser (headless Chromium).

The dashboard runs in this process on a runs dir holding the demo (a robot run) and a tiny
CartPole task run; the page lists the task run as one, loads it from the Runs tab, and shows
its fitness plot, the task's frame where the arena was (changing as the cart moves) and the
graph following the brain; loading the robot again brings the arena back. A CMA-ES net's task
run shows its network instead, live. Saves `task-run.png` and `task-run-net.png` with the other
screenshots (test-output/dashboard/).
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from page_helpers import (
    DEMO,
    choose,
    dashboard_in_process,
    open_page,
    press,
    type_into,
    until,
    wait_for_line,
)
from test_task_replay import tiny_task_config

from app.brains.net_settings import NetSettings
from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, train_task

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """The dashboard, in this process, on the demo and a tiny CartPole task run."""
    runs = tmp_path_factory.mktemp("task-dash-runs")
    shutil.copyfile(DEMO, runs / "demo.h5")
    train_task(tiny_task_config(), runs / "cartpole.h5")
    elman = TaskRunConfig(
        seed=2,
        task=TaskSettings(id="CartPole-v1"),
        brain=NetSettings(family="cmaes", hidden=3),
        training=TaskTraining(population=8, generations=2, steps=120),
    )
    train_task(elman, runs / "elman.h5")
    with dashboard_in_process(runs, "demo") as dashboard:
        yield dashboard


def test_a_task_run_loads_and_replays_on_its_task(
    served: Any, browser: Any, screenshots: Path
) -> None:
    dashboard = served
    url = f"http://127.0.0.1:{dashboard.server.get_port()}"
    page = open_page(browser, url, {"width": 1600, "height": 900})
    page.get_by_role("tab", name="Runs").click()
    page.get_by_text("task CartPole-v1").first.wait_for()  # listed as a task run, not unreadable
    assert page.get_by_text("unreadable").count() == 0

    choose(page, "Run", "cartpole")
    press(page, "Load")
    first = wait_for_line(page, "on show: task CartPole-v1", r"step (\d+) · return (\d+)")
    # The readout's paragraph also says what the fitness plot holds: best/mean per generation.
    wait_for_line(page, "on show: task CartPole-v1", r"fitness plot: 3 generations")
    page.get_by_text("is a task run").first.wait_for()
    assert dashboard.task.active and dashboard.task.image.visible
    # The robot's controls are off for a task run, with a note that says so.
    assert page.get_by_role("button", name="Replay best individual").is_disabled()
    page.get_by_text("are the robot's and are off for it").first.wait_for()

    # The replay goes on: steps and returns move, the frame changes, the graph follows.
    frames = dashboard.task.frames
    later = wait_for_line(
        page, "on show: task CartPole-v1", rf"episode \d+ · step (?!{first.group(1)}\b)\d+"
    )
    assert later
    until(lambda: dashboard.task.frames > frames + 5)
    with dashboard.lock:
        replay = dashboard.task.replay
        snapshot = replay.snapshot()
        graph = dashboard.graph_view
        graph.update(snapshot)
        ring = graph._current.points.reshape(-1, 3)[:, :2].mean(axis=0)
        node = graph._origin + graph.layout.positions[replay.current_node]
        assert np.allclose(ring, node, atol=1e-3)  # the ring on the brain's current node
        assert graph.layout.column_names[1] == "f0 cart x"
    # The readout names the node the brain is at.
    wait_for_line(page, "on show: task CartPole-v1", r"node \d+ · [JPs]")

    canvas = page.locator("canvas").first
    shot = canvas.screenshot()
    page.wait_for_timeout(1500)
    assert canvas.screenshot() != shot  # the frame (and graph) moved on in the page
    page.screenshot(path=str(screenshots / "task-run.png"))

    # An observation fault on the replay: features 2,3 die from step 5.
    type_into(page, "Break features", "2,3")
    type_into(page, "Feature fault step", "5")
    press(page, "Replay on task")
    wait_for_line(page, "on show: task CartPole-v1", r"broken features: f2, f3")

    # A robot run again: the arena is back, the task's frame hidden.
    choose(page, "Run", "demo")
    press(page, "Load")
    press(page, "Replay best individual")
    until(lambda: not dashboard.task.active and not dashboard.task.image.visible)
    wait_for_line(page, "on show: step", r"reward/step")
    page.close()


def test_a_nets_task_run_shows_its_network_live(
    served: Any, browser: Any, screenshots: Path
) -> None:
    dashboard = served
    url = f"http://127.0.0.1:{dashboard.server.get_port()}"
    page = open_page(browser, url, {"width": 1600, "height": 900})
    page.get_by_role("tab", name="Runs").click()
    page.get_by_text("task CartPole-v1 (cmaes)").first.wait_for()
    choose(page, "Run", "elman")
    press(page, "Load")
    wait_for_line(page, "on show: task CartPole-v1", r"cmaes: Elman net, 3 hidden · outputs [+-]")
    assert dashboard.task.network.visible and not dashboard.task.graph.visible
    colours = dashboard.task.network.node_colors.copy()
    until(lambda: not np.array_equal(dashboard.task.network.node_colors, colours))
    canvas = page.locator("canvas").first
    shot = canvas.screenshot()
    page.wait_for_timeout(1500)
    assert canvas.screenshot() != shot  # the frame and the units moved on in the page
    page.screenshot(path=str(screenshots / "task-run-net.png"))
    page.close()
