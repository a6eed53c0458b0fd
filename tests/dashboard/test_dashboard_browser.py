"""The dashboard in a real browser: headless Chromium drives the page like a user would.

Observations come from the page itself (the readout and status lines), never from test hooks.
Each state is saved as a screenshot under test-output/dashboard/.
"""

from __future__ import annotations

import contextlib
import os
import re
import time
from pathlib import Path
from typing import Any

import pytest

# One server and one page per module, used in order (pytest-xdist: run with --dist loadgroup).
pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]


def viewport() -> dict[str, int]:
    """1280x720 by default (software WebGL is slow); GNP_LAB_VIEWPORT=1600x900 for docs."""
    width, height = os.environ.get("GNP_LAB_VIEWPORT", "1280x720").split("x")
    return {"width": int(width), "height": int(height)}


def open_page(browser: Any, url: str) -> Any:
    page = browser.new_page(viewport=viewport())
    page.goto(url)
    page.get_by_text("Status:").first.wait_for(timeout=60_000)
    webgl = page.locator(".mantine-Notification-root", has_text="Software WebGL")
    with contextlib.suppress(Exception):  # cosmetic; a machine with a GPU never shows it
        webgl.get_by_role("button").first.click(timeout=3_000)
    return page


def on_show(page: Any) -> str:
    """The Show tab's description of what is on show."""
    return str(page.get_by_text(re.compile("^On show:")).first.locator("..").inner_text())


def wait_for(page: Any, pattern: str, timeout: float = 60.0) -> re.Match[str]:
    """Wait until the readout matches `pattern`; return the match."""
    deadline = time.monotonic() + timeout
    text = ""
    while time.monotonic() < deadline:
        page.wait_for_timeout(250)
        text = page.get_by_text(re.compile("^on show:")).first.locator("..").inner_text()
        match = re.search(pattern, text)
        if match:
            return match
    raise AssertionError(f"readout never matched {pattern!r}; last readout:\n{text}")


def status(page: Any) -> str:
    return str(page.get_by_text(re.compile("^Status:")).first.locator("..").inner_text())


def step_of(page: Any) -> int:
    return int(wait_for(page, r"on show: step (\d+)").group(1))


def field(page: Any, label: str) -> Any:
    """The input on the row of a GUI control's label (viser does not always link the two)."""
    row = "ancestor::div[contains(@class, 'mantine-Flex-root')][1]"
    return page.locator(f'xpath=//label[normalize-space(text())="{label}"]/{row}//input').first


def choose(page: Any, label: str, option: str) -> None:
    field(page, label).click()
    page.get_by_role("option", name=option, exact=True).click()


def type_into(page: Any, label: str, value: str) -> None:
    box = field(page, label)
    box.fill(value)
    box.press("Enter")
    box.blur()


@pytest.fixture(scope="module")
def page(browser: Any, dashboard_url: str) -> Any:
    page = open_page(browser, dashboard_url)
    yield page
    page.close()


def test_page_shows_a_run_that_moves(page: Any, screenshots: Path) -> None:
    wait_for(page, r"on show: step [1-9]")
    assert "cs (CS, fuzzy)" in on_show(page)
    first = step_of(page)
    page.wait_for_timeout(1500)
    # Moving on (a new life from the next start pose after T steps also counts).
    assert step_of(page) != first, "the live robot must keep stepping"
    assert re.search(r"fitness plot: 2 generations", page.content())
    page.screenshot(path=str(screenshots / "arena-graph.png"))


def test_break_a_sensor_marks_it_and_the_reward_curve_reacts(page: Any, screenshots: Path) -> None:
    page.get_by_role("tab", name="Faults").click()
    type_into(page, "Sensors to break", "9")
    page.get_by_role("button", name="Break now").click()
    page.get_by_text(re.compile("sensors are numbered 0..7")).first.wait_for(timeout=10_000)
    assert "broken: none" in wait_for(page, r"broken: none").group(0), "a bad value changes nothing"

    type_into(page, "Sensors to break", "2,3")
    choose(page, "Fault mode", "saturated")
    page.get_by_role("button", name="Break now").click()
    match = wait_for(page, r"broken: s2, s3 \(saturated\) since step (\d+)")
    fault = int(match.group(1))
    reaction = wait_for(
        page, rf"fault marked at step {fault} · reward/step before ([\d.]+), after ([\d.]+)"
    )
    assert float(reaction.group(1)) != float(reaction.group(2))
    page.wait_for_timeout(1500)
    page.screenshot(path=str(screenshots / "faults.png"))

    page.get_by_role("button", name="Repair all").click()
    wait_for(page, r"broken: none")


