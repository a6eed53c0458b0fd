"""Run an experiment on Dask: one task per (arm, seed) = a training run plus all its conditions.

Folder (under the runs dir): `experiments/NAME/SCALE/ARM-seedN.h5` are ordinary run files, each
holding its conditions as implementations; `experiments/NAME/summary-SCALE.h5` is the summary
(`summary.py`). A rerun skips finished runs and conditions and resumes cut runs from their
checkpoints; a run file whose config differs from the experiment's is an error, never
overwritten. Every draw is keyed by the run seed, so results do not depend on the cluster,
the worker count, the order, retries or resumption.
"""

from __future__ import annotations

import hashlib
import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from app.config import ImplementationSettings, RunConfig
from app.experiments.progress import TOPIC, Progress, outcome_line
from app.experiments.results import CONVERGENCE_SHARE, Condition, ExperimentResults
from app.experiments.spec import ExperimentError, ExperimentSpec, check_name, load_file
from app.experiments.summary import write_summary
from app.security import local_cluster_security
from app.store import RunFileError, RunReader
from app.store.files import atomic_file
from sim.arena import ArenaSpec

Echo = Callable[[str], None]
Watch = Callable[[Progress], None]


# --- the folder -----------------------------------------------------------------------------


def experiment_dir(runs_dir: str | Path, name: str) -> Path:
    """`RUNS_DIR/experiments/NAME` (the name is checked: no path escapes the runs dir)."""
    try:
        check_name(name)
    except ValueError as error:
        raise ExperimentError(str(error)) from None
    return Path(runs_dir) / "experiments" / name


DEFINITION = "experiment.toml"  # a --file experiment's own file, kept in its folder


def definition_path(runs_dir: str | Path, name: str) -> Path:
    """`RUNS_DIR/experiments/NAME/experiment.toml`: the file a `--file` experiment ran from."""
    return experiment_dir(runs_dir, name) / DEFINITION


def saved_spec(runs_dir: str | Path, name: str) -> ExperimentSpec | None:
    """The experiment a runs dir keeps the file of (None when its folder has none).

    Raises:
        ExperimentError: the kept file is not a valid experiment named `name`.
    """
    path = definition_path(runs_dir, name)
    if not path.is_file():
        return None
    spec = load_file(path)
    if spec.name != name:
        raise ExperimentError(f"{path} defines experiment {spec.name!r}, not {name!r}")
    return spec


def keep_definition(runs_dir: str | Path, name: str, text: str) -> Path:
    """Keep an experiment's file in its folder (replacing an older copy in one step), so that
    `status`, `report` and the dashboard find it by name."""
    path = definition_path(runs_dir, name)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path, overwrite=True) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def summary_path(runs_dir: str | Path, name: str, scale: str) -> Path:
    """`RUNS_DIR/experiments/NAME/summary-SCALE.h5`."""
    return experiment_dir(runs_dir, name) / f"summary-{scale}.h5"


@dataclass(frozen=True)
class Task:
    """One (arm, seed): what a Dask task needs, as plain data."""

    arm: str
    seed: int
    path: str
    config_json: str
    conditions: tuple[tuple[str, str], ...]  # (name, ImplementationSettings JSON)
    generation_cost: int  # robot-steps of one generation
    condition_cost: int  # trial-steps of one condition

    @property
    def name(self) -> str:
        return f"{self.arm}-seed{self.seed}"

    @property
    def key(self) -> str:
        """A Dask key, unique per run file and the same on every rerun."""
        digest = hashlib.sha1(self.path.encode()).hexdigest()[:10]
        return f"gnp-lab-run-{self.name}-{digest}"

    @property
    def config(self) -> RunConfig:
        return RunConfig.model_validate_json(self.config_json)


def plan(
    spec: ExperimentSpec, scale: str, runs_dir: str | Path, seeds: int | None = None
) -> list[Task]:
    """Every (arm, seed) task of the experiment at `scale`, arms outer, seeds inner."""
    folder = experiment_dir(runs_dir, spec.name) / scale
    tasks = []
    starts: dict[str, int] = {}
    for arm in spec.arms:
        for seed in spec.seed_list(scale, seeds):  # type: ignore[arg-type]
            config = spec.run_config(arm.name, scale, seed)
            settings = [
                (c.name, spec.condition_settings(c, config, scale)) for c in spec.conditions
            ]
            trials = [_start_poses(s.arena, starts) * s.repeats for _, s in settings]
            tasks.append(
                Task(
                    arm=arm.name,
                    seed=seed,
                    path=str(folder / f"{arm.name}-seed{seed}.h5"),
                    config_json=config.model_dump_json(),
                    conditions=tuple((n, s.model_dump_json()) for n, s in settings),
                    generation_cost=config.training.population * config.training.steps,
                    condition_cost=max(
                        [n * s.steps for n, (_, s) in zip(trials, settings, strict=True)] or [0]
                    ),
                )
            )
    return tasks


