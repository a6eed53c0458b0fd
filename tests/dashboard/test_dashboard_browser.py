"""The dashboard in a real browser: headless Chromium drives the page like a user would.

Observations come from the page itself (the readout and status lines), never from test hooks.
Every wait is for a state of the page, never for a length of time: the machine may be loaded.
Each state is saved as a screenshot under test-output/dashboard/.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from page_helpers import TIMEOUT_MS, choose, field, open_page, press, sent, type_into

# One server and one page per module, used in order (pytest-xdist: run with --dist loadgroup).
pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]


READOUT_MATCH = """([pattern, atLeast]) => {
  const readout = [...document.querySelectorAll("p")].find(
    (p) => p.innerText.startsWith("on show:"));
  const match = readout && new RegExp(pattern).exec(readout.innerText);
  return match && (atLeast === null || Number(match[1]) >= atLeast) ? match[0] : null;
}"""


def readout(page: Any) -> str:
    return str(page.get_by_text(re.compile("^on show:")).first.inner_text())


def wait_for(page: Any, pattern: str, at_least: int | None = None) -> re.Match[str]:
    """Wait until the readout matches `pattern` (with its first group ≥ `at_least` if given).

    The pattern is matched in the page (a JavaScript RegExp, same syntax here) each 100 ms, so
    the match returned is the text as it was, not as it is a moment later.
    """
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    try:
        found = page.wait_for_function(
            READOUT_MATCH, arg=[pattern, at_least], polling=100, timeout=TIMEOUT_MS
        )
    except PlaywrightTimeout:
        raise AssertionError(
            f"readout never matched {pattern!r}; last readout:\n{readout(page)}"
        ) from None
    match = re.search(pattern, found.json_value())
    assert match is not None
    return match


def step_of(page: Any) -> int:
    return int(wait_for(page, r"on show: step (\d+)").group(1))


def later_step(page: Any, than: int) -> int:
    """Wait until the robot on show is at another step than `than` (it moved on)."""
    return int(wait_for(page, rf"on show: step (?!{than} )(\d+)").group(1))


def on_show(page: Any) -> Any:
    """The Show tab's description of what is on show."""
    return page.get_by_text(re.compile("^On show:")).first.locator("..")


def status(page: Any) -> str:
    return str(page.get_by_text(re.compile("^Status:")).first.locator("..").inner_text())


@pytest.fixture(scope="module")
def page(browser: Any, dashboard_url: str) -> Iterator[Any]:
    page = open_page(browser, dashboard_url)
    yield page
    page.close()


def test_page_shows_a_run_that_moves(page: Any, screenshots: Path) -> None:
    from playwright.sync_api import expect

    first = int(wait_for(page, r"on show: step ([1-9]\d*)").group(1))
    expect(on_show(page)).to_contain_text("cs (CS fuzzy)", timeout=TIMEOUT_MS)
    # Moving on (a new life from the next start pose after T steps also counts).
    later_step(page, first)
    wait_for(page, r"fitness plot: 2 generations")
    page.screenshot(path=str(screenshots / "arena-graph.png"))


def test_break_a_sensor_marks_it_and_the_reward_curve_reacts(page: Any, screenshots: Path) -> None:
    from playwright.sync_api import expect

    page.get_by_role("tab", name="Faults").click()
    type_into(page, "Sensors to break", "9")
    press(page, "Break now")
    notification = page.locator(".mantine-Notification-root", has_text="Not applied")
    expect(notification.filter(has_text="sensor index 9 is not in 0..7").first).to_be_visible(
        timeout=TIMEOUT_MS
    )
    assert "⚠ sensor index 9 is not in 0..7" in status(page)
    wait_for(page, r"broken: none")  # a bad value changes nothing

    type_into(page, "Sensors to break", "2,3")
    choose(page, "Fault mode", "saturated")
    press(page, "Break now")
    match = wait_for(page, r"sensors 2,3 broken \(saturated\) since step (\d+)")
    fault = int(match.group(1))
    reaction = wait_for(
        page, rf"fault marked at step {fault} · reward/step before ([\d.]+), after ([\d.]+)"
    )
    assert float(reaction.group(1)) != float(reaction.group(2))
    wait_for(page, r"on show: step (\d+)", at_least=fault + 45)  # a trail after the fault
    page.screenshot(path=str(screenshots / "faults.png"))

    press(page, "Repair all")
    wait_for(page, r"broken: none")


def test_train_from_the_controls_grows_the_fitness_plot(page: Any, screenshots: Path) -> None:
    page.get_by_role("tab", name="Train").click()
    choose(page, "Method", "RL")
    type_into(page, "Population", "8")
    type_into(page, "Generations", "3")
    type_into(page, "Life T (steps)", "60")
    press(page, "Start")
    started = wait_for(page, r"training: (?:started|running)[^\n]*\n.*fitness plot: (\d+)")
    assert int(started.group(1)) < 3
    wait_for(page, r"on show: .*RL-fuzzy")  # each new best is replayed at once
    page.screenshot(path=str(screenshots / "training.png"))
    wait_for(page, r"training: finished · generation 3/3 · best [\d.]+")
    wait_for(page, r"fitness plot: 3 generations")
    assert "⚠" not in status(page)


