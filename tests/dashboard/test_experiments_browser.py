"""The Experiments tab in a real browser: start ch3-bs-rl at smoke scale from the page, on the
Dask cluster the dashboard starts, follow its progress, see its verdicts and load one of its
runs on the stage; then run it adaptively (stages of 2 seeds up to 4) and see its stages and
verdicts. Saves `experiments-curves.png` and `experiments.png` with the other screenshots
(test-output/dashboard/).

Every wait is for a state of the page; how long a control took to answer while the experiment
ran is printed, not asserted (bench/dashboard_latency.py --during experiment measures it).
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import psutil
import pytest
from page_helpers import TIMEOUT_MS, choose, field, open_page, press, sent, type_into, wait_for_line

from app.dashboard.experiment_verdicts import CLAIM_HEADER
from app.dashboard.headless import start_dashboard, stop_dashboard
from app.experiments import layout
from app.experiments.report import analyse
from app.experiments.results import VERDICTS
from app.experiments.spec_loading import load_shipped
from app.experiments.summary import read_summary

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]

NAME, SCALE = "ch3-bs-rl", "smoke"  # 4 runs of 2 generations and a few conditions: seconds
PROGRESS = "experiment: "
BROKEN_TEXT = """(table) => {
  const broken = [];
  const walker = document.createTreeWalker(table, NodeFilter.SHOW_TEXT);
  for (let node = walker.nextNode(); node; node = walker.nextNode()) {
    if (!node.textContent.trim()) continue;
    const range = document.createRange();
    range.selectNodeContents(node);
    const lines = new Set([...range.getClientRects()].map((r) => Math.round(r.top)));
    if (lines.size > 1) broken.push(node.textContent);
  }
  return broken;
}"""
"""The texts of a table laid out on more than one line (a name broken at each hyphen, say)."""


def catalogue_table(page: Any) -> Any:
    """The local runs' catalogue: experiments by scale (a column per scale)."""
    return page.locator("table", has=page.get_by_role("columnheader", name="smoke", exact=True))


def local_verdicts(page: Any) -> Any:
    """The local runs' verdict tables (a "runs" column; the committed reports' have "look,
    runs")."""
    header = page.get_by_role("columnheader", name=CLAIM_HEADER, exact=True)
    runs = page.get_by_role("columnheader", name="runs", exact=True)
    return page.locator("table", has=header).filter(has=runs)


def totals() -> tuple[str, str, str]:
    """Runs, generations and conditions of the experiment at the scale, as the line counts them."""
    spec = load_shipped(NAME)
    runs = len(spec.arms) * len(spec.seed_list("smoke"))
    generations = spec.run_config(spec.arms[0].name, SCALE, 0).training.generations
    return str(runs), str(runs * generations), str(runs * len(spec.conditions))


RUNS, GENERATIONS, CONDITIONS = totals()
COUNTS = (
    rf"(\d+)/{RUNS} runs done · generations (\d+)/{GENERATIONS} · conditions (\d+)/{CONDITIONS}"
)


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Any, str, Path]]:
    """`gnp-lab serve` on an empty runs dir, in its own process."""
    runs = tmp_path_factory.mktemp("experiment-browser-runs")
    process, url = start_dashboard(runs, runs.parent / "experiments-server.log")
    yield process, url, runs
    stop_dashboard(process)


def listening(pid: int) -> set[str]:
    """The addresses a process and its descendants listen on."""
    root = psutil.Process(pid)
    found = set()
    for process in [root, *root.children(recursive=True)]:
        try:
            connections = process.net_connections(kind="inet")
        except psutil.NoSuchProcess:
            continue
        found |= {c.laddr.ip for c in connections if c.status == psutil.CONN_LISTEN}
    return found