def _start_poses(arena: ArenaSpec, known: dict[str, int]) -> int:
    """How many start poses `arena` (an inline spec, see `app.arenas`) has."""
    return len(arena.start_poses)


@dataclass(frozen=True)
class Work:
    """What an experiment costs at one scale, in simulated steps."""

    runs: int
    robot_steps: int  # training: generations × population × life time, summed over the runs
    trial_steps: int  # implementation: conditions × trials × steps, summed over the runs


def work(spec: ExperimentSpec, scale: str) -> Work:
    """The simulated work of `spec` at `scale` (its default seeds; a seed changes no size)."""
    seeds = len(spec.seed_list(scale))  # type: ignore[arg-type]
    robot_steps = trial_steps = 0
    starts: dict[str, int] = {}
    for arm in spec.arms:
        config = spec.run_config(arm.name, scale, 0)
        t = config.training
        robot_steps += seeds * t.generations * t.population * t.steps
        for condition in spec.conditions:
            s = spec.condition_settings(condition, config, scale)
            trial_steps += seeds * _start_poses(s.arena, starts) * s.repeats * s.steps
    return Work(runs=seeds * len(spec.arms), robot_steps=robot_steps, trial_steps=trial_steps)


@dataclass
class RunState:
    """What a run file holds of its task."""

    generations_done: int = 0
    generations: int = 0
    finished: bool = False
    conditions: tuple[str, ...] = ()

    def complete(self, task: Task) -> bool:
        return self.finished and all(name in self.conditions for name, _ in task.conditions)


def inspect(task: Task) -> RunState:
    """The state of a task's run file (empty if absent).

    Raises:
        ExperimentError: the file holds another config, or another condition under a name.
    """
    path = Path(task.path)
    config = task.config
    state = RunState(generations=config.training.generations)
    if not path.exists():
        return state
    try:
        with RunReader(path) as run:
            if run.config != config:
                raise ExperimentError(
                    f"{path} holds a run with another config than the experiment's "
                    f"{task.name} (left untouched; move it away or use another --runs-dir)"
                )
            names = run.implementation_names()
            for name, settings_json in task.conditions:
                stored = (
                    run.implementation(name, recorded=False).settings if name in names else None
                )
                if stored is not None and stored.model_dump_json() != settings_json:
                    raise ExperimentError(
                        f"{path} holds an implementation {name!r} with other settings than "
                        "the experiment's condition (left untouched)"
                    )
            state.generations_done = run.generations_done
            state.finished = run.finished
            state.conditions = tuple(n for n, _ in task.conditions if n in names)
    except RunFileError as error:
        raise ExperimentError(f"{path}: {error}") from None
    return state


@dataclass(frozen=True)
class ScaleStatus:
    """What an experiment's folder holds at one scale, run by run."""

    tasks: tuple[Task, ...]
    states: tuple[RunState, ...]  # empty for a run whose file cannot be used
    problems: dict[str, str]  # task key → why its file cannot be used

    @property
    def done(self) -> int:
        """Runs trained with every condition implemented."""
        return sum(s.complete(t) for s, t in zip(self.states, self.tasks, strict=True))


def scale_status(
    spec: ExperimentSpec, scale: str, runs_dir: str | Path, seeds: int | None = None
) -> ScaleStatus:
    """Every run's state at `scale`; a foreign or half-replaced file is a problem, not an error."""
    tasks = plan(spec, scale, runs_dir, seeds)
    states, problems = [], {}
    for task in tasks:
        try:
            states.append(inspect(task))
        except ExperimentError as error:  # a foreign file, or one being replaced right now
            states.append(RunState(generations=task.config.training.generations))
            problems[task.key] = str(error)
    return ScaleStatus(tuple(tasks), tuple(states), problems)


# --- one task (runs inside a Dask worker, or in-process) -------------------------------------


def _emitter(task: Task) -> Callable[[dict[str, Any]], None]:
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return lambda msg: None
    return lambda msg: worker.log_event(TOPIC, {"task": task.key, **msg})