def test_train_from_the_controls_grows_the_fitness_plot(page: Any, screenshots: Path) -> None:
    page.get_by_role("tab", name="Train").click()
    choose(page, "Method", "RL")
    type_into(page, "Population", "8")
    type_into(page, "Generations", "3")
    type_into(page, "Life T (steps)", "60")
    page.get_by_role("button", name="Start").click()
    started = wait_for(page, r"training: (?:started|running)[^\n]*\n.*fitness plot: (\d+)")
    assert int(started.group(1)) < 3
    wait_for(page, r"on show: .*RL-fuzzy", timeout=120)  # each new best is replayed at once
    page.screenshot(path=str(screenshots / "training.png"))
    wait_for(page, r"training: finished · generation 3/3 · best [\d.]+", timeout=120)
    wait_for(page, r"fitness plot: 3 generations")
    assert "⚠" not in status(page)


def test_pause_and_stop_training(page: Any) -> None:
    page.get_by_role("tab", name="Train").click()
    type_into(page, "Population", "8")
    type_into(page, "Life T (steps)", "60")
    type_into(page, "Generations", "5000")
    page.get_by_role("button", name="Start").click()
    wait_for(page, r"training: running · generation [1-9]", timeout=120)
    page.get_by_role("button", name="Pause").click()
    paused = int(wait_for(page, r"training: paused · generation (\d+)").group(1))
    page.wait_for_timeout(1500)
    # At most the generation in flight completes after SIGSTOP reached the group.
    assert int(wait_for(page, r"training: paused · generation (\d+)").group(1)) <= paused + 1
    before = step_of(page)
    page.wait_for_timeout(600)
    assert step_of(page) != before, "the page stays live while training is paused"
    page.get_by_role("button", name="Resume").click()
    wait_for(page, r"training: running", timeout=10)
    page.get_by_role("button", name="Stop").click()
    stopped = wait_for(page, r"training: stopped · generation (\d+)/5000", timeout=60)
    assert int(stopped.group(1)) < 5000


def test_load_a_saved_run_replay_and_implement(page: Any, screenshots: Path) -> None:
    page.get_by_role("tab", name="Runs").click()
    page.get_by_role("button", name="Refresh list").click()
    choose(page, "Run", "bs")
    page.get_by_role("button", name="Load").click()
    page.get_by_text(re.compile("loaded run bs")).first.wait_for(timeout=10_000)
    choose(page, "Replay in", "implementation")
    page.get_by_role("button", name="Replay best individual").click()
    wait_for(page, r"on show: step \d+ · bs: reward/step")
    assert "implementation arena" in on_show(page)
    type_into(page, "Steps T", "300")
    type_into(page, "Fault step t'", "100")
    type_into(page, "Repeats per start pose", "1")
    page.get_by_role("button", name="Run implementation").click()
    match = wait_for(
        page,
        r"implementation: bs · 10 trials · breaks s2, s3 \(dead\) at 100 · mean reward/step "
        r"([\d.]+), after the fault ([\d.]+)",
        timeout=120,
    )
    assert 0.0 <= float(match.group(1)) <= 1.0
    page.screenshot(path=str(screenshots / "runs.png"))


def test_compare_two_runs_after_the_same_fault(page: Any, screenshots: Path) -> None:
    page.get_by_role("tab", name="Compare").click()
    choose(page, "Run A (blue)", "bs")
    choose(page, "Run B (orange)", "cs")
    type_into(page, "At step", "40")
    page.get_by_role("button", name="Compare").click()
    wait_for(page, r"on show: step \d+ · bs: reward/step [\d.]+ · cs: reward/step")
    wait_for(page, r"broken: s2, s3 \(dead\) since step 40", timeout=30)
    page.wait_for_timeout(2500)
    page.screenshot(path=str(screenshots / "compare.png"))


def test_tabs_share_state_and_closing_one_leaves_the_server_healthy(
    page: Any, browser: Any, dashboard_url: str
) -> None:
    other = open_page(browser, dashboard_url)
    page.get_by_role("tab", name="Faults").click()
    page.get_by_role("button", name="Repair all").click()
    wait_for(other, r"broken: none")
    type_into(page, "Sensors to break", "5")
    page.get_by_role("button", name="Break now").click()
    wait_for(other, r"broken: s5 \(")  # the other tab sees the same robot
    other.close()
    before = step_of(page)
    page.wait_for_timeout(1000)
    assert step_of(page) != before, "the server carries on after a tab closed"
    page.get_by_role("button", name="Repair all").click()
    wait_for(page, r"broken: none")
