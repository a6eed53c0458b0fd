"""The plan of an experiment's runs: one task per (arm, seed), what it costs, what its run
file holds of it.

A task is plain data (what a Dask worker needs); `inspect` reads its run file's state and
refuses a file that holds another config than the experiment's (never overwritten);
`StateCache` remembers it while the file is unchanged, for the dashboard's repeated reads.
"""

from __future__ import annotations

import dataclasses
import hashlib
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pydantic_core
from pydantic import BaseModel

from app.experiments.layout import experiment_dir
from app.experiments.spec import ExperimentError, ExperimentSpec
from app.settings.config import ImplementationSettings, RunConfig
from app.store import RunFileError, RunReader
from app.store.files import Stamp, settled, stamp

if TYPE_CHECKING:
    from app.tasks.config import TaskRunConfig


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
    task_json: str = ""  # a task experiment's run (app.tasks.peer.PeerRun JSON); "" = robot

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
    for arm in spec.arms:
        for seed in spec.seed_list(scale, seeds):  # type: ignore[arg-type]
            config = spec.run_config(arm.name, scale, seed)
            if spec.task is not None:
                tasks.append(_task_run(spec, arm.name, seed, config, folder))
                continue
            settings = [
                (c.name, spec.condition_settings(c, config, scale)) for c in spec.conditions
            ]
            tasks.append(
                Task(
                    arm=arm.name,
                    seed=seed,
                    path=str(folder / f"{arm.name}-seed{seed}.h5"),
                    config_json=config.model_dump_json(),
                    conditions=tuple((n, s.model_dump_json()) for n, s in settings),
                    generation_cost=config.training.population * config.training.steps,
                    condition_cost=max([trial_steps(s) for _, s in settings] or [0]),
                )
            )
    return tasks


def peer_run_json(spec: ExperimentSpec, arm: str, config: RunConfig) -> str:
    """The `app.tasks.peer.PeerRun` of one run of a task experiment, as JSON: the lab's
    settings as a task run (`TaskRunConfig.from_run_config`), the arm's brain and the test
    seeds; a fracnetics arm takes fracnetics' documented settings of the task, with the
    arm's own (`fracnetics`) over them."""
    from app.tasks.config import TaskRunConfig, TaskSettings, task_layout_1
    from app.tasks.fracnetics_arm import arm_settings
    from app.tasks.peer import PeerRun

    assert spec.task is not None
    brain = spec.arm(arm).brain
    run = TaskRunConfig.from_run_config(config, TaskSettings(id=spec.task.id), spec.task)
    peer = PeerRun(
        brain=brain,
        run=run,
        fracnetics=(
            arm_settings(spec.task.id, spec.arm(arm).fracnetics) if brain == "fracnetics" else None
        ),
        test_seeds=spec.task.seeds(),
    )
    data = peer.model_dump(mode="json", exclude=_later_defaults(run))
    data["run"] = task_layout_1(data["run"])  # the identity committed ledgers hold (layout 1)
    return pydantic_core.to_json(data).decode()


def _later_defaults(run: TaskRunConfig) -> dict[str, Any]:
    """The settings added to a task run after the first task experiments (issue #45: the
    brain's `gnp.config.TASK_SETTINGS` and `EVOLUTION_TASK_SETTINGS`, the episodes'
    `PROTOCOL_FIELDS`) that `run` leaves at their defaults: left out of its JSON, so a run's
    identity (`ledger.fingerprint`) and every committed ledger stay as they were."""
    from app.tasks.config import PROTOCOL_FIELDS
    from gnp.config import EVOLUTION_TASK_SETTINGS, TASK_SETTINGS, EvolutionConfig

    def unset(model: BaseModel, names: tuple[str, ...]) -> set[str]:
        fields = type(model).model_fields
        return {n for n in names if getattr(model, n) == fields[n].default}

    brain = getattr(run.brain, "controller", None)  # GNP's (a net has no TASK_SETTINGS)
    evolution = getattr(run.brain, "evolution", None)
    later: dict[str, Any] = {"training": unset(run.training, PROTOCOL_FIELDS)}
    if isinstance(brain, BaseModel):
        later["brain"] = {"controller": unset(brain, TASK_SETTINGS)}
        if isinstance(evolution, EvolutionConfig):
            later["brain"]["evolution"] = unset(evolution, EVOLUTION_TASK_SETTINGS)
    return {"run": later}


