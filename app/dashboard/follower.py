"""Following a training run as its file is written: progress, and each new best to put on show.

No viser and no process here: the follower is told the job's state at each poll and reads the
run file (SWMR), so it can follow a run written by anything, a test included.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from app import store
from app.dashboard.stage import run_robot
from app.dashboard.training_job import JobState
from app.phases.live import RobotSpec
from app.settings.config import RunConfig

FINISHED_RETRIES = 5
"""Polls to retry reading a finished run's file before giving up on its last generations."""


@dataclass(frozen=True)
class Best:
    """The best individual of a newly completed generation, to put on show at once."""

    generation: int
    robot: RobotSpec
    life: int  # the run's life time T
    control_period: float


@dataclass(frozen=True)
class Progress:
    """What one poll found."""

    state: JobState
    generations: int  # completed generations, as last read
    total: int
    history: store.History | None  # as last read (None until the first good read)
    best: Best | None  # a generation's best not reported before; None if nothing new
    elapsed: float  # seconds spent running, pauses excluded
    error: str  # the job's error message when it failed
    ended: bool  # the job is over and its file read: the follower has nothing more to say

    @property
    def fraction(self) -> float:
        return self.generations / self.total

    def describe(self) -> str:
        """One line: `running · generation 3/10 · best 0.41 · mean 0.20 · 12 s · ETA 28 s`."""
        if self.state == "failed":
            return f"failed: {self.error}"
        line = f"{self.state} · generation {self.generations}/{self.total}"
        if self.history is not None and len(self.history.best_fitness):
            best, mean = self.history.best_fitness[-1], self.history.mean_fitness[-1]
            line += f" · best {best:.4f} · mean {mean:.4f}"
        line += f" · {self.elapsed:.0f} s"
        if self.state == "running" and self.generations:
            eta = self.elapsed / self.generations * (self.total - self.generations)
            line += f" · ETA {eta:.0f} s"
        return line


class TrainingFollower:
    """Reads the run file `out` of a training of `config` at each `poll`.

    Args:
        out: the run file being written (it may not exist yet).
        config: the run's configuration (generations to expect, life time T).
    """

    def __init__(self, out: Path, config: RunConfig) -> None:
        self.out = Path(out)
        self.config = config
        self.history: store.History | None = None
        self.shown = -1  # the generation whose best was last reported
        self._reader: store.RunReader | None = None
        self._retries = 0

    def poll(self, state: JobState, elapsed: float = 0.0, error: str = "") -> Progress:
        """Read what the file holds now, given the job's `state` taken just before.

        A job that ended is read once more (a finished job's file is complete); if that read
        fails, later polls retry a few times before the follower gives up and ends.
        """
        history, best = self._read()
        if history is not None:
            self.history = history
        over = state not in ("running", "paused", "stopping")
        retry = history is None and state == "finished" and self._retries < FINISHED_RETRIES
        self._retries += over and retry
        ended = over and not retry
        if ended:
            self.close()
        return Progress(
            state=state,
            generations=len(self.history.best_fitness) if self.history is not None else 0,
            total=self.config.training.generations,
            history=self.history,
            best=best,
            elapsed=elapsed,
            error=error,
            ended=ended,
        )

    def _read(self) -> tuple[store.History | None, Best | None]:
        """The run's history so far and a new best, or (None, None) if unreadable right now.

        A SWMR reader can catch the writer mid-flush (h5py then raises); the reader is dropped
        and the file reopened at the next poll, which sees a consistent state again.
        """
        if not self.out.exists():
            return None, None
        try:
            if self._reader is None:
                self._reader = store.RunReader(self.out)
            else:
                self._reader.refresh()
            history = self._reader.history()
            last = len(history.best_fitness) - 1
            best = None
            if last >= 0 and last != self.shown:
                training = self.config.training
                robot = run_robot(self._reader, last)
                best = Best(last, robot, training.steps, training.control_period)
                self.shown = last
            return history, best
        except Exception:  # a torn SWMR read, or a file not yet complete: retry next poll
            self.close()
            return None, None

    def close(self) -> None:
        if self._reader is not None:
            self._reader.close()
            self._reader = None
