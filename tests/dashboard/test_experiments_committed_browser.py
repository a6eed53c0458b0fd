"""The committed reports in a real browser, on a runs dir with no run files (a fresh clone):
the Experiments tab shows the verdict tally of every report folder in docs/experiments, the
thesis's answers, and one report's claims with their verdicts and intervals, a claim's runs as
a picture and its report page served. Saves `experiments-answers.png`, `experiments-claim.png` and
`experiments-committed.png` (test-output/dashboard/).

The expectations are read here from the report files (report.json) with plain json, and one
claim's verdict and interval are written out by hand from ch5-cs-bs-rl-decisive-thesis.
"""

from __future__ import annotations

import json
import re
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from page_helpers import TIMEOUT_MS, choose, open_page

from app.dashboard.headless import start_dashboard, stop_dashboard
from app.experiments.ledger import DOCS
from app.experiments.questions import tally

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]

DECISIVE = "ch5-cs-bs-rl-decisive-thesis"


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """`gnp-lab serve` on an empty runs dir (no runs, no experiments), in its own process."""
    runs = tmp_path_factory.mktemp("committed-browser-runs")
    process, url = start_dashboard(runs, runs.parent / "committed-server.log")
    yield url
    stop_dashboard(process)


def committed() -> dict[str, dict[str, Any]]:
    """Every committed report folder's report.json, by folder."""
    return {
        path.parent.name: json.loads(path.read_text())
        for path in sorted(DOCS.glob("*/report.json"))
    }


def test_a_fresh_clone_shows_every_committed_report(
    served: str, browser: Any, screenshots: Path
) -> None:
    from playwright.sync_api import expect

    reports = committed()
    assert len(reports) >= 15 and DECISIVE in reports
    page = open_page(browser, served)
    page.get_by_role("tab", name="Experiments").click()

    # Every report folder is a row with its verdict tally.
    shelf = page.locator("table", has=page.get_by_role("columnheader", name="verdicts"))
    expect(shelf.locator("tr")).to_have_count(1 + len(reports), timeout=TIMEOUT_MS)
    rows = shelf.locator("tr td:nth-child(1)").all_inner_texts()
    tallies = shelf.locator("tr td:nth-child(2)").all_inner_texts()
    expected = {
        f"{r['experiment']} · {r['scale']}": tally(r["comparisons"]) for r in reports.values()
    }
    assert dict(zip(rows, tallies, strict=True)) == expected
    assert "⚠" not in shelf.inner_text()
    page.screenshot(path=str(screenshots / "experiments-answers.png"))
    assert expected["ch5-cs-bs-rl-decisive · thesis"] == (
        "2 held, 1 reversed, 1 undecided; 16 exploratory"
    )  # by hand, from report.json's tally

    # The thesis's answers: the decisive column reads the decisive reports.
    answers = page.locator("table", has=page.get_by_role("columnheader", name="decisive"))
    row = answers.locator("tr", has_text="Does CS earn more reward than BS after a sensor breaks?")
    expect(row.locator("td").nth(3)).to_have_text("reversed (50 + 50 runs)")

    # One report: its claims with verdict, Δ [interval], look and runs, the thesis's ordering.
    choose(page, "Report", DECISIVE)
    page.get_by_text("ch5-cs-bs-rl-decisive at thesis scale (committed report)").wait_for()
    claims = page.locator("table", has_text="look, runs")
    claim = claims.locator("tr", has_text="after-1-sensor-CS-BS").first
    cells = claim.locator("td")
    expect(cells.nth(0)).to_contain_text("-0.09892 [-0.179, -0.01883]")
    expect(cells.nth(0)).to_contain_text("thesis: CS > BS")
    expect(cells.nth(1)).to_have_text(re.compile(r"look 2\s*50, 50"))
    expect(cells.nth(2)).to_have_text("reversed")
    exploratory = claims.locator("tr", has_text="training-fitness-CS-BS").first.locator("td")
    expect(exploratory.nth(2)).to_have_text("exploratory")
    expect(claims.locator("tbody tr")).to_have_count(len(reports[DECISIVE]["comparisons"]))

    # A claim's runs drawn from values.csv; its report page served.
    choose(page, "Claim", "after-1-sensor-CS-BS")
    page.get_by_text("CS n = 50, BS n = 50").wait_for()
    link = page.get_by_role("link", name="report page")
    href = link.get_attribute("href")
    assert href is not None and href.endswith(f"/{DECISIVE}/index.html")
    with urllib.request.urlopen(href, timeout=30) as answer:
        assert answer.status == 200 and b"ch5-cs-bs-rl-decisive" in answer.read()
    page.get_by_text("CS n = 50, BS n = 50").evaluate(
        "(element) => element.scrollIntoView({block: 'end'})"
    )
    page.wait_for_timeout(500)
    page.screenshot(path=str(screenshots / "experiments-claim.png"))

    # The local runs' view says where the answer is.
    choose(page, "Experiment", "ch5-cs-bs-rl-decisive")
    choose(page, "Scale", "thesis")
    page.get_by_text(f"the committed report {DECISIVE} is shown above").wait_for()
    page.get_by_text("ch5-cs-bs-rl-decisive at thesis scale (committed report)").wait_for()
    page.get_by_text("Report", exact=True).first.evaluate(
        "(element) => element.scrollIntoView({block: 'start'})"
    )
    page.wait_for_timeout(500)
    page.screenshot(path=str(screenshots / "experiments-committed.png"))
    page.close()
