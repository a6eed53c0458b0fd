"""The simplified graph and the second-stage switch in a real browser (headless Chromium).

The dashboard runs in this process so the test can read what the scene draws from the server's
own handles (what the page is sent); the page's controls are driven as a user would, and the
Show tab's line of what the graph draws is read from the page. Saves
`graph-simplified.png` with the other screenshots (test-output/dashboard/).
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
    sent,
    until,
    wait_for_line,
)

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """The dashboard, in this process, replaying the shipped demo run (a copy of it)."""
    runs = tmp_path_factory.mktemp("graph-runs")
    shutil.copyfile(DEMO, runs / "demo.h5")
    with dashboard_in_process(runs, "demo") as dashboard:
        dashboard.stage.speed = 60.0
        yield dashboard


def test_the_simplified_graph_draws_less_and_still_marks_the_walk(
    served: Any, browser: Any, screenshots: Path
) -> None:
    from app.views.graph_counts import FULL, SIMPLIFIED

    dashboard = served
    graph = dashboard.graph_view
    url = f"http://127.0.0.1:{dashboard.server.get_port()}"
    page = open_page(browser, url, {"width": 1600, "height": 900})

    wait_for_line(page, "graph: ", r"graph: simplified · ")  # the page opens on what it runs
    assert graph.mode == SIMPLIFIED
    choose(page, "Graph", FULL)
    until(lambda: graph.mode == FULL)
    full_pattern = r"graph: full · (\d+) nodes · (\d+) connections · (\d+) line"
    full_line = wait_for_line(page, "graph: ", full_pattern)
    full = graph.drawn()
    assert full.mode == FULL
    assert (int(full_line.group(1)), int(full_line.group(2))) == (full.nodes, full.edges)
    until(lambda: dashboard.stage.session.robots[0].t > 150)  # a life under way

    choose(page, "Graph", SIMPLIFIED)
    until(lambda: graph.mode == SIMPLIFIED)
    simple_line = wait_for_line(
        page,
        "graph: ",
        r"graph: simplified · (\d+) of (\d+) nodes .* · (\d+) transitions taken .* (\d+) line",
    )
    nodes, total, edges, segments = (int(g) for g in simple_line.groups())
    assert nodes < total == full.nodes
    assert edges < full.edges and segments < full.segments

    # Pause, then compare the marks drawn with the robot's own state.
    dashboard.stage.playing = False
    session = dashboard.stage.session
    with dashboard.lock:
        snapshot = session.snapshot()[0]
        graph.update(snapshot)
        drawn = graph.drawn()
        positions = graph._origin + graph.layout.positions
        ring = graph._current.points.reshape(-1, 3)[:, :2].mean(axis=0)
        shaft = graph._recent.points[-3]
        shown = set(graph._shown_nodes.tolist())
        inspected = int(snapshot.visits[-1, 0])
        dashboard.show.inspect(inspected)
    assert drawn.mode == SIMPLIFIED and drawn.nodes < full.nodes and drawn.edges < full.edges
    assert np.allclose(ring, positions[snapshot.current_node], atol=1e-3)  # current node ringed
    last_from, last_to = int(snapshot.visits[-2, 0]), int(snapshot.visits[-1, 0])
    assert {last_from, last_to} <= shown  # the last transition's nodes are drawn...
    (dx, dy), (ex, ey) = shaft[1, :2] - shaft[0, :2], positions[last_to] - positions[last_from]
    assert abs(dx * ey - dy * ex) < 1e-4 and dx * ex + dy * ey >= 0  # ...and its arrow
    page.get_by_text(re.compile(rf"^Node {inspected} ")).first.wait_for()  # inspector still on
    wait_for_line(page, "graph: ", rf"graph: simplified · {drawn.nodes} of ")
    page.wait_for_timeout(1500)  # let software WebGL draw the paused scene
    page.screenshot(path=str(screenshots / "graph-simplified.png"))

    # The second stage's switch, from the Faults tab.
    page.get_by_role("tab", name="Faults").click()
    switch = field(page, "Second stage (BS branch / CS credit)")
    assert switch.is_checked()
    sent(page, switch.uncheck, "false")
    until(lambda: not dashboard.stage.learning.second_stage)
    assert session.learning.second_stage is False
    method = dashboard.stage.show.robots[0].family.label
    words = {"BS": "BS takes its greedy", "CS": "CS never takes", "RL": "RL has none"}[method]
    page.get_by_text(re.compile(words)).first.wait_for()
    sent(page, switch.check, "true")
    until(lambda: dashboard.stage.learning.second_stage)

    # The full view is one choice away.
    page.get_by_role("tab", name="Show").click()

    choose(page, "Graph", FULL)
    wait_for_line(page, "graph: ", rf"graph: full · {full.nodes} nodes · {full.edges} connections")
    page.close()
