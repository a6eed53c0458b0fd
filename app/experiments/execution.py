"""Tasks on Dask: what one task does inside a worker (`run_task`) and how the client hands the
unfinished ones out and gathers their outcomes (`execute`).

Every draw is keyed by the run seed, so results do not depend on the cluster, the worker
count, the order, retries or resumption; a rerun skips finished runs and conditions and resumes
cut runs from their checkpoints.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from app.experiments.cluster import warm_numba
from app.experiments.planning import Task, inspect
from app.experiments.progress import TOPIC, Echo, Progress, Watch, outcome_line
from app.settings.config import ImplementationSettings
from app.store import RunReader


def _emitter(task: Task) -> Callable[[dict[str, Any]], None]:
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return lambda _msg: None
    return lambda msg: worker.log_event(TOPIC, {"task": task.key, **msg})


def run_task(task: Task) -> dict[str, Any]:
    """Train (or resume) one run and implement its missing conditions, in this process.

    Returns the run's final best fitness and each condition's means (plain floats).
    """
    from app.phases.implementation import implement
    from app.phases.training import resume, train

    emit = _emitter(task)
    if task.task_json:
        return _run_task_run(task, emit)
    path = Path(task.path)
    state = inspect(task)

    def progress(summary: Any) -> None:
        emit({"generations": summary.generation + 1})

    if not path.exists():
        train(task.config, path, workers=1, progress=progress)
    elif not state.finished:
        with RunReader(path) as run:
            cut_before_checkpoint = run.checkpoint() is None
        if cut_before_checkpoint:  # killed between creating the file and generation 0's data
            path.unlink()
            train(task.config, path, workers=1, progress=progress)
        else:
            resume(path, workers=1, progress=progress)
    outcome: dict[str, Any] = {"task": task.key, "arm": task.arm, "seed": task.seed}
    for name, settings_json in task.conditions:
        if name not in state.conditions:
            settings = ImplementationSettings.model_validate_json(settings_json)
            implement(path, settings, name=name, workers=1)
        emit({"condition": name})
    with RunReader(path) as run:
        outcome["final_best_fitness"] = float(run.history().best_fitness[-1])
        results = {name: run.implementation(name, recorded=False) for name, _ in task.conditions}
    outcome["conditions"] = {n: (r.mean_reward, r.mean_after_fault) for n, r in results.items()}
    return outcome


def _run_task_run(task: Task, emit: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    """A task experiment's run (app.tasks.peer): train or resume, then test the final elite."""
    import numpy as np

    from app.experiments.results import PROTOCOL_METRICS
    from app.tasks.peer import PeerRun, run_peer

    inspect(task)  # a foreign file is refused, not overwritten
    peer = PeerRun.model_validate_json(task.task_json)
    result = run_peer(peer, task.path, progress=lambda g: emit({"generations": g + 1}))
    assert result.test_returns is not None
    return {
        "task": task.key,
        "arm": task.arm,
        "seed": task.seed,
        "final_best_fitness": float(result.best_curve[-1]),
        "test_return": float(np.mean(result.test_returns)),
        **{
            metric: float(np.mean(result.protocol_returns[protocol]))
            for protocol, metric in PROTOCOL_METRICS.items()
            if result.protocol_returns and protocol in result.protocol_returns
        },
        **(
            {}
            if result.training_env_steps is None
            else {"training_env_steps": result.training_env_steps}
        ),
        "conditions": {},
    }


def execute(
    tasks: list[Task],
    client: Any,
    quiet: bool = False,
    echo: Echo | None = None,
    watch: Watch | None = None,
) -> list[str]:
    """Run the unfinished tasks on `client`; returns the errors of the tasks that failed.

    `watch` is given the live `Progress` once the tasks are submitted (to read its counts).
    """
    import sys

    from distributed import as_completed

    states = {t.key: inspect(t) for t in tasks}
    todo = [t for t in tasks if not states[t.key].complete(t)]
    if not todo:
        return []
    if not quiet:
        sys.stderr.write("warming numba's cache in this process (minutes the first time)...\n")
    warm_numba(todo, client)
    progress = Progress(tasks, states, quiet=quiet)
    say = echo or progress.write
    client.subscribe_topic(TOPIC, progress.event)
    errors = []
    try:
        futures = {client.submit(run_task, t, key=t.key, pure=False, retries=2): t for t in todo}
        if watch is not None:
            watch(progress)
        for future in as_completed(futures):
            task = futures[future]
            try:
                outcome = future.result()
            except Exception as error:  # a failed run must not hide the others' results
                reason = f"{type(error).__name__}: {error}".splitlines()[0]
                errors.append(f"{task.name}: {reason}")
                say(f"{task.name} failed: {reason}")
                continue
            progress.finished(task)
            say(outcome_line(outcome))
    finally:
        client.unsubscribe_topic(TOPIC)
        progress.close()
    return errors
