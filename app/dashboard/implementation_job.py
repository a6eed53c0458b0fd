"""An implementation phase started from the dashboard, run in a worker process
(`app.system.workers`).

The child calls `app.phases.implementation.implementation_of` on the run's final best individual (a
GNP individual, or a neural run's net, which does not learn online) and returns the result;
nothing is written to the run file (a run on show, the bundled demo included, stays as it was;
`gnp-lab implement` is the way to store one).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.dashboard.controls import build
from app.phases.implementation import implementation_of
from app.settings.config import ImplementationSettings
from app.store import Implementation, RunFileError, RunReader
from app.system.workers import Count, Handler, WorkerPool


@dataclass(frozen=True)
class ImplementationRequest:
    """The Runs tab's implementation fields, validated."""

    run: Path
    sensors: tuple[int, ...]
    mode: str
    fault_step: int
    steps: int
    repeats: int
    schedule: str  # "fixed" | "changing"

    def settings(self, base: ImplementationSettings) -> ImplementationSettings:
        """The run's own implementation settings with this request's fault and sizes.

        Raises:
            DashboardInputError: one line naming each value the model refuses.
        """
        values = {
            **base.model_dump(),
            "broken_sensors": self.sensors,
            "fault_mode": self.mode,
            "fault_step": self.fault_step,
            "steps": self.steps,
            "repeats": self.repeats,
            "schedule": self.schedule,
            "recorded_trials": 0,
            "generation": None,
        }
        return build(ImplementationSettings, values, "implementation settings")


def implement_run(request: ImplementationRequest) -> Implementation:
    """Run the implementation phase of `request.run`'s last best individual (no file written)."""
    with RunReader(request.run) as run:
        if run.generations_done == 0:
            raise RunFileError(f"{request.run.name} has no completed generation yet")
        settings = request.settings(run.config.implementation)
        generation = run.generations_done - 1
        phase = implementation_of(run, settings, generation, seed=run.seed, name="dashboard")
    return phase()


def _implementer() -> Handler:
    """A worker's state: it implements each request it is given."""

    def handle(request: ImplementationRequest, count: Count) -> Implementation:
        return implement_run(request)

    return handle


class ImplementationJob:
    """`implement_run(request)` in a worker process of its own, so the page stays responsive."""

    def __init__(self, request: ImplementationRequest) -> None:
        self.request = request
        self.reported = False
        self._outcome: tuple[Any, BaseException | None] | None = None
        self._pool = WorkerPool(1, _implementer)
        self._pool.send(0, request)

    def _wait(self, timeout: float | None) -> None:
        if self._outcome is not None:
            return
        try:
            worker, result = self._pool.receive(timeout)
        except Exception as error:  # the request's own error, or a worker that died
            self._outcome = (None, error)
        else:
            if worker < 0:
                return
            self._outcome = (result, None)
        self._pool.close()

    @property
    def active(self) -> bool:
        self._wait(0)
        return self._outcome is None

    def result(self) -> Implementation:
        """The finished result; raises the worker's error (e.g. RunFileError)."""
        self._wait(None)
        assert self._outcome is not None
        result, error = self._outcome
        if error is not None:
            raise error
        return result

    def close(self) -> None:
        self._pool.close()
