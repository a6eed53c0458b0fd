"""The Runs and Compare tabs' implementation and fault controls: their choices come from the
implementation model, and a value it refuses is one message at once, with nothing started."""

from __future__ import annotations

from pathlib import Path
from typing import Any, get_args

import pytest
from page_helpers import dashboard_in_process

import sim
from app.dashboard import tab_runs
from app.dashboard.implementation_job import ImplementationRequest, JobProgress
from app.settings.config import ImplementationSettings, ScheduleKind


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


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"sensors": "9"}, "broken_sensors: sensors are numbered 0..7, got [9]"),
        ({"sensors": "s2 s8"}, "broken_sensors: sensors are numbered 0..7, got [2, 8]"),
        (
            {"fault_step": 200, "steps": 200},
            "fault_step (200) must be below steps (200) for the sensors to break",
        ),
    ],
)
def test_a_request_the_model_refuses_is_one_message_and_starts_no_worker(
    runs_dir: Path, changes: dict[str, Any], message: str
) -> None:
    with dashboard_in_process(runs_dir, "cs") as dashboard:
        runs = dashboard.runs
        runs.load_file(runs_dir / "cs.h5")
        for name, value in changes.items():
            getattr(runs, name).value = value
        dashboard.status.guarded(None, runs.start_implementation)
        assert dashboard.status.text == f"⚠ implementation settings: {message}"
        assert runs.implementation is None
        assert runs.plots.implementation_line != "implementation: running"


class FakeJob:
    """Stands in for `ImplementationJob`: records the request, starts no worker."""

    def __init__(self, request: ImplementationRequest, total: int = 0) -> None:
        self.request, self.total = request, total
        self.active = True
        self.reported = False

    def progress(self) -> JobProgress:
        return JobProgress("starting", 0, self.total, 0.0, None, self.request.steps)

    def close(self) -> None:
        self.active = False


def test_a_request_the_model_takes_starts_the_job(
    runs_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tab_runs, "ImplementationJob", FakeJob)
    with dashboard_in_process(runs_dir, "cs") as dashboard:
        runs = dashboard.runs
        runs.load_file(runs_dir / "cs.h5")
        runs.sensors.value = "s7, 0"
        runs.mode.value = "stuck"
        runs.fault_step.value, runs.steps.value = 100, 101
        dashboard.status.guarded(None, runs.start_implementation)
        assert dashboard.status.text == "implementation phase of cs started"
        job = runs.implementation
        assert isinstance(job, FakeJob)
        request = job.request
        assert (request.sensors, request.mode, request.fault_step, request.steps) == (
            (0, 7),
            "stuck",
            100,
            101,
        )


def test_the_compare_tab_refuses_a_bad_sensor_at_once_and_keeps_the_show(runs_dir: Path) -> None:
    with dashboard_in_process(runs_dir, "cs") as dashboard:
        compare, stage = dashboard.compare, dashboard.stage
        compare.list_runs(["bs", "cs"])
        shown = stage.show
        compare.sensors.value = "9"
        dashboard.status.guarded(None, compare.compare)
        assert dashboard.status.text == "⚠ sensor index 9 is not in 0..7"
        assert stage.show is shown  # nothing new on show
        compare.sensors.value = "2,3"
        dashboard.status.guarded(None, compare.compare)
        assert dashboard.status.text == "comparing bs and cs"
        assert stage.show is not shown and stage.show is not None
        assert stage.show.fault is not None and stage.show.fault[1] == (2, 3)
