"""The Experiments tab in a real browser: start ch3-bs-rl at smoke scale from the page, on the
Dask cluster the dashboard starts, follow its progress, see its verdicts and load one of its
runs on the stage. Saves `experiments.png` with the other screenshots (test-output/dashboard/).

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
from page_helpers import TIMEOUT_MS, choose, field, open_page, press, wait_for_line

from app.dashboard.headless import start_dashboard, stop_dashboard
from app.experiments.results import VERDICTS
from app.experiments.spec import load_shipped

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("dashboard-browser")]

NAME, SCALE = "ch3-bs-rl", "smoke"  # 4 runs of 2 generations and a few conditions: seconds
PROGRESS = "experiment: "


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
    catalogue = page.locator("table", has_text="experiment").first
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
    verdicts = page.locator("table", has_text="a − b [interval]").first
    expect(verdicts).to_contain_text(re.compile("|".join(VERDICTS)), timeout=TIMEOUT_MS)
    claims = len(load_shipped(NAME).comparisons)
    expect(verdicts.locator("tr")).to_have_count(1 + claims)  # a header and a row per claim
    assert page.locator(".u-legend", has_text="BS (n = 2)").count() >= 1
    smoke_cell = catalogue.locator("tr", has_text=NAME).locator("td").nth(1)
    expect(smoke_cell).to_have_text(f"{RUNS}/{RUNS}", timeout=TIMEOUT_MS)  # the list is refreshed
    assert listening(process.pid) == {"127.0.0.1"}  # the server and its Dask cluster

    # One of its runs on the stage.
    choose(page, "Run (arm-seed)", "BS-seed1")
    press(page, "Load run on stage")
    page.get_by_text("replaying the best of generation 1 of BS-seed1").first.wait_for()
    wait_for_line(page, "on show:", r"^on show: step \d+ · BS-seed1: reward/step")
    assert (runs / "experiments" / NAME / "summary-smoke.h5").is_file()
    title = page.get_by_text("Training: best fitness").first  # the charts, then the table
    title.evaluate("(element) => element.scrollIntoView({block: 'start'})")
    page.wait_for_timeout(1000)  # let software WebGL draw the new robot
    page.screenshot(path=str(screenshots / "experiments.png"))
    page.close()


def progress_text(page: Any) -> str:
    return str(page.get_by_text(re.compile("^" + PROGRESS)).first.inner_text())
