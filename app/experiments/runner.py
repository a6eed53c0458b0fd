"""Run an experiment on Dask: one task per (arm, seed) = a training run plus all its conditions.

The rooms: `layout` (where the files live), `planning` (the plan and each run file's state),
`cluster` (the Dask client), `execution` (a task in its worker, the tasks on the client),
`harvest` (the results from the run files). This module runs the whole: the runs not yet done,
then the summary. A run file whose config differs from the experiment's is an error, never
overwritten.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.experiments.cluster import connect
from app.experiments.execution import execute
from app.experiments.harvest import collect
from app.experiments.layout import keep_definition, summary_path
from app.experiments.ledger import Ledger
from app.experiments.planning import Task, inspect, plan
from app.experiments.progress import Echo, Watch
from app.experiments.results import ExperimentResults
from app.experiments.spec import ExperimentError, ExperimentSpec
from app.experiments.summary import write_summary


@dataclass(frozen=True)
class RunOptions:
    """How to run an experiment, whatever it runs (`run_experiment`, `run_adaptive`).

    `client` (an existing Dask client) wins over `scheduler`; with neither, a LocalCluster of
    `workers` processes is started for the run and closed after it. `echo` gets each run's
    outcome line, `watch` the live `Progress` (see `execution.execute`). `definition`, the text
    of the experiment's file, is kept in its folder (`layout.keep_definition`) once its run
    files are known to be its own.
    """

    client: Any = None
    scheduler: str | None = None
    workers: int | None = None
    quiet: bool = False
    echo: Echo | None = None
    watch: Watch | None = None
    definition: str | None = None
    ledger: Ledger | None = None  # a committed report's finished runs: not run again

    def execute(self, tasks: list[Task], client: Any) -> list[str]:
        """`execution.execute` of `tasks` (but the ledger's) on `client` with these options."""
        if self.ledger is not None:
            tasks = self.ledger.pending(tasks)
        return execute(tasks, client, self.quiet, self.echo, self.watch)

    def pending(self, tasks: list[Task]) -> list[Task]:
        """The tasks neither finished here nor held by the ledger."""
        open_tasks = [t for t in tasks if not inspect(t).complete(t)]
        return self.ledger.pending(open_tasks) if self.ledger is not None else open_tasks


def check_task(spec: ExperimentSpec) -> None:
    """A task experiment's task can be run by GNP, and fracnetics is there for its arm.

    Raises:
        ExperimentError: one line saying why not.
    """
    if spec.task is None:
        return
    from app.tasks.common import TaskError
    from app.tasks.config import TaskSettings

    try:
        TaskSettings(id=spec.task.id).adapter()
    except TaskError as error:
        raise ExperimentError(f"experiment {spec.name!r}: {error}") from None
    if any(arm.brain == "fracnetics" for arm in spec.arms):
        try:
            import fracnetics  # noqa: F401
        except ImportError:
            raise ExperimentError(
                f"experiment {spec.name!r}: its fracnetics arm needs fracnetics "
                "(pip install fracnetics)"
            ) from None


def run_experiment(
    spec: ExperimentSpec,
    scale: str,
    runs_dir: str | Path,
    *,
    seeds: int | None = None,
    options: RunOptions | None = None,
) -> ExperimentResults:
    """Run (or finish) an experiment, then write and return its summary.

    Raises:
        ExperimentError: a run file holds another config, or some runs failed (the summary
            is still written, with NaN for them).
    """
    options = options or RunOptions()
    spec.scale(scale)
    check_task(spec)
    tasks = plan(spec, scale, runs_dir, seeds)
    for task in tasks:  # refuse a foreign file before starting anything
        inspect(task)
    if options.definition is not None:
        keep_definition(runs_dir, spec.name, options.definition)
    if not options.pending(tasks):
        errors: list[str] = []
    elif options.client is not None:
        errors = options.execute(tasks, options.client)
    else:
        with connect(options.scheduler, options.workers) as own:
            errors = options.execute(tasks, own)
    results = collect(spec, scale, runs_dir, seeds, ledger=options.ledger)
    unwritten = ""
    try:
        write_summary(results, summary_path(runs_dir, spec.name, scale))
    except ExperimentError as error:  # a full disk, say: not to hide why the runs failed
        if not errors:
            raise
        unwritten = f"; the summary was not written either: {error}"
    if errors:
        raise ExperimentError(f"{len(errors)} run(s) failed; the first: {errors[0]}{unwritten}")
    return results
