"""An implementation phase started from the dashboard, run in a child process.

The child calls `app.implementation.run_implementation` on the run's final best individual (a
GNP individual, or a neural run's net, which does not learn online) and returns the result;
nothing is written to the run file (a run on show, the bundled demo included, stays as it was;
`gnp-lab implement` is the way to store one).
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from app.config import ImplementationSettings
from app.dashboard.controls import DashboardInputError
from app.implementation import run_implementation
from app.neural import best_individual
from app.store import Implementation, RunFileError, RunReader


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
        """The run's own implementation settings with this request's fault and sizes."""
        try:
            return ImplementationSettings.model_validate(
                {
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
            )
        except ValueError as error:
            raise DashboardInputError(f"implementation settings: {error}") from None


def implement_run(request: ImplementationRequest) -> Implementation:
    """Run the implementation phase of `request.run`'s last best individual (no file written)."""
    with RunReader(request.run) as run:
        if run.generations_done == 0:
            raise RunFileError(f"{request.run.name} has no completed generation yet")
        settings = request.settings(run.config.implementation)
        cfg, individual = best_individual(run, -1)
        generation = run.generations_done - 1
        seed = run.seed
        control_period = run.config.training.control_period
        c_from = run.config.reward.c_from
    return run_implementation(
        cfg,
        individual,
        settings,
        seed=seed,
        control_period=control_period,
        name="dashboard",
        generation=generation,
        c_from=c_from,
    )


class ImplementationJob:
    """`implement_run(request)` in a spawned child process, so the page stays responsive."""

    def __init__(self, request: ImplementationRequest) -> None:
        self.request = request
        self.reported = False
        self._pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
        self._future: Future[Implementation] = self._pool.submit(implement_run, request)

    @property
    def active(self) -> bool:
        return not self._future.done()

    def result(self) -> Implementation:
        """The finished result; raises the child's error (RunFileError, DashboardInputError)."""
        try:
            return self._future.result()
        finally:
            self._pool.shutdown(wait=False)

    def close(self) -> None:
        self._future.cancel()
        self._pool.shutdown(wait=False, cancel_futures=True)
