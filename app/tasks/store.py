"""Task runs, read: a task run file as one typed view, `TaskRun`, whichever format it is in.

A task run is a run file of the lab's format ("gnp-lab-run", docs/run-format.md) of kind "task",
written by `app.store.RunWriter` (SWMR, the writer lock, disk-space checks, double-buffered
checkpoints, atomic resume) and read by `app.store.RunReader`; its stored config is the
`TaskRunConfig`, which this module reads. A file of the old task run format
("gnp-lab-task-run", `app.store.legacy`) reads the same; a resume rewrites it into the run
format. The family is the config's `brain.family` (a file written before #46 item 2 is GNP's);
ε and α are NaN for a family that does not learn online.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

import gnp
from app.settings.loading import describe_problems
from app.settings.user_files import loads_json
from app.store import TASK, RunFileError, RunReader
from app.store.legacy import is_legacy_task_run, read_legacy_task_run
from app.tasks.config import TaskRunConfig


@dataclass(frozen=True)
class TaskRun:
    """A task run file, read (its completed generations)."""

    path: Path
    config: TaskRunConfig
    generation_done: int
    fitness: np.ndarray  # (generations_done, N) episode returns
    epsilon: np.ndarray
    alpha: np.ndarray
    package_version: str
    #: (generations_done,) env-steps per generation; None where a generation's are not known
    #: (a file written before #45, and a run resumed from one)
    env_steps: np.ndarray | None = None
    legacy: bool = False  # a file of the old task run format (`app.store.legacy`)

    def best_arrays(self, generation: int | None = None) -> dict[str, np.ndarray]:
        """A generation's best (default: the last) as the file stores it: its family's arrays,
        with a leading axis of 1."""
        done = self.generation_done
        g = done - 1 if generation is None else generation
        if not 0 <= g < done:
            raise RunFileError(f"{self.path.name} has generations 0..{done - 1}, not {g}")
        if self.legacy:
            return read_legacy_task_run(self.path).best_arrays(g)
        with RunReader(self.path, TASK) as run:
            return run.best_genome_arrays(g)

    def best_individual(self, generation: int | None = None) -> Any:
        """A generation's best (default: the last) as its family's individuals (one).

        Raises:
            RunFileError: no such generation, or arrays the family does not read (one line).
            TaskError: the run's family is not registered here, or cannot run on its task.
        """
        family, arrays = self.config.family, self.best_arrays(generation)
        try:
            return family.from_arrays(arrays)
        except ValueError as error:  # a family's own check (GNP's `gnp.GnpError`)
            raise RunFileError(f"{self.path.name}: an invalid best individual: {error}") from None

    def best_genome(self, generation: int | None = None) -> tuple[gnp.GnpConfig, gnp.Population]:
        """(brain config, 1-individual population) of a GNP run's best (`best_individual`)."""
        return self.config.gnp_config(), self.best_individual(generation)


def task_run_config(path: Path, text: str) -> TaskRunConfig:
    """A task run's stored config (JSON, either layout), checked.

    Raises:
        RunFileError: not JSON (bounded in size and depth) or not a valid task run config.
    """
    data = loads_json(text, RunFileError, f"{path}: config")
    try:
        return TaskRunConfig.model_validate(data)
    except ValidationError as error:
        problems = describe_problems(error, limit=3)
        raise RunFileError(f"{path} holds an invalid config: {problems}") from None


def read_task_run(path: str | Path) -> TaskRun:
    """Read a task run file's settings and history (its completed generations), checked: a run
    file of kind "task" (`RunReader`'s checks) or an old task run file
    (`app.store.legacy.read_legacy_task_run`'s), its config a valid `TaskRunConfig`. Also while
    a writer is writing it.

    Raises:
        RunFileError: missing, not a task run, of an unknown schema version, or holding
            contents of the wrong kind (named).
    """
    path = Path(path)
    if is_legacy_task_run(path):
        old = read_legacy_task_run(path)
        return TaskRun(
            path=path,
            config=task_run_config(path, old.task_config),
            generation_done=old.generations_done,
            fitness=old.fitness,
            epsilon=old.epsilon,
            alpha=old.alpha,
            package_version=old.package_version,
            env_steps=old.env_steps,
            legacy=True,
        )
    with RunReader(path, TASK) as run:
        history = run.history()
        assert run.task_config is not None  # a run of kind "task" has it
        steps = history.env_steps
        return TaskRun(
            path=path,
            config=task_run_config(path, run.task_config),
            generation_done=len(history.fitness),
            fitness=history.fitness,
            epsilon=history.epsilon,
            alpha=history.alpha,
            package_version=run.package_version,
            env_steps=None if steps is None or (steps < 0).any() else steps,
        )
