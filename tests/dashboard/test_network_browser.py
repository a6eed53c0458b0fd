"""A neural run in a real browser (headless Chromium): loaded from the Runs tab while a GNP run is
on show, replayed in the implementation arena, its network drawn in the graph panel, then its
implementation phase run with a fault.

The dashboard runs in this process so the test can read the scene from the server's own
handles (what the page is sent); the page is driven as a user would and its lines are read from
the page. Saves `network.png` with the other screenshots (test-output/dashboard/).
"""

from __future__ import annotations

import re
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
    field,
    open_page,
    press,
    until,
    wait_for_line,
)

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]


@pytest.fixture(scope="module")
def served(net_runs_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """The dashboard, in this process, showing the demo (GNP) beside a tiny trained net run."""
    runs = tmp_path_factory.mktemp("network-runs")
    shutil.copyfile(DEMO, runs / "demo.h5")
    shutil.copyfile(net_runs_dir / "elman.h5", runs / "elman.h5")
    with dashboard_in_process(runs, "demo") as dashboard:
        dashboard.stage.speed = 60.0
        yield dashboard


def test_a_neural_run_on_the_stage_shows_its_network(
    served: Any, browser: Any, screenshots: Path
) -> None:
    import neuro

    dashboard = served
    network, graph = dashboard.network_view, dashboard.graph_view
    assert graph.visible and not network.visible  # the demo's GNP graph first
    page = open_page(browser, f"http://127.0.0.1:{dashboard.server.get_port()}")

    page.get_by_role("tab", name="Runs").click()
    choose(page, "Run", "elman")
    press(page, "Load")
    wait_for_line(page, "elman", r"cmaes: Elman net, 6 hidden")
    choose(page, "Replay in", "implementation")
    press(page, "Replay best individual")
    wait_for_line(page, "on show:", r"elman: reward/step [\d.]+ · wheels [-+][\d.]+ [-+][\d.]+")

    page.get_by_role("tab", name="Show").click()
    # 8 × 6 input weights, 6 × 6 context weights, 6 × 2 wheel weights: one line segment each.
    wait_for_line(
        page,
        "network: ",
        r"network: Elman · 8 IR in · 6 context t−1 · 6 hidden · 2 wheels · 96 weights · "
        r"96 line segments",
    )
    assert network.visible and not graph.visible
    show = dashboard.stage.show
    assert show.arena == "implementation" and show.robots[
        0
    ].family.network_config == neuro.ElmanConfig(hidden=6)
    assert network._edges.points.shape == (96, 2, 3)
    assert field(page, "Inspect node").is_disabled() and field(page, "Graph").is_disabled()
    page.get_by_text(re.compile("^Elman net: 8 IR readings")).first.wait_for()

    # Live: the nodes take the colours of what the net computes at each step.
    first = network.node_colors.copy()
    until(lambda: not np.array_equal(network.node_colors, first))
    with dashboard.lock:
        robot = dashboard.stage.session.snapshot()[0]
        network.update(robot)
        from app.dashboard.network import activation_colors, node_values

        values = node_values(
            network.layout, robot.activation, robot.context, robot.seen_readings, robot.commands
        )
        assert np.array_equal(network.node_colors, activation_colors(values))
    page.wait_for_timeout(1500)  # let software WebGL draw the network
    page.screenshot(path=str(screenshots / "network.png"))

    # Its implementation phase, with the run's fault (s2, s3 dead at t' = 60 of T = 120).
    page.get_by_role("tab", name="Runs").click()
    press(page, "Run implementation")
    match = wait_for_line(
        page,
        "on show:",
        r"implementation: elman/break-2-3-dead-[\w.-]+ · 10 trials · breaks s2, s3 \(dead\) at 60 "
        r"· mean reward/step "
        r"([\d.]+)",
    )
    assert 0.0 <= float(match.group(1)) <= 1.0
    page.close()
