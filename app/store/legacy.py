"""Task run files of the old format ("gnp-lab-task-run"), read; resumed into the run format.

Before task runs shared the run format (`schema.LAYOUT`, kind "task"), a task run was a file of
its own layout: root attributes `format` ("gnp-lab-task-run"), `schema_version` 1,
`package_version`, `seed`, `task` (the Gymnasium id), `config` (the task run's config as JSON,
in either layout: a file before issue #46 is GNP's, in layout 1) and `generations_done`;
`history/fitness` (rows, N) returns, `history/epsilon`, `history/alpha` (rows,),
`history/env_steps` (rows,) int64 (none in a file written before #45), `history/best/<array>`
(rows, ...) each generation's best, and `checkpoint/<array>` (N, ...) the population generation
`checkpoint.attrs["generation"]` starts from; rows past `generations_done` are not valid.

Such files are still read (listed, replayed, exported) through `read_legacy_task_run`, and a
resume rewrites one into the run format (`fill_run_file`, under `RunWriter.resume`'s lock and
atomic rename) and goes on in that.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
from pydantic import ValidationError

from app.settings.config import RunConfig
from app.settings.loading import describe_problems
from app.settings.user_files import check_regular
from app.store.files import RunFileError
from app.store.schema import TaskRunHeader, task_run_header
from app.store.validation import check_progress, plain_dataset, plain_group

LEGACY_TASK_FORMAT = "gnp-lab-task-run"
"""The `format` attribute of an old task run file."""
LEGACY_SCHEMA_VERSION = 1


@dataclass(frozen=True)
class LegacyTaskRun:
    """An old-format task run file, read and checked (its rows up to `generations_done`)."""

    path: Path
    task_config: str  # the task run's config, JSON as stored
    task: str  # its Gymnasium id
    config: RunConfig  # the config its family is bound with (`schema.task_run_header`)
    generations_done: int
    fitness: np.ndarray  # (generations_done, N)
    epsilon: np.ndarray  # (generations_done,)
    alpha: np.ndarray  # (generations_done,)
    env_steps: np.ndarray | None  # (generations_done,); None in a file written before #45
    package_version: str

    def best_arrays(self, generation: int) -> dict[str, np.ndarray]:
        """A completed generation's best, its arrays with a leading axis of 1."""
        if not 0 <= generation < self.generations_done:
            raise RunFileError(f"{self.path.name}: generation {generation} is not complete")
        with _open(self.path) as handle:
            best = plain_group(handle, "history/best")
            return {name: np.asarray(best[name][generation : generation + 1]) for name in best}

    def checkpoint(self) -> tuple[int, dict[str, np.ndarray]]:
        """(the generation it starts, the population's arrays) of the file's checkpoint.

        Raises:
            RunFileError: none, or not within the generations held.
        """
        with _open(self.path) as handle:
            if "checkpoint" not in handle:
                raise RunFileError(f"{self.path} has no checkpoint yet; start the run again")
            group = plain_group(handle, "checkpoint")
            rows = plain_dataset(handle, "history/fitness").shape[0]
            generations = self.config.training.generations
            generation = check_progress(
                "checkpoint generation", group.attrs["generation"], 0, min(rows, generations),
                self.path,
            )  # fmt: skip
            return generation, {name: np.asarray(plain_dataset(group, name)) for name in group}


def is_legacy_task_run(path: str | Path) -> bool:
    """Whether `path` is an old-format task run file (False for anything else)."""
    try:
        check_regular(path, RunFileError, "run file")
        with h5py.File(path, "r", locking=False) as handle:
            return bool(handle.attrs.get("format") == LEGACY_TASK_FORMAT)
    except (RunFileError, OSError, ValueError):
        return False


def _open(path: Path) -> h5py.File:
    check_regular(path, RunFileError, "run file")
    try:
        return h5py.File(path, "r", locking=False)
    except OSError as error:
        raise RunFileError(f"cannot read {path}: {error}") from None