def _task_run(spec: ExperimentSpec, arm: str, seed: int, config: RunConfig, folder: Path) -> Task:
    return Task(
        arm=arm,
        seed=seed,
        path=str(folder / f"{arm}-seed{seed}.h5"),
        config_json=config.model_dump_json(),
        conditions=(),
        generation_cost=config.training.population * config.training.steps,
        condition_cost=0,
        task_json=peer_run_json(spec, arm, config),
    )


def training_steps(config: RunConfig) -> int:
    """Robot-steps of a run's training: generations × population × life time."""
    t = config.training
    return t.generations * t.population * t.steps


def trial_steps(settings: ImplementationSettings) -> int:
    """Trial-steps of one implementation condition: start poses × trials each × steps."""
    return len(settings.arena.start_poses) * settings.repeats * settings.steps


@dataclass(frozen=True)
class Work:
    """What an experiment costs at one scale, in simulated steps."""

    runs: int
    robot_steps: int  # training: generations × population × life time, summed over the runs
    trial_steps: int  # implementation: conditions × trials × steps, summed over the runs


def work(spec: ExperimentSpec, scale: str) -> Work:
    """The simulated work of `spec` at `scale` (its default seeds; a seed changes no size)."""
    seeds = len(spec.seed_list(scale))  # type: ignore[arg-type]
    robot = trials = 0
    for arm in spec.arms:
        config = spec.run_config(arm.name, scale, 0)
        robot += seeds * training_steps(config)
        for condition in spec.conditions:
            trials += seeds * trial_steps(spec.condition_settings(condition, config, scale))
    return Work(runs=seeds * len(spec.arms), robot_steps=robot, trial_steps=trials)


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
    if task.task_json:
        return _inspect_task_run(task, state)
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


def _inspect_task_run(task: Task, state: RunState) -> RunState:
    """A task experiment's run file (either brain): its config must be the task's."""
    from app.tasks.peer import PeerRun, read_peer

    path = Path(task.path)
    try:
        result = read_peer(path)
    except RunFileError as error:
        raise ExperimentError(f"{path}: {error}") from None
    peer = PeerRun.model_validate_json(task.task_json)
    stored = PeerRun.model_validate_json(result.peer_json) if result.peer_json else None
    if result.run != peer.run or (stored is not None and stored != peer):
        raise ExperimentError(
            f"{path} holds a run with another config than the experiment's "
            f"{task.name} (left untouched; move it away or use another --runs-dir)"
        )
    state.generations_done = result.generations_done
    state.finished = result.finished
    return state


class StateCache:
    """`inspect`, remembered while a run file is unchanged (its `files.stamp`): the dashboard
    reads a folder again (Refresh, another experiment chosen and back) at the cost of the files
    that changed, not of every file's validation (about 5 ms each). A file not yet `settled` is
    read each time. The dashboard's views only; what runs next is decided on a fresh
    `inspect`."""

    def __init__(self) -> None:
        self._known: dict[Task, tuple[Stamp, RunState | str]] = {}
        self._lock = threading.Lock()

    def inspect(self, task: Task) -> RunState:
        """As `inspect(task)`.

        Raises:
            ExperimentError: as `inspect`, also when remembered.
        """
        mark = stamp(Path(task.path))
        if mark is None:
            return inspect(task)
        with self._lock:
            known = self._known.get(task)
        if known is not None and known[0] == mark:
            outcome = known[1]
        else:
            try:
                outcome = inspect(task)
            except ExperimentError as error:
                outcome = str(error)
            if settled(mark):
                with self._lock:
                    self._known[task] = (mark, outcome)
        if isinstance(outcome, str):
            raise ExperimentError(outcome)
        return dataclasses.replace(outcome)


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
    spec: ExperimentSpec,
    scale: str,
    runs_dir: str | Path,
    seeds: int | None = None,
    read: Callable[[Task], RunState] = inspect,
) -> ScaleStatus:
    """Every run's state at `scale`; a foreign or half-replaced file is a problem, not an error.

    `read`: how a run's state is read (`StateCache.inspect`: remembered while unchanged)."""
    tasks = plan(spec, scale, runs_dir, seeds)
    states, problems = [], {}
    for task in tasks:
        try:
            states.append(read(task))
        except ExperimentError as error:  # a foreign file, or one being replaced right now
            states.append(RunState(generations=task.config.training.generations))
            problems[task.key] = str(error)
    return ScaleStatus(tuple(tasks), tuple(states), problems)
