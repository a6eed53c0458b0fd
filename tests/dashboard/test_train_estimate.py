"""The Train tab's estimate beside Start: robot-steps at the lab's measured rate."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from app.dashboard.controls import training_config
from app.dashboard.tab_train import duration, estimate
from app.experiments.results import CORE_STEPS_PER_SECOND, PYMUNK_CORE_STEPS_PER_SECOND


def test_thesis_ch5_by_hand() -> None:
    """300 robots × 1000 generations × 2000 steps on pymunk's physics (the preset's), two
    workers (four shards of 75 robots)."""
    cost = estimate(training_config("thesis-ch5", {}), workers=2)
    assert cost.robot_steps == 300 * 1000 * 2000
    assert cost.steps_per_core_second == PYMUNK_CORE_STEPS_PER_SECOND == 0.46e6
    assert cost.core_hours == pytest.approx(6e8 / 0.46e6 / 3600)  # 0.362 core-hours
    assert cost.seconds == pytest.approx(6e8 / 0.46e6 / 2)  # 652 s
    text = cost.describe()
    assert text.startswith("**Estimate**")
    assert "about 11 min on 2 idle cores, 0.36 core-hours: 600 M robot-steps" in text


def test_the_settings_and_the_physics_move_it() -> None:
    values: dict[tuple[str, ...], Any] = {("training", "population"): 10}
    values |= {("training", "generations"): 3, ("training", "steps"): 100}
    values[("training", "physics")] = "analytic"
    cost = estimate(training_config("quick", values), workers=8)
    assert cost.robot_steps == 3000
    assert cost.steps_per_core_second == CORE_STEPS_PER_SECOND
    assert cost.workers == 1  # 10 robots are one shard: one worker lives them


@pytest.mark.parametrize(
    ("seconds", "words"), [(12.4, "12 s"), (652.2, "11 min"), (3 * 3600 + 1500, "3.4 h")]
)
def test_duration(seconds: float, words: str) -> None:
    assert duration(seconds) == words


@pytest.mark.browser
def test_picking_thesis_ch5_shows_its_estimate_before_start(browser: Any, runs_dir: Path) -> None:
    """In Chromium, on a dashboard of its own (the preset would change a shared one's)."""
    from page_helpers import choose, dashboard_in_process, open_page, wait_for_line

    with dashboard_in_process(runs_dir) as board:
        page = open_page(browser, f"http://127.0.0.1:{board.server.get_port()}")
        try:
            page.get_by_role("tab", name="Train").click()
            wait_for_line(page, "Estimate", r"core-hours: 4 M robot-steps")  # quick's
            choose(page, "Preset", "thesis-ch5")
            wait_for_line(page, "Estimate", r"0\.36 core-hours: 600 M robot-steps")
        finally:
            page.close()
