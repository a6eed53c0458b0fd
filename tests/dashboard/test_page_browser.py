"""Rough edges a new user met on the page, checked in a real browser (headless Chromium): the tab
row, the reward chart's series and the Experiments tab's charts before there is anything to draw.

The verdict tables' fit is checked with an experiment's results in test_experiments_browser.py.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from page_helpers import TIMEOUT_MS, choose, open_page

from app.dashboard.app import PANEL_WIDTH, TAB_NAMES
from app.dashboard.plots import BIN, SMOOTH
from app.experiments import execution, planning
from app.experiments.spec_loading import load_shipped

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]

EXPERIMENT = "ch3-bs-rl"  # its smoke runs train in a second or so
CHART_TITLES = ("Training: best fitness", "Implementation: reward per step")


@pytest.fixture(scope="module")
def page(browser: Any, dashboard_url: str) -> Iterator[Any]:
    page = open_page(browser, dashboard_url)
    yield page
    page.close()


def test_the_tabs_sit_in_one_row(page: Any) -> None:
    boxes = [page.get_by_role("tab", name=name, exact=True).bounding_box() for name in TAB_NAMES]
    assert all(box is not None for box in boxes)
    tops = {round(box["y"]) for box in boxes}
    assert len(tops) == 1, f"the tab row wraps: tops {sorted(tops)}"
    left = min(box["x"] for box in boxes)
    right = max(box["x"] + box["width"] for box in boxes)
    assert right - left <= PANEL_WIDTH


def test_the_reward_chart_draws_block_means_under_the_smooth_mean(
    page: Any, screenshots: Path
) -> None:
    from playwright.sync_api import expect

    chart = page.locator(".uplot", has_text="Reward per step")
    legend = chart.locator(".u-legend")
    # The run on show may be another test's (a training on this server puts its best on show).
    expect(legend).to_contain_text(f"({BIN}-step)", timeout=TIMEOUT_MS)
    expect(legend).to_contain_text(f"{SMOOTH}-step mean")
    expect(legend).to_contain_text("broken sensors")
    chart.first.screenshot(path=str(screenshots / "reward-chart.png"))


def test_the_experiments_charts_wait_for_curves(
    page: Any, runs_dir: Path, screenshots: Path
) -> None:
    """No experiment has run in this runs dir: a hint, no empty axes. Once one of its runs is
    there, picking it shows both charts (so the titles looked for are the charts' own: a
    renamed chart fails here, not only a shown one)."""
    from playwright.sync_api import expect

    page.get_by_role("tab", name="Experiments", exact=True).click()
    hint = page.get_by_text("Implementation: no curves yet.").first
    expect(hint).to_be_visible(timeout=TIMEOUT_MS)
    charts = [page.locator(".uplot", has_text=title) for title in CHART_TITLES]
    for chart in charts:
        expect(chart).to_be_hidden()
    hint.evaluate("(element) => element.scrollIntoView({block: 'center'})")
    page.screenshot(path=str(screenshots / "experiments-before.png"))

    spec = load_shipped(EXPERIMENT)
    try:
        execution.run_task(next(iter(planning.plan(spec, "smoke", runs_dir))))  # a second or so
        choose(page, "Experiment", EXPERIMENT)
        choose(page, "Scale", "smoke")
        for chart in charts:
            expect(chart).to_be_visible(timeout=TIMEOUT_MS)
        expect(hint).to_be_hidden()
    finally:  # the runs dir is shared with the other browser tests: leave it as it was
        shutil.rmtree(runs_dir / "experiments", ignore_errors=True)
    page.get_by_role("tab", name="Show", exact=True).click()
