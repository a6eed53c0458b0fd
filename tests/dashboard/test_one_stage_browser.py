"""One stage, one truth (#43), in a real browser: what is on show is one state that every
panel draws from and names; Load changes it; RL, BS and CS meet the same broken sensor.

A dashboard of its own (runs `alpha`, a CS run, and `beta`, a BS run, each with a stored
implementation phase, and the three bundled names), so no other module's state leaks in.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from page_helpers import choose, field, open_page, press, sent, type_into, wait_for_line

from app.dashboard.headless import start_dashboard, stop_dashboard
from app.dashboard.method_show import ALL_THREE, BUNDLED

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("one-stage-browser")]

LOAD_SECONDS = 5.0
"""Load puts the loaded run on show within this long, with no other click (issue #43)."""


@pytest.fixture(scope="module")
def stage_runs(runs_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """alpha (CS) and beta (BS), each with a stored implementation; the bundled trio."""
    folder = tmp_path_factory.mktemp("one-stage")
    for name, source in (("alpha", "cs"), ("beta", "bs")):
        shutil.copy(runs_dir / f"{source}.h5", folder / f"{name}.h5")
        subprocess.run(
            [sys.executable, "-m", "app.cli", "implement", name, "--runs-dir", str(folder),
             "--break", "2", "--steps", "200", "--fault-step", "100", "--repeats", "1"],
            check=True, capture_output=True,
        )  # fmt: skip
    for method, name in BUNDLED.items():
        shutil.copy(runs_dir / ("bs.h5" if method == "BS" else "cs.h5"), folder / f"{name}.h5")
    return folder


@pytest.fixture(scope="module")
def page(browser: Any, stage_runs: Path) -> Iterator[Any]:
    process, url = start_dashboard(
        stage_runs, stage_runs.parent / "one-stage.log", ("--run", "alpha")
    )
    page = open_page(browser, url)
    yield page
    page.close()
    stop_dashboard(process)


def panels(page: Any) -> str:
    """Every panel's words: the readout, the Show tab's description, the charts' titles, the
    graph's robot list."""
    readout = page.get_by_text(re.compile("^on show:")).first.inner_text()
    described = page.get_by_text(re.compile("^On show:")).first.locator("..").inner_text()
    titles = " | ".join(page.locator(".u-title").all_inner_texts())
    return f"{readout}\n{described}\n{titles}\n{field(page, 'Graph of').input_value()}"


def status(page: Any) -> str:
    return str(page.get_by_text(re.compile("^Status:")).first.locator("..").inner_text())


def test_load_puts_the_loaded_run_on_every_panel(page: Any, screenshots: Path) -> None:
    from playwright.sync_api import expect

    wait_for_line(page, "on show:", r"on show: step \d+ · alpha: reward/step")
    assert "beta" not in panels(page)
    page.get_by_role("tab", name="Runs").click()
    choose(page, "Run", "beta")
    press(page, "Load")  # and nothing else
    page.get_by_role("tab", name="Show").click()
    expect(page.get_by_text(re.compile("^On show:")).first.locator("..")).to_contain_text(
        "best of generation 1 of run beta", timeout=LOAD_SECONDS * 1000
    )
    wait_for_line(page, "on show:", r"on show: step \d+ · beta: reward/step")
    wait_for_line(page, "on show:", r"fitness plot: 2 generations of beta")
    wait_for_line(page, "on show:", r"implementation: beta/break-2-dead-\S+ · 10 trials")
    text = panels(page)
    for title in (
        "Reward per step · beta",
        "Fitness per generation · beta",
        "Implementation phase · beta/",
    ):
        assert title in text, text
    assert "alpha" not in text, text  # no panel still tells of the run shown before
    assert "loaded run beta" in status(page)
    page.screenshot(path=str(screenshots / "one-stage-load.png"))


def test_a_warning_ends_when_its_cause_does(page: Any) -> None:
    page.get_by_role("tab", name="Faults").click()
    type_into(page, "Sensors to break", "9")
    press(page, "Break now")
    wait_for_line(page, "Status:", "Status: ⚠")
    type_into(page, "Sensors to break", "2")  # the cause fixed: the same action works
    press(page, "Break now")
    wait_for_line(page, "Status:", r"Status: (?!⚠)")
    press(page, "Repair all")


def test_rl_bs_and_cs_meet_the_same_broken_sensor(page: Any, screenshots: Path) -> None:
    rl, bs, cs = BUNDLED["RL"], BUNDLED["BS"], BUNDLED["CS"]
    page.get_by_role("tab", name="Show").click()
    press(page, ALL_THREE)
    wait_for_line(
        page,
        "on show:",
        rf"on show: step \d+ · {rl}: reward/step [\d.]+ · {bs}: reward/step [\d.]+ · "
        rf"{cs}: reward/step",
    )
    wait_for_line(page, "Status:", rf"Status: on show: {re.escape(ALL_THREE)}")
    page.get_by_role("tab", name="Faults").click()
    type_into(page, "Sensors to break", "3")
    press(page, "Break now")
    wait_for_line(page, "on show:", r"sensors 3 broken \(\w+\)")
    page.get_by_role("tab", name="Show").click()
    choose(page, "Graph of", f"3 · {cs}")
    wait_for_line(page, "on show:", rf"fitness plot: 2 generations of {cs}\n")
    assert f"Fitness per generation · {cs}" in panels(page)
    page.screenshot(path=str(screenshots / "rl-bs-cs.png"))
    button = page.get_by_role("button", name="BS", exact=True)
    sent(page, button.click, "BS")  # one method now, the sensor still broken
    wait_for_line(page, "on show:", rf"on show: step \d+ · {bs}: reward/step [\d.]+ · node")
    wait_for_line(page, "on show:", r"sensors 3 broken \(dead\)")
    text = panels(page)
    assert f"Reward per step · {bs}" in text and rl not in text, text


def test_the_graph_opens_simplified_and_compare_offers_two_runs(page: Any) -> None:
    wait_for_line(page, "graph:", r"graph: simplified · \d+ of \d+ nodes")
    page.get_by_role("tab", name="Compare").click()
    a = field(page, "Run A (blue)").input_value()
    b = field(page, "Run B (orange)").input_value()
    assert a != b, (a, b)


def settled_box(locator: Any, fits: Any, wait_s: float = 10.0) -> Any:
    """The locator's bounding box once `fits` holds, or the last one read after `wait_s`: the
    page lays out again as its panels fill (a loaded machine draws them late)."""
    deadline = time.monotonic() + wait_s
    box = locator.bounding_box()
    while (box is None or not fits(box)) and time.monotonic() < deadline:
        time.sleep(0.2)
        box = locator.bounding_box()
    return box


def test_at_1280_by_720_the_implementation_phase_is_in_view(
    browser: Any, page: Any, screenshots: Path
) -> None:
    small = open_page(browser, page.url, {"width": 1280, "height": 720})
    try:
        wait_for_line(small, "on show:", r"on show: step \d+")
        small.get_by_role("tab", name="Runs").click()
        button = small.get_by_role("button", name="Run implementation")
        button.wait_for()
        box = button.bounding_box()
        assert box is not None and box["y"] + box["height"] <= 720, box
        title = small.locator(".u-title", has_text="Implementation phase").first
        chart = settled_box(title, lambda box: box["y"] + 80 <= 720, wait_s=30.0)
        # its curve shows, not only its title; failing, the page's words say what stands above
        assert chart is not None and chart["y"] + 80 <= 720, (chart, small.inner_text("body"))
        labels = small.locator(".u-label").all_inner_texts()
        assert "sensors broken" in labels, labels  # the count is read on its own axis
        small.screenshot(path=str(screenshots / "runs-1280x720.png"))
    finally:
        small.close()
