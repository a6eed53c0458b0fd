"""An experiment started from the dashboard: `run_experiment`, or `run_adaptive` for stages of
seeds, in a background thread, on the dashboard's own Dask LocalCluster (127.0.0.1, one
single-threaded worker process per core).

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

from app.experiments import cluster, layout, planning, runner
from app.experiments.adaptive import Stage, run_adaptive
from app.experiments.lock import experiment_lock
from app.experiments.progress import Counts, Progress
from app.experiments.results import ExperimentResults
from app.experiments.runner import RunOptions
from app.experiments.sequential import Design
from app.experiments.spec import ExperimentError, ExperimentSpec

Phase = Literal["starting", "running", "finished", "failed", "stopped"]
ENDED: tuple[Phase, ...] = ("finished", "failed", "stopped")
OUTCOME_LINES = 3  # the last finished runs' lines kept for the page


class DaskCluster:
    """The dashboard's LocalCluster, started on first use (`cluster.connect`), closed by `close`.

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
                self._client = stack.enter_context(cluster.connect(workers=self.workers))
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
    seeds: int | None = None  # adaptive: seeds per arm of the stage under way

    @property
    def active(self) -> bool:
        """Whether the job was going when this was taken: read with its phase, so a job that
        ends meanwhile is not reported in the phase it left."""
        return self.phase not in ENDED


class _StartedOnUse:
    """The cluster's client, started only when a stage has runs to submit (`run_adaptive`
    takes a client up front, and a rerun of a decided experiment runs nothing)."""

    def __init__(self, cluster: DaskCluster, stopping: threading.Event) -> None:
        self._cluster, self._stopping = cluster, stopping

    def __getattr__(self, name: str) -> Any:
        if self._stopping.is_set():  # stopped between stages: no new cluster
            raise ExperimentError("stopped")
        return getattr(self._cluster.client(), name)


class ExperimentJob:
    """`runner.run_experiment(spec, scale, runs_dir)` in a daemon thread, on `cluster`; with a
    `design`, `run_adaptive` in its stages (the design's looks) instead.

    The thread reads the run files' state first (a foreign file fails the job before anything
    runs), then runs the missing runs and writes the summary (an adaptive run: after every
    look); `snapshot` says how far it is.
    """

    def __init__(
        self,
        spec: ExperimentSpec,
        scale: str,
        runs_dir: Path,
        cluster: DaskCluster,
        design: Design | None = None,
    ) -> None:
        self.spec, self.scale, self.runs_dir, self.cluster = spec, scale, runs_dir, cluster
        self.design = design
        self.since = time.time()  # a summary written after this is the job's own
        self.results: ExperimentResults | None = None
        self.stages: tuple[Stage, ...] = ()
        self.reported = False
        self._phase: Phase = "starting"
        self._detail = "reading its run files"
        self._progress: Progress | None = None
        self._seeds: int | None = None
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
            seeds=self._seeds,
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
        if self.design is not None:  # the stage whose runs were just submitted
            seeds = 1 + max(task.seed for task in progress.tasks)
            self._seeds = seeds
            look = self.design.looks.index(seeds) + 1  # run_adaptive plans a look's seeds
            self._detail = (
                f"stage {look} of {len(self.design.looks)} ({seeds} seeds per arm) "
                "running on the Dask cluster"
            )

    def _run(self) -> None:
        try:
            if self.design is not None:
                self._run_adaptive(self.design)
                return
            status = planning.scale_status(self.spec, self.scale, self.runs_dir)
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
            with experiment_lock(layout.experiment_dir(self.runs_dir, self.spec.name), self.scale):
                self.results = runner.run_experiment(
                    self.spec,
                    self.scale,
                    self.runs_dir,
                    options=RunOptions(
                        client=client, quiet=True, echo=self._echo, watch=self._watch
                    ),
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

    def _run_adaptive(self, design: Design) -> None:
        """`run_adaptive` up to the design's last look, on the cluster once runs are due."""
        most = design.looks[-1]
        status = planning.scale_status(self.spec, self.scale, self.runs_dir, most)
        if status.problems:  # any look's file: refused before anything runs
            raise ExperimentError(next(iter(status.problems.values())))
        first = design.looks[0]
        states = {t.key: s for t, s in zip(status.tasks, status.states, strict=True)}
        # The first stage's counts from the files until the runner's own Progress takes over.
        tasks = [t for t in status.tasks if t.seed < first]
        self._progress = Progress(tasks, {t.key: states[t.key] for t in tasks}, quiet=True)
        self._seeds = first
        self._phase = "running"
        self._detail = "stage 1: starting the Dask cluster and loading numba's kernels"
        with experiment_lock(layout.experiment_dir(self.runs_dir, self.spec.name), self.scale):
            self.results, self.stages = run_adaptive(
                self.spec,
                self.scale,
                self.runs_dir,
                stage_seeds=first,
                max_seeds=most,
                options=RunOptions(
                    client=_StartedOnUse(self.cluster, self._stopping),
                    quiet=True,
                    echo=self._echo,
                    watch=self._watch,
                ),
            )
        looks = self.stages[-1].seeds if self.stages else 0
        self._phase = "finished"
        self._detail = f"summary written after {len(self.stages)} look(s), {looks} seeds per arm"
