"""A Gymnasium task run in the dashboard, in a real browser (headless Chromium).

The dashboard runs in this process on a runs dir holding the demo (a robot run) and a tiny
CartPole task run; the page lists the task run as one, loads it from the Runs tab, and shows
its fitness plot, the task's frame where the arena was (changing as the cart moves) and the
graph following the brain; loading the robot again brings the arena back. Saves
`task-run.png` with the other screenshots (test-output/dashboard/).
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

from app.tasks import train_task

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """The dashboard, in this process, on the demo and a tiny CartPole task run."""
    runs = tmp_path_factory.mktemp("task-dash-runs")
    shutil.copyfile(DEMO, runs / "demo.h5")
    train_task(tiny_task_config(), runs / "cartpole.h5")
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
