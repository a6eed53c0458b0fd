"""The Runs tab's implementation phase as a person meets it: the σ it will use in the form,
a progress bar with an ETA while it runs, Cancel, and the plot and readout naming the run and
condition they belong to; in the dashboard's own objects and in headless Chromium."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from page_helpers import (
    TIMEOUT_MS,
    choose,
    dashboard_in_process,
    field,
    open_page,
    press,
    type_into,
    until,
    wait_for_line,
)

from app.dashboard.headless import start_dashboard, stop_dashboard

PROGRESS = """([above]) => {
  const line = [...document.querySelectorAll("p")].find(
    (p) => /^Implementation (?!phase)/.test(p.innerText));
  if (!line) return null;
  const bars = [...document.querySelectorAll("[role=progressbar]")].filter(
    (bar) => line.compareDocumentPosition(bar) & Node.DOCUMENT_POSITION_PRECEDING);
  const value = bars.length ? Number(bars[bars.length - 1].getAttribute("aria-valuenow")) : 0;
  return value > above ? value : null;
}"""
"""The value of the Runs tab's implementation bar (the last before its line) once above `above`."""


def test_the_sigma_field_takes_the_loaded_runs_noise_and_is_checked_by_the_model(
    runs_dir: Path,
) -> None:
    with dashboard_in_process(runs_dir, "cs") as dashboard:
        runs, status = dashboard.runs, dashboard.status
        with dashboard.lock:
            runs.load_file(runs_dir / "cs.h5")
            runs.follow_loaded()
            assert runs.loaded is not None
            assert runs.noise.value == runs.loaded.config.implementation.noise_sigma
            runs.noise.value = 2000.0
        status.guarded(None, runs.start_implementation)
        assert status.text.startswith("⚠ noise σ") and runs.implementation is None
        with dashboard.lock:
            runs.noise.value, runs.steps.value, runs.repeats.value = 5.0, 120, 1
        status.guarded(None, runs.start_implementation)
        assert status.text == "implementation phase of cs started"
        assert runs.run_implementation.disabled and not runs.cancel_implementation.disabled
        until(lambda: status.text.startswith("implementation phase finished"), 300)
        name = "cs/break-2-3-dead-fixed-noise5"  # the run and the condition, σ included
        assert status.text.startswith(f"implementation phase finished: {name} in ")
        assert runs.plots.implementation.title.endswith(name)
        assert runs.plots.implementation_line.startswith(f"implementation: {name} · 10 trials")
        assert not runs.run_implementation.disabled and runs.cancel_implementation.disabled
        assert runs.implementation_bar.value == 100.0


def test_a_phase_of_a_run_no_longer_loaded_is_told_of_not_plotted(runs_dir: Path) -> None:
    with dashboard_in_process(runs_dir, "cs") as dashboard:
        runs, status = dashboard.runs, dashboard.status
        with dashboard.lock:
            runs.load_file(runs_dir / "cs.h5")
            runs.steps.value, runs.repeats.value = 120, 1
        status.guarded(None, runs.start_implementation)
        with dashboard.lock:
            runs.load_file(runs_dir / "bs.h5")  # while cs's phase runs
        until(lambda: status.text.startswith("implementation phase finished"), 300)
        assert status.text.endswith("; not plotted: another run is loaded)")
        assert "cs/" not in runs.plots.implementation.title
        assert "cs/" not in runs.plots.implementation_line


@pytest.fixture(scope="module")
def page(browser: Any, runs_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """A page on a dashboard of its own (the shared one's state is other tests')."""
    log = tmp_path_factory.mktemp("implementation-server") / "server.log"
    process, url = start_dashboard(runs_dir, log, ("--run", "cs"))
    page = open_page(browser, url)
    yield page
    page.close()
    stop_dashboard(process)


def progress_above(page: Any, value: float) -> float:
    return float(page.wait_for_function(PROGRESS, arg=[value], polling=100).json_value())


def status_line(page: Any, pattern: str) -> None:
    wait_for_line(page, "Status:", pattern)


@pytest.mark.browser
def test_run_watch_cancel_and_run_again(page: Any, screenshots: Path) -> None:
    from playwright.sync_api import expect

    page.get_by_role("tab", name="Runs").click()
    press(page, "Refresh list")
    choose(page, "Run", "bs")
    press(page, "Load")
    status_line(page, r"loaded run bs")
    expect(field(page, "Noise σ (trials)")).to_have_value("0", timeout=TIMEOUT_MS)  # bs's own
    run, cancel = (
        page.get_by_role("button", name=name, exact=True)
        for name in ("Run implementation", "Cancel implementation")
    )
    expect(cancel).to_be_disabled(timeout=TIMEOUT_MS)
    # Minutes of work: 3000 trials of 3000 steps.
    type_into(page, "Steps T", "3000")
    type_into(page, "Fault step t'", "500")
    type_into(page, "Repeats per start pose", "300")
    press(page, "Run implementation")
    expect(run).to_be_disabled(timeout=TIMEOUT_MS)
    expect(cancel).to_be_enabled(timeout=TIMEOUT_MS)
    first = progress_above(page, 0.0)
    progress_above(page, first)  # it moves
    line = r"running · \d+ of 3000 trials · \d+% · \d+ s · ETA \d+ s · σ 0$"
    wait_for_line(page, "Implementation bs/break-2-3-dead-fixed", line)
    wait_for_line(
        page, "on show:", r"implementation: bs/break-2-3-dead-fixed running · \d+ of 3000 trials"
    )
    page.screenshot(path=str(screenshots / "implementation-progress.png"))

    press(page, "Cancel implementation")
    status_line(page, r"implementation cancelled: bs/break-2-3-dead-fixed after \d+ s")
    wait_for_line(page, "Implementation bs/", r"cancelled · \d+ of 3000 trials")
    expect(run).to_be_enabled(timeout=TIMEOUT_MS)
    expect(cancel).to_be_disabled(timeout=TIMEOUT_MS)

    # A small one to the end.
    type_into(page, "Steps T", "300")
    type_into(page, "Fault step t'", "100")
    type_into(page, "Repeats per start pose", "1")
    press(page, "Run implementation")
    status_line(page, r"implementation phase finished: bs/break-2-3-dead-fixed in \d+ s")
    wait_for_line(page, "Implementation bs/", r"finished · 10 of 10 trials · 100%")
    assert progress_above(page, 99.0) == 100.0
    wait_for_line(
        page,
        "on show:",
        r"implementation: bs/break-2-3-dead-fixed · 10 trials · breaks s2, s3 \(dead\) at 100",
    )
    title = page.locator(".u-title", has_text="Implementation phase")
    expect(title).to_have_text("Implementation phase · bs/break-2-3-dead-fixed")
    expect(run).to_be_enabled(timeout=TIMEOUT_MS)
    page.screenshot(path=str(screenshots / "implementation-done.png"))