def test_start_an_experiment_follow_it_and_load_its_run(
    served: tuple[Any, str, Path], browser: Any, screenshots: Path
) -> None:
    from playwright.sync_api import expect

    process, url, runs = served
    page = open_page(browser, url)
    page.get_by_role("tab", name="Experiments").click()
    catalogue = catalogue_table(page)
    expect(catalogue).to_contain_text(f"{NAME}", timeout=TIMEOUT_MS)
    choose(page, "Experiment", NAME)
    choose(page, "Scale", SCALE)
    press(page, "Start")
    first = wait_for_line(page, PROGRESS, rf"^experiment: {NAME} at {SCALE} · ([^·\n]+) · {COUNTS}")
    assert first.group(1) != "finished: summary written" and int(first.group(2)) < 4

    # The page answers while the experiment runs: another scale's view, then this one's again.
    asked = time.monotonic()
    choose(page, "Scale", "small")
    page.get_by_text("small: 0/20 runs done").first.wait_for()
    answered = time.monotonic() - asked
    during = wait_for_line(page, PROGRESS, rf"^experiment: {NAME} at {SCALE} · ([^·\n]+) · ")
    print(f"\nthe Scale control answered in {1000 * answered:.0f} ms ({during.group(1)})")
    choose(page, "Scale", SCALE)

    # Progress grows to the end, and the verdicts follow from the summary.
    seen = {first.group(0)}
    while "finished" not in (line := progress_text(page)):
        seen.add(line)
        time.sleep(0.1)
    last = wait_for_line(page, PROGRESS, rf"finished: summary written · {COUNTS}")
    assert last.groups() == (RUNS, GENERATIONS, CONDITIONS) and len(seen) >= 2
    assert field(page, "Experiment").input_value() == NAME
    verdicts = local_verdicts(page)
    expect(verdicts.first).to_contain_text(re.compile("|".join(VERDICTS)), timeout=TIMEOUT_MS)
    claims = len(load_shipped(NAME).comparisons)
    expect(verdicts.locator("tr")).to_have_count(2 + claims)  # questions, sanity: header, rows
    page.get_by_text("one look at 2 seeds per arm (not adaptive)").first.wait_for()
    assert page.locator(".u-legend", has_text="BS (n = 2)").count() >= 1
    smoke_cell = catalogue.locator("tr", has_text=NAME).locator("td").nth(1)
    expect(smoke_cell).to_have_text(f"{RUNS}/{RUNS}", timeout=TIMEOUT_MS)  # the list is refreshed
    assert listening(process.pid) == {"127.0.0.1"}  # the server and its Dask cluster

    # One of its runs on the stage.
    choose(page, "Run (arm-seed)", "BS-seed1")
    press(page, "Load run on stage")
    wait_for_line(page, "on show:", r"^on show: step \d+ · BS-seed1: reward/step")
    assert (runs / "experiments" / NAME / "summary-smoke.h5").is_file()
    title = page.get_by_text("Training: best fitness").first  # the charts, then the table
    title.evaluate("(element) => element.scrollIntoView({block: 'start'})")
    page.wait_for_timeout(1000)  # let software WebGL draw the new robot
    page.screenshot(path=str(screenshots / "experiments-curves.png"))
    page.close()


def test_an_adaptive_run_shows_its_stages_and_verdicts(
    served: tuple[Any, str, Path], browser: Any, screenshots: Path
) -> None:
    """Stages of 2 seeds up to 4: after the test above only the second stage has runs to do."""
    from playwright.sync_api import expect

    _, url, runs = served
    page = open_page(browser, url)
    page.get_by_role("tab", name="Experiments").click()
    expect(catalogue_table(page)).to_contain_text(NAME, timeout=TIMEOUT_MS)
    choose(page, "Experiment", NAME)
    choose(page, "Scale", SCALE)
    adaptive = field(page, "Adaptive")
    sent(page, adaptive.check, "true")
    type_into(page, "Stage seeds", "1")  # refused, with the reason
    type_into(page, "Max seeds", "4")
    press(page, "Start")
    page.get_by_text("⚠ adaptive: stages need at least 2 seeds each").first.wait_for()
    type_into(page, "Stage seeds", "2")
    press(page, "Start")
    page.get_by_text(f"experiment {NAME} at {SCALE} started adaptively").first.wait_for()
    done = wait_for_line(
        page, PROGRESS, r"finished: summary written after (\d) look\(s\), (\d) seeds per arm"
    )
    # The stages on the page are the summary's looks (the report is the oracle).
    report = analyse(read_summary(layout.summary_path(runs, NAME, SCALE)))
    looks = len(report.looks)
    assert done.groups() == (str(looks), str(report.looks[-1])) and report.looks[0] == 2
    header = page.get_by_role("columnheader", name="decided", exact=True)
    stages = page.locator("table", has=header)
    expect(stages.locator("tr")).to_have_count(1 + looks, timeout=TIMEOUT_MS)
    first = stages.locator("tr").nth(1).locator("td")
    expect(first.nth(1)).to_have_text("2")
    expect(first.nth(2)).to_have_text("BS 2 · RL 2")
    # The verdicts: questions then sanity claims, each named by one of the four verdicts.
    verdicts = local_verdicts(page)
    expect(verdicts).to_have_count(2)
    for table, kind in zip((verdicts.nth(0), verdicts.nth(1)), ("question", "sanity"), strict=True):
        claims = report.of_kind(kind)
        expect(table.locator("tr")).to_have_count(1 + len(claims))
        box = table.bounding_box()  # it fits the side panel: nothing off the page's right edge
        assert box is not None and box["x"] + box["width"] <= page.viewport_size["width"]
        cells = table.locator("tr td:nth-child(3)").all_inner_texts()
        assert [cell.splitlines()[0] for cell in cells] == [c.claim.verdict for c in claims]
        names = table.locator("tr td:nth-child(1)").all_inner_texts()
        assert [cell.splitlines()[0] for cell in names] == [c.comparison.name for c in claims]
    # Nothing in the tables is broken inside a name, a number or an interval.
    for table in (*verdicts.all(), stages):
        assert table.evaluate(BROKEN_TEXT) == []
    page.get_by_text("Stages").first.evaluate(
        "(element) => element.scrollIntoView({block: 'start'})"
    )
    page.wait_for_timeout(500)
    page.screenshot(path=str(screenshots / "experiments.png"))
    page.close()


def progress_text(page: Any) -> str:
    return str(page.get_by_text(re.compile("^" + PROGRESS)).first.inner_text())