def test_pause_and_stop_training(page: Any) -> None:
    from playwright.sync_api import expect

    page.get_by_role("tab", name="Show").click()
    new_lives = field(page, "New life every T steps")
    if new_lives.is_checked():  # endless lives: the step count is the page's clock below
        sent(page, new_lives.uncheck, "false")
    expect(new_lives).not_to_be_checked(timeout=TIMEOUT_MS)
    page.get_by_role("tab", name="Train").click()
    expect_buttons(page, enabled={"Start"})  # no training: nothing to pause, resume or stop
    type_into(page, "Population", "8")
    type_into(page, "Life T (steps)", "60")
    type_into(page, "Generations", "5000")
    press(page, "Start")
    wait_for(page, r"training: running · generation [1-9]")
    expect_buttons(page, enabled={"Pause", "Stop"})
    press(page, "Pause")
    paused = int(wait_for(page, r"training: paused · generation (\d+)").group(1))
    expect_buttons(page, enabled={"Resume", "Stop"})
    # The page stays live while training is paused: the robot lives 45 more steps, in which
    # at most the generation in flight when Pause was pressed completes.
    before = step_of(page)
    wait_for(page, r"on show: step (\d+)", at_least=before + 45)
    assert int(wait_for(page, r"training: paused · generation (\d+)").group(1)) <= paused + 1
    press(page, "Resume")
    wait_for(page, r"training: running")
    press(page, "Stop")
    stopped = wait_for(page, r"training: stopped · generation (\d+)/5000")
    assert int(stopped.group(1)) < 5000
    expect_buttons(page, enabled={"Start"})


def expect_buttons(page: Any, enabled: set[str]) -> None:
    """Wait until exactly the training buttons in `enabled` can be clicked."""
    from playwright.sync_api import expect

    for name in ("Start", "Pause", "Resume", "Stop"):
        button = expect(page.get_by_role("button", name=name, exact=True))
        if name in enabled:
            button.to_be_enabled(timeout=TIMEOUT_MS)
        else:
            button.to_be_disabled(timeout=TIMEOUT_MS)


def test_load_a_saved_run_replay_and_implement(page: Any, screenshots: Path) -> None:
    from playwright.sync_api import expect

    page.get_by_role("tab", name="Runs").click()
    press(page, "Refresh list")
    choose(page, "Run", "bs")
    press(page, "Load")
    expect(page.get_by_text("loaded run bs").first).to_be_visible(timeout=TIMEOUT_MS)
    choose(page, "Replay in", "implementation")
    press(page, "Replay best individual")
    wait_for(page, r"on show: step \d+ · bs: reward/step")
    expect(on_show(page)).to_contain_text("implementation arena", timeout=TIMEOUT_MS)
    type_into(page, "Steps T", "300")
    type_into(page, "Fault step t'", "100")
    type_into(page, "Repeats per start pose", "1")
    press(page, "Run implementation")
    match = wait_for(
        page,
        r"implementation: bs/break-2-3-dead-fixed · 10 trials · breaks s2, s3 \(dead\) at 100 "
        r"· mean reward/step "
        r"([\d.]+), after the fault ([\d.]+)",
    )
    assert 0.0 <= float(match.group(1)) <= 1.0
    page.screenshot(path=str(screenshots / "runs.png"))


def test_compare_two_runs_after_the_same_fault(page: Any, screenshots: Path) -> None:
    page.get_by_role("tab", name="Compare").click()
    choose(page, "Run A (blue)", "bs")
    choose(page, "Run B (orange)", "cs")
    type_into(page, "At step", "40")
    press(page, "Compare")
    wait_for(page, r"on show: step \d+ · bs: reward/step [\d.]+ · cs: reward/step")
    wait_for(page, r"sensors 2,3 broken \(dead\) since step 40")
    wait_for(page, r"on show: step (\d+)", at_least=115)  # both trails well past the fault
    page.screenshot(path=str(screenshots / "compare.png"))


def test_tabs_share_state_and_closing_one_leaves_the_server_healthy(
    page: Any, browser: Any, dashboard_url: str
) -> None:
    other = open_page(browser, dashboard_url)
    page.get_by_role("tab", name="Faults").click()
    press(page, "Repair all")
    wait_for(other, r"broken: none")
    type_into(page, "Sensors to break", "5")
    press(page, "Break now")
    wait_for(other, r"sensors 5 broken \(")  # the other tab sees the same robot
    other.close()
    later_step(page, step_of(page))  # the server carries on after a tab closed
    press(page, "Repair all")
    wait_for(page, r"broken: none")
