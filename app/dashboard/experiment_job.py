"""An experiment started from the dashboard: `run_experiment` in a background thread, on the
dashboard's own Dask LocalCluster (127.0.0.1, one single-threaded worker process per core).

The cluster starts with the first experiment and lives until the dashboard stops; its worker
processes do the training, so the page's process only waits on Dask and reads progress events.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from app.experiments import runner
from app.experiments.lock import experiment_lock
from app.experiments.progress import Counts, Progress
from app.experiments.results import ExperimentResults
from app.experiments.spec import ExperimentError, ExperimentSpec

Phase = Literal["starting", "running", "finished", "failed", "stopped"]
ENDED: tuple[Phase, ...] = ("finished", "failed", "stopped")
OUTCOME_LINES = 3  # the last finished runs' lines kept for the page


class DaskCluster:
    """The dashboard's LocalCluster, started on first use (`runner.connect`), closed by `close`.

    Args:
        workers: worker processes (default: one per core).
    """

    def __init__(self, workers: int | None = None) -> None:
        self.workers = workers
        self._lock = threading.Lock()
        self._stack: contextlib.ExitStack | None = None
        self._client: Any = None

    @property
    def started(self) -> bool:
        return self._client is not None

    def client(self) -> Any:
        """The client, starting the cluster if there is none (seconds: call it off the GUI)."""
        with self._lock:
            if self._client is None:
                stack = contextlib.ExitStack()
                self._client = stack.enter_context(runner.connect(workers=self.workers))
                self._stack = stack
            return self._client

    def close(self) -> None:
        """Close the client and the cluster (its worker processes end)."""
        with self._lock:
            stack, self._stack, self._client = self._stack, None, None
        if stack is not None:
            with contextlib.suppress(Exception):  # a cluster already torn down
                stack.close()


@dataclass(frozen=True)
class JobSnapshot:
    """A started experiment as it is now."""

    phase: Phase
    detail: str  # what it is doing, or why it failed
    counts: Counts | None
    outcomes: tuple[str, ...]  # the last finished runs, as `gnp-lab experiment run` prints them
    seconds: float


class ExperimentJob:
    """`runner.run_experiment(spec, scale, runs_dir)` in a daemon thread, on `cluster`.

    The thread reads the run files' state first (a foreign file fails the job before anything
    runs), then runs the missing runs and writes the summary; `snapshot` says how far it is.
    """

    def __init__(
        self, spec: ExperimentSpec, scale: str, runs_dir: Path, cluster: DaskCluster
    ) -> None:
        self.spec, self.scale, self.runs_dir, self.cluster = spec, scale, runs_dir, cluster
        self.results: ExperimentResults | None = None
        self.reported = False
        self._phase: Phase = "starting"
        self._detail = "reading its run files"
        self._progress: Progress | None = None
        self._outcomes: deque[str] = deque(maxlen=OUTCOME_LINES)
        self._started = time.monotonic()
        self._ended: float | None = None
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name="experiment-job", daemon=True)
        self._thread.start()

    @property
    def active(self) -> bool:
        return self._phase not in ENDED

    def snapshot(self) -> JobSnapshot:
        progress = self._progress
        end = self._ended if self._ended is not None else time.monotonic()
        return JobSnapshot(
            phase=self._phase,
            detail=self._detail,
            counts=progress.counts() if progress is not None else None,
            outcomes=tuple(self._outcomes),
            seconds=end - self._started,
        )

    def stop(self) -> None:
        """Stop: close the cluster (its workers end mid-run; a rerun resumes the cut runs)."""
        if self.active:
            self._stopping.set()
            self._detail = "stopping"
            self.cluster.close()

    def join(self, timeout: float | None = None) -> None:
        self._thread.join(timeout)

    def _echo(self, line: str) -> None:
        if not self._stopping.is_set():  # not the runs cancelled by a stop
            self._outcomes.append(line)

    def _watch(self, progress: Progress) -> None:
        self._progress = progress
        self._detail = "running on the Dask cluster"

    def _run(self) -> None:
        try:
            status = runner.scale_status(self.spec, self.scale, self.runs_dir)
            if status.problems:
                raise ExperimentError(next(iter(status.problems.values())))
            states = {t.key: s for t, s in zip(status.tasks, status.states, strict=True)}
            # Counts from the files until the runner's own Progress takes over.
            self._progress = Progress(list(status.tasks), states, quiet=True)
            if status.done < len(status.tasks):
                self._detail = "starting the Dask cluster"
                client = self.cluster.client()
                self._detail = "loading numba's kernels, then submitting the runs"
            else:
                client, self._detail = None, "every run is done: writing the summary"
            self._phase = "running"
            with experiment_lock(runner.experiment_dir(self.runs_dir, self.spec.name)):
                self.results = runner.run_experiment(
                    self.spec,
                    self.scale,
                    self.runs_dir,
                    client=client,
                    quiet=True,
                    echo=self._echo,
                    watch=self._watch,
                )
            self._phase, self._detail = "finished", "summary written"
        except BaseException as error:  # the job's end, whatever it is, belongs on the page
            if self._stopping.is_set():
                self._phase = "stopped"
                self._detail = "finished runs are kept; Start resumes the others"
            else:
                self._phase = "failed"
                text = str(error) if isinstance(error, ExperimentError) else repr(error)
                self._detail = text.splitlines()[0] if text else type(error).__name__
        finally:
            self._ended = time.monotonic()
