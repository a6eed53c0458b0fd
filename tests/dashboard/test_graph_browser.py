"""The simplified graph and the second-stage switch in a real browser (headless Chromium).

The dashboard runs in this process so the test can read what the scene draws from the server's
own handles (what the page is sent); the page's controls are driven as a user would, and the
Show tab's line of what the graph draws is read from the page. Saves
`graph-simplified.png` with the other screenshots (test-output/dashboard/).
"""

from __future__ import annotations

import re
import shutil
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from page_helpers import HIDE_WEBGL_NOTICE, RECORD_SENT, TIMEOUT_MS, sent

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]

DEMO = Path(__file__).resolve().parents[2] / "saved_runs" / "demo.h5"


def field(page: Any, label: str) -> Any:
    """The input on the row of a GUI control's label (viser breaks long labels with <wbr>)."""
    row = "ancestor::div[contains(@class, 'mantine-Flex-root')][1]"
    return page.locator(f'xpath=//label[normalize-space(.)="{label}"]/{row}//input').first


def until(condition: Callable[[], bool], seconds: float = 120.0) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, "the server never reached the state"
        time.sleep(0.05)


def graph_line(page: Any, pattern: str) -> re.Match[str]:
    """Wait until the Show tab's line of what the graph draws matches `pattern`."""
    found = page.wait_for_function(
        """(pattern) => {
          const line = [...document.querySelectorAll("p")].find(
            (p) => p.innerText.startsWith("graph: "));
          return line && new RegExp(pattern).test(line.innerText) ? line.innerText : null;
        }""",
        arg=pattern,
        polling=100,
    )
    match = re.search(pattern, found.json_value())
    assert match is not None
    return match


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """The dashboard, in this process, replaying the shipped demo run (a copy of it)."""
    import viser

    from app.dashboard.app import Dashboard

    runs = tmp_path_factory.mktemp("graph-runs")
    shutil.copyfile(DEMO, runs / "demo.h5")
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    dashboard = Dashboard(server, runs, "demo")
    dashboard.stage.speed = 60.0
    yield dashboard
    dashboard.stop()
    server.stop()


def test_the_simplified_graph_draws_less_and_still_marks_the_walk(
    served: Any, browser: Any, screenshots: Path
) -> None:
    from app.views.graph_counts import FULL, SIMPLIFIED

    dashboard = served
    graph = dashboard.graph_view
    page = browser.new_page(viewport={"width": 1600, "height": 900})
    page.set_default_timeout(TIMEOUT_MS)
    page.add_init_script(RECORD_SENT)
    page.goto(f"http://127.0.0.1:{dashboard.server.get_port()}")
    page.add_style_tag(content=HIDE_WEBGL_NOTICE)
    page.get_by_text("Status:").first.wait_for()

    full_line = graph_line(page, r"graph: full · (\d+) nodes · (\d+) connections · (\d+) line")
    full = graph.drawn()
    assert full.mode == FULL
    assert (int(full_line.group(1)), int(full_line.group(2))) == (full.nodes, full.edges)
    until(lambda: dashboard.stage.session.robots[0].t > 150)  # a life under way

    box = field(page, "Graph")

    def pick() -> None:
        box.click()
        page.get_by_role("option", name=SIMPLIFIED, exact=True).click()

    sent(page, pick, SIMPLIFIED)
    until(lambda: graph.mode == SIMPLIFIED)
    simple_line = graph_line(
        page, r"graph: simplified · (\d+) of (\d+) nodes .* · (\d+) transitions taken .* (\d+) line"
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
    graph_line(page, rf"graph: simplified · {drawn.nodes} of ")
    page.wait_for_timeout(1500)  # let software WebGL draw the paused scene
    page.screenshot(path=str(screenshots / "graph-simplified.png"))

    # The second stage's switch, from the Faults tab.
    page.get_by_role("tab", name="Faults").click()
    switch = field(page, "Second stage (BS branch / CS credit)")
    assert switch.is_checked()
    sent(page, switch.uncheck, "false")
    until(lambda: not dashboard.stage.learning.second_stage)
    assert session.learning.second_stage is False
    method = dashboard.stage.show.robots[0].cfg.method
    words = {"BS": "BS takes its greedy", "CS": "CS never takes", "RL": "RL has none"}[method]
    page.get_by_text(re.compile(words)).first.wait_for()
    sent(page, switch.check, "true")
    until(lambda: dashboard.stage.learning.second_stage)

    # The full view is one choice away.
    page.get_by_role("tab", name="Show").click()

    def pick_full() -> None:
        box.click()
        page.get_by_role("option", name=FULL, exact=True).click()

    sent(page, pick_full, FULL)
    graph_line(page, rf"graph: full · {full.nodes} nodes · {full.edges} connections")
    page.close()