def run_task(task: Task) -> dict[str, Any]:
    """Train (or resume) one run and implement its missing conditions, in this process.

    Returns the run's final best fitness and each condition's means (plain floats).
    """
    from app.implementation import implement
    from app.training import resume, train

    emit = _emitter(task)
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


# --- the client -----------------------------------------------------------------------------


def warm_numba(tasks: list[Task], client: Any = None) -> None:
    """Compile (or load) numba's cached kernels once, in this process, before fanning out:
    several workers compiling the same cache at once can race (numba#4807). Then, given a Dask
    `client`, have every worker load them as it starts, not inside its first task."""
    from app.experiments.warm import WarmWorkers, controllers, warm_up

    configs = controllers([t.config for t in tasks])
    warm_up(configs)
    # After the cache is written: the workers only read it. Workers inside this process (an
    # in-process cluster) are warm already, and their warm-up would hold the event loop that
    # this process's scheduler and client share.
    if client is not None and not _in_process(client):
        client.register_plugin(WarmWorkers(configs))


def _in_process(client: Any) -> bool:
    """Every worker of `client`'s cluster lives in this process (`processes=False`)."""
    workers = client.scheduler_info().get("workers", {})
    return bool(workers) and all(str(a).startswith("inproc://") for a in workers)


def default_workers() -> int:
    """One worker per core."""
    from app.training import default_workers as cores

    return cores()


NO_DASHBOARD: dict[str, Any] = {
    "dashboard_address": None,
    # The scheduler still serves its HTTP routes: on a free loopback port, not on 8787, which a
    # second cluster on the machine would find taken (and warn about).
    "scheduler_kwargs": {"dashboard_address": "127.0.0.1:0"},
}
"""LocalCluster arguments: no dashboard, and nothing on a fixed port."""


