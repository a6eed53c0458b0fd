"""The Runs and Compare tabs' implementation and fault controls: their choices come from the
implementation model, and a value it refuses is one message at once, with nothing started."""

from __future__ import annotations

from pathlib import Path
from typing import get_args

from page_helpers import dashboard_in_process

import sim
from app.config import ImplementationSettings, ScheduleKind


def test_fault_modes_and_schedules_are_the_models_choices(runs_dir: Path) -> None:
    modes = get_args(ImplementationSettings.model_fields["fault_mode"].annotation)
    assert set(modes) == set(sim.FAULT_MODES)  # the model and the world agree
    with dashboard_in_process(runs_dir, "cs") as dashboard:
        for dropdown in (dashboard.runs.mode, dashboard.compare.mode, dashboard.faults.mode):
            assert dropdown.options == modes
            assert dropdown.value == ImplementationSettings().fault_mode
            assert dropdown.hint is not None and "what a broken sensor reads" in dropdown.hint
        assert dashboard.runs.schedule.options == get_args(ScheduleKind)
        assert dashboard.runs.schedule.value == ImplementationSettings().schedule