def read_legacy_task_run(path: str | Path, rows: int | None = None) -> LegacyTaskRun:
    """An old-format task run file, checked: its config valid JSON of bounded size and depth,
    `generations_done` within the config's generations and the rows held, every history dataset
    of the shape and type the config gives. `rows`: read that many rows instead of
    `generations_done` (a resume reads up to its checkpoint).

    Raises:
        RunFileError: missing, not an old task run, of an unknown schema version, or holding
            contents of the wrong kind (named).
    """
    path = Path(path)
    with _open(path) as handle:
        if handle.attrs.get("format") != LEGACY_TASK_FORMAT:
            raise RunFileError(f"{path} is not a task run file")
        try:
            version = int(handle.attrs["schema_version"])
            if version != LEGACY_SCHEMA_VERSION:
                raise RunFileError(
                    f"{path} is task run schema {version}; this reads {LEGACY_SCHEMA_VERSION}"
                )
            text = str(handle.attrs["config"])
            header = task_run_header(text)
            return _read(path, handle, text, header, rows)
        except ValidationError as error:
            problems = describe_problems(error, limit=3)
            raise RunFileError(f"{path} holds an invalid config: {problems}") from None
        except (KeyError, ValueError, TypeError, OverflowError, OSError) as error:
            first = str(error).splitlines()[0] if str(error) else type(error).__name__
            raise RunFileError(f"corrupt task run file {path}: {first}") from None


def _read(
    path: Path, handle: h5py.File, text: str, header: TaskRunHeader, rows: int | None
) -> LegacyTaskRun:
    config = header.config
    generations, population = config.training.generations, config.training.population
    done = check_progress(
        "generations_done", handle.attrs["generations_done"], 0, generations, path
    )
    done = done if rows is None else rows
    fitness = plain_dataset(handle, "history/fitness")
    held = fitness.shape[0] if fitness.ndim == 2 else -1
    if fitness.shape != (held, population) or held < done or fitness.dtype.kind != "f":
        raise RunFileError(f"{path}: history/fitness is {fitness.shape} {fitness.dtype}")
    columns = {name: plain_dataset(handle, f"history/{name}") for name in ("epsilon", "alpha")}
    for name, dataset in columns.items():
        if dataset.shape != (held,) or dataset.dtype.kind != "f":
            raise RunFileError(f"{path}: history/{name} is {dataset.shape} {dataset.dtype}")
    steps = None
    if "env_steps" in plain_group(handle, "history"):
        steps = plain_dataset(handle, "history/env_steps")
        if steps.ndim != 1 or steps.shape[0] < done or steps.dtype.kind not in "iu":
            raise RunFileError(f"{path}: history/env_steps is {steps.shape} {steps.dtype}")
    best = plain_group(handle, "history/best")
    for name in best:
        genes = plain_dataset(best, name)
        if genes.ndim < 1 or genes.shape[0] < done or genes.dtype.kind not in "biuf":
            raise RunFileError(f"{path}: history/best/{name} is {genes.shape} {genes.dtype}")
    return LegacyTaskRun(
        path=path,
        task_config=text,
        task=header.task,
        config=config,
        generations_done=done,
        fitness=np.asarray(fitness[:done]),
        epsilon=np.asarray(columns["epsilon"][:done]),
        alpha=np.asarray(columns["alpha"][:done]),
        env_steps=None if steps is None else np.asarray(steps[:done], np.int64),
        package_version=str(handle.attrs["package_version"]),
    )


def fill_run_file(
    handle: h5py.File, run: LegacyTaskRun, generation: int, population: dict[str, np.ndarray]
) -> None:
    """Write an old file's generations (`run`, read up to its checkpoint `generation`) and its
    checkpoint (`population`) into a new task run file laid out for it: the rows the writer
    derives from a generation's fitness derived the same way, env-steps −1 where the old file
    has none, the checkpoint in slot 0."""
    for g, fitness in enumerate(run.fitness[:generation]):
        best = int(np.argmax(fitness))
        handle["generations/fitness"][g] = fitness
        handle["generations/best_fitness"][g] = fitness[best]
        handle["generations/mean_fitness"][g] = fitness.mean()
        handle["generations/std_fitness"][g] = fitness.std()
        handle["generations/best_index"][g] = best
        handle["generations/epsilon"][g] = run.epsilon[g]
        handle["generations/alpha"][g] = run.alpha[g]
        if run.env_steps is not None:
            handle["generations/env_steps"][g] = run.env_steps[g]
    with _open(run.path) as source:
        best = plain_group(source, "history/best")
        for name in best:
            if f"genomes/best/{name}" not in handle:
                raise RunFileError(f"{run.path.name}: history/best/{name} is not in its genome")
            handle[f"genomes/best/{name}"][:generation] = best[name][:generation]
    for name, values in population.items():
        handle[f"checkpoint/slot0/{name}"][...] = values
    handle["progress/checkpoint"][...] = [0, generation]
    handle["progress/generations_done"][()] = generation
