"""An implementation phase started from the dashboard, run in a worker process
(`app.system.workers`), with its progress and a way to cancel it.

The child calls `app.phases.implementation.implementation_of` on the run's final best individual (a
GNP individual, or a neural run's net, which does not learn online) and returns the result;
nothing is written to the run file (a run on show, the bundled demo included, stays as it was;
`gnp-lab implement` is the way to store one). As it goes, the child reports the trial-steps it
has done over the worker's pipe (the phase's own `progress` hook, which changes nothing in
the results); `cancel` kills it, and with nothing written there is nothing to undo.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from app.dashboard.controls import build
from app.phases.implementation import StepProgress, implementation_of, trial_count
from app.settings.config import ImplementationSettings
from app.store import Implementation, RunFileError, RunReader
from app.system.workers import Count, Handler, WorkerPool

REPORT_SECONDS = 0.2
"""The child reports its progress at most this often (and once at the end)."""

JobState = Literal["starting", "running", "finished", "failed", "cancelled"]


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
    noise_sigma: float | None = None  # None: the run's own implementation σ

    def settings(self, base: ImplementationSettings) -> ImplementationSettings:
        """The run's own implementation settings with this request's fault, noise and sizes.

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
        if self.noise_sigma is not None:
            values["noise_sigma"] = self.noise_sigma
        return build(ImplementationSettings, values, "implementation settings")


def trial_steps(settings: ImplementationSettings) -> int:
    """The work of an implementation phase, as its progress counts it: trials × steps."""
    return trial_count(settings) * settings.steps


def implement_run(
    request: ImplementationRequest, progress: StepProgress | None = None
) -> Implementation:
    """Run the implementation phase of `request.run`'s last best individual (no file written);
    `progress(done, total)` is told the trial-steps done as it goes."""
    with RunReader(request.run) as run:
        if run.generations_done == 0:
            raise RunFileError(f"{request.run.name} has no completed generation yet")
        settings = request.settings(run.config.implementation)
        generation = run.generations_done - 1
        phase = implementation_of(run, settings, generation, seed=run.seed, name="dashboard")
    return phase(progress=progress)


def _implementer() -> Handler:
    """A worker's state: it implements each request it is given, counting the trial-steps
    done since its last report (at most every REPORT_SECONDS, and at the end)."""

    def handle(request: ImplementationRequest, count: Count) -> Implementation:
        reported, last = 0, 0.0

        def progress(done: int, total: int) -> None:
            nonlocal reported, last
            now = time.monotonic()
            if done > reported and (done >= total or now - last >= REPORT_SECONDS):
                count(done - reported)
                reported, last = done, now

        return implement_run(request, progress)

    return handle


@dataclass(frozen=True)
class JobProgress:
    """How far an implementation job is: trial-steps done of `total`, seconds since it started,
    and the seconds it still needs at its rate so far (None until that rate is known)."""

    state: JobState
    done: int
    total: int
    elapsed: float
    eta: float | None
    steps: int  # a trial's life time T: done / steps trials' worth

    @property
    def fraction(self) -> float:
        return min(1.0, self.done / self.total) if self.total else 0.0

    def describe(self) -> str:
        """`running · 1230 of 3000 trials · 41% · 40 s · ETA 58 s` (trials' worth of steps:
        the trials of a world live side by side, so none ends before the others)."""
        trials = self.total // self.steps if self.steps else 0
        if self.state == "starting":
            return f"starting its worker process · {trials} trials · {self.elapsed:.0f} s"
        line = f"{self.state} · {self.done / max(1, self.steps):.0f} of {trials} trials"
        line += f" · {100 * self.fraction:.0f}% · {self.elapsed:.0f} s"
        if self.eta is not None and self.state == "running":
            line += f" · ETA {self.eta:.0f} s"
        return line


class ImplementationJob:
    """`implement_run(request)` in a worker process of its own, so the page stays responsive.

    Args:
        request: what to implement.
        total: the trial-steps it will take (`trial_steps` of its settings), for the progress;
            0 when unknown.
    """

    def __init__(self, request: ImplementationRequest, total: int = 0) -> None:
        self.request = request
        self.total = total
        self.reported = False
        self.done = 0
        self.started = time.monotonic()
        self._first: tuple[float, int] | None = None  # (when, done) of the first report
        self._last_report = self.started
        self._ended: float | None = None
        self._outcome: tuple[Any, BaseException | None] | None = None
        self._cancelled = False
        self._pool = WorkerPool(1, _implementer)
        self._pool.send(0, request)

    def _count(self, done: int) -> None:
        self.done += done
        self._last_report = time.monotonic()
        if self._first is None:
            self._first = (self._last_report, self.done)

    def _wait(self, timeout: float | None) -> None:
        if self._outcome is not None:
            return
        try:
            worker, result = self._pool.receive(timeout, self._count)
        except Exception as error:  # the request's own error, or a worker that died
            self._outcome = (None, error)
        else:
            if worker < 0:
                return
            self._outcome = (result, None)
        self._ended = time.monotonic()
        self._pool.close()

    @property
    def active(self) -> bool:
        self._wait(0)
        return self._outcome is None

    @property
    def state(self) -> JobState:
        if self.active:
            return "running" if self._first is not None else "starting"
        if self._cancelled:
            return "cancelled"
        assert self._outcome is not None
        return "failed" if self._outcome[1] is not None else "finished"

    def progress(self) -> JobProgress:
        """The progress as reported so far (reports read first)."""
        state = self.state
        now = self._ended if self._ended is not None else time.monotonic()
        eta = None
        if self._first is not None and self.total and self.done > self._first[1]:
            when, first = self._first
            rate = (self.done - first) / max(1e-9, self._last_report - when)
            eta = max(0.0, (self.total - self.done) / rate - (now - self._last_report))
        steps = self.request.steps
        return JobProgress(state, self.done, self.total, now - self.started, eta, steps)

    def cancel(self) -> None:
        """Stop the child at once (killed: it writes nothing, so nothing is left half-done)."""
        if not self.active:
            return
        self._cancelled = True
        self._outcome = (None, None)
        self._ended = time.monotonic()
        self._pool.close()

    def result(self) -> Implementation:
        """The finished result; raises the worker's error (e.g. RunFileError), or
        RuntimeError when cancelled."""
        self._wait(None)
        assert self._outcome is not None
        if self._cancelled:
            raise RuntimeError("the implementation phase was cancelled")
        result, error = self._outcome
        if error is not None:
            raise error
        return result

    def close(self) -> None:
        self._pool.close()