@contextmanager
def connect(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A Dask client: of the cluster at `scheduler`, or of a new LocalCluster on 127.0.0.1
    with `workers` single-threaded worker processes (default: one per core)."""
    import logging

    import dask
    from distributed import Client, LocalCluster

    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
        if scheduler:
            try:
                client = Client(scheduler, timeout="20s")
            except (OSError, TimeoutError) as error:
                raise ExperimentError(
                    f"cannot reach the Dask scheduler {scheduler}: {error}"
                ) from None
            try:
                yield client
            finally:
                client.close()
            return
        with _ignoring_ctrl_c():  # the worker processes inherit it
            cluster = LocalCluster(
                n_workers=workers or default_workers(),
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                silence_logs=logging.CRITICAL,  # a failed task is reported on one line
                security=local_cluster_security(),  # TLS: no other local user gets in
                **NO_DASHBOARD,
            )
        with cluster, Client(cluster) as client:
            yield client


@contextmanager
def _ignoring_ctrl_c() -> Iterator[None]:
    """Ignore SIGINT meanwhile. Ctrl-C reaches the whole foreground process group; worker
    processes started meanwhile ignore it, and the client alone stops (closing its cluster)."""
    try:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous if previous is not None else signal.SIG_DFL)


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


# --- results --------------------------------------------------------------------------------


def convergence_generation(best_fitness: np.ndarray) -> float:
    """The first generation (from 1) whose best fitness reaches CONVERGENCE_SHARE of the last."""
    final = best_fitness[-1]
    reached = np.flatnonzero(best_fitness >= CONVERGENCE_SHARE * final)
    return float(reached[0] + 1)


def _fault_effects(
    spec: ExperimentSpec,
    conditions: tuple[Condition, ...],
    scalars: dict[tuple[str, str, str], np.ndarray],
    curves: dict[tuple[str, str, str], np.ndarray],
) -> None:
    """fault_effect of every fault condition: its reward per step from the fault step on minus
    the control's over the same steps, run by run (NaN where either is missing)."""
    if spec.control is None:
        return
    for arm in spec.arms:
        control = curves[("reward_per_step", arm.name, spec.control)]
        for c in conditions:
            if c.fault_step is None:
                continue
            ours = curves[("reward_per_step", arm.name, c.name)]
            scalars[("fault_effect", arm.name, c.name)] = ours[:, c.fault_step :].mean(
                axis=1
            ) - control[:, c.fault_step :].mean(axis=1)


def collect(
    spec: ExperimentSpec,
    scale: str,
    runs_dir: str | Path,
    seeds: int | None = None,
    looks: tuple[int, ...] = (),
) -> ExperimentResults:
    """The experiment's results from its run files (NaN where a run or condition is missing).

    `looks` are the seeds per arm at each planned look of an adaptive run (see `run_adaptive`).
    """
    tasks = plan(spec, scale, runs_dir, seeds)
    seed_list = spec.seed_list(scale, seeds)  # type: ignore[arg-type]
    n = len(seed_list)
    conditions = spec.conditions_info(scale)
    scalars: dict[tuple[str, str, str], np.ndarray] = {}
    curves: dict[tuple[str, str, str], np.ndarray] = {}
    fault_steps = {c.name: c.steps if c.fault_step is None else c.fault_step for c in conditions}
    for arm in spec.arms:
        generations = spec.run_config(arm.name, scale, 0).training.generations
        scalars[("final_best_fitness", arm.name, "")] = np.full(n, np.nan)
        scalars[("convergence_generation", arm.name, "")] = np.full(n, np.nan)
        curves[("best_fitness_curve", arm.name, "")] = np.full((n, generations), np.nan)
        for c in conditions:
            for metric in ("mean_reward", "mean_reward_before_fault", "mean_reward_after_fault"):
                scalars[(metric, arm.name, c.name)] = np.full(n, np.nan)
            curves[("reward_per_step", arm.name, c.name)] = np.full((n, c.steps), np.nan)
    for task in tasks:
        row = seed_list.index(task.seed)
        state = inspect(task)
        if not Path(task.path).exists():
            continue
        with RunReader(task.path) as run:
            history = run.history()
            curves[("best_fitness_curve", task.arm, "")][row, : len(history.best_fitness)] = (
                history.best_fitness
            )
            if state.finished:
                scalars[("final_best_fitness", task.arm, "")][row] = history.best_fitness[-1]
                scalars[("convergence_generation", task.arm, "")][row] = convergence_generation(
                    np.asarray(history.best_fitness)
                )
            for name in state.conditions:
                result = run.implementation(name, recorded=False)
                scalars[("mean_reward", task.arm, name)][row] = result.mean_reward
                before = result.reward_per_step[: fault_steps[name]]  # every trial is as long
                scalars[("mean_reward_before_fault", task.arm, name)][row] = (
                    before.mean() if len(before) else np.nan  # a fault at step 0: no before
                )
                scalars[("mean_reward_after_fault", task.arm, name)][row] = result.mean_after_fault
                curves[("reward_per_step", task.arm, name)][row] = result.reward_per_step
    _fault_effects(spec, conditions, scalars, curves)
    cost = work(spec, scale)
    return ExperimentResults(
        name=spec.name,
        description=spec.description,
        source=spec.source,
        scale=scale,
        arms=spec.arms_info(),
        seeds=seed_list,
        conditions=conditions,
        comparisons=spec.comparisons_info(),
        thesis=spec.thesis_info(),
        control=spec.control,
        looks=looks,
        steps_per_run=(cost.robot_steps + cost.trial_steps) / cost.runs,
        scalars=scalars,
        curves=curves,
    )


def run_experiment(
    spec: ExperimentSpec,
    scale: str,
    runs_dir: str | Path,
    *,
    seeds: int | None = None,
    client: Any = None,
    scheduler: str | None = None,
    workers: int | None = None,
    quiet: bool = False,
    echo: Echo | None = None,
    watch: Watch | None = None,
    definition: str | None = None,
) -> ExperimentResults:
    """Run (or finish) an experiment, then write and return its summary.

    `client` (an existing Dask client) wins over `scheduler`; with neither, a LocalCluster is
    started for the run and closed after it. `echo` gets each run's outcome line, `watch` the
    live `Progress` (see `execute`). `definition`, the text of the experiment's file, is kept
    in its folder (`keep_definition`) once its run files are known to be its own.

    Raises:
        ExperimentError: a run file holds another config, or some runs failed (the summary
            is still written, with NaN for them).
    """
    spec.scale(scale)
    tasks = plan(spec, scale, runs_dir, seeds)
    states = [inspect(task) for task in tasks]  # refuse a foreign file before starting anything
    if definition is not None:
        keep_definition(runs_dir, spec.name, definition)
    if all(state.complete(task) for state, task in zip(states, tasks, strict=True)):
        errors: list[str] = []
    elif client is not None:
        errors = execute(tasks, client, quiet, echo, watch)
    else:
        with connect(scheduler, workers) as own:
            errors = execute(tasks, own, quiet, echo, watch)
    results = collect(spec, scale, runs_dir, seeds)
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
