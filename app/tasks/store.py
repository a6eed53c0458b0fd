"""Task run files: one HDF5 file per run of any brain family, with the lab's run-file conventions.

Root attributes `format` ("gnp-lab-task-run"), `schema_version`, `package_version`, `seed`,
`config` (the `TaskRunConfig` as JSON), `task` (the Gymnasium id) and `generations_done`;
`history/fitness` (G, N) returns, `history/epsilon`, `history/alpha` (G,), `history/env_steps`
(G,) int64 the env-steps each generation's episodes took (the sum of their lengths; a file
written before #45 has none, and a run resumed from one writes none), `history/best/<field>`
(G, ...) each generation's best after its life, and `checkpoint/<field>` (N, ...) the
population the next generation (`checkpoint.attrs["generation"]`) starts from, both in the
arrays of the family's `genome_layout` (GNP: genome and Q tables; a net: its weights). The
family is the config's `brain.family` (a file written before #46 item 2 is GNP's); ε and α are
NaN for a family that does not learn online. Plain h5py, no pickled objects; rows past
`generations_done` are not yet valid. Written generation by generation (flushed), so a crash
loses at most the generation in flight, and `resume` goes on from the checkpoint.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from pydantic import ValidationError

import gnp
from app.settings.loading import describe_problems
from app.settings.user_files import check_regular, loads_json
from app.store.files import LIBVER, RunFileError
from app.store.schema import package_version
from app.store.validation import check_progress, plain_dataset, plain_group
from app.tasks.common import FORMAT
from app.tasks.config import TaskRunConfig

SCHEMA_VERSION = 1


class TaskRunWriter:
    """The writer of a task run file (open for the whole training)."""

    def __init__(self, path: Path, handle: h5py.File, config: TaskRunConfig) -> None:
        self.path = path
        self.config = config
        self._file = handle

    @classmethod
    def create(cls, path: str | Path, config: TaskRunConfig) -> TaskRunWriter:
        """A new file; refuses to overwrite one.

        Raises:
            RunFileError: `path` exists or cannot be created.
        """
        path = Path(path)
        if path.exists():
            raise RunFileError(f"{path} already exists; choose another --out or --resume it")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            handle = h5py.File(path, "w-", libver=LIBVER, locking=False)
        except OSError as error:
            raise RunFileError(f"cannot create {path}: {error}") from None
        n = config.training.population
        handle.attrs["format"] = FORMAT
        handle.attrs["schema_version"] = SCHEMA_VERSION
        handle.attrs["package_version"] = package_version()
        handle.attrs["seed"] = config.seed
        handle.attrs["task"] = config.task.id
        handle.attrs["config"] = config.model_dump_json()
        handle.attrs["generations_done"] = 0
        history = handle.create_group("history")
        history.create_dataset("fitness", (0, n), np.float64, maxshape=(None, n))
        history["fitness"].attrs["unit"] = "episode return"
        for name in ("epsilon", "alpha"):
            history.create_dataset(name, (0,), np.float64, maxshape=(None,))
        steps = history.create_dataset("env_steps", (0,), np.int64, maxshape=(None,))
        steps.attrs["unit"] = "env steps"
        best = history.create_group("best")
        for name, (shape, dtype) in config.family.genome_layout.items():
            best.create_dataset(name, (0, *shape), dtype, maxshape=(None, *shape))
        return cls(path, handle, config)

    @classmethod
    def resume(cls, path: str | Path) -> tuple[TaskRunWriter, int, dict[str, np.ndarray]]:
        """The writer of an unfinished run, its next generation and that generation's arrays.

        Raises:
            RunFileError: not a task run, or already finished.
        """
        run = read_task_run(path)
        if run.generation_done >= run.config.training.generations:
            raise RunFileError(f"{Path(path).name} is finished; nothing to resume")
        handle = h5py.File(path, "r+", locking=False)
        generation = int(handle["checkpoint"].attrs["generation"])
        arrays = {name: ds[()] for name, ds in handle["checkpoint"].items()}
        return cls(Path(path), handle, run.config), generation, arrays

    def write_generation(
        self,
        generation: int,
        fitness: np.ndarray,
        epsilon: float,
        alpha: float,
        best: dict[str, np.ndarray],
        env_steps: int | None = None,
    ) -> None:
        """Generation `generation`'s row; `env_steps` (the steps its episodes took) goes to
        `history/env_steps` where the file has it (not in a file begun before #45)."""
        history = self._file["history"]
        rows = generation + 1
        columns: list[tuple[str, object]] = [
            ("fitness", fitness), ("epsilon", epsilon), ("alpha", alpha)
        ]  # fmt: skip
        if env_steps is not None and "env_steps" in history:
            columns.append(("env_steps", env_steps))
        for name, value in columns:
            ds = history[name]
            ds.resize(rows, axis=0)
            ds[generation] = value
        for name, value in best.items():
            ds = history["best"][name]
            ds.resize(rows, axis=0)
            ds[generation] = value[0]

    def write_checkpoint(self, next_generation: int, arrays: dict[str, np.ndarray]) -> None:
        """The population generation `next_generation` starts from (replaces the last)."""
        if "checkpoint" in self._file:
            del self._file["checkpoint"]
        group = self._file.create_group("checkpoint")
        group.attrs["generation"] = next_generation
        for name, value in arrays.items():
            group.create_dataset(name, data=value)

    def mark_done(self, generations_done: int) -> None:
        self._file.attrs["generations_done"] = generations_done
        self._file.flush()

    def close(self) -> None:
        self._file.close()


@dataclass(frozen=True)
class TaskRun:
    """A task run file, read."""

    path: Path
    config: TaskRunConfig
    generation_done: int
    fitness: np.ndarray  # (generations_done, N)
    epsilon: np.ndarray
    alpha: np.ndarray
    package_version: str
    #: (generations_done,) env-steps per generation; None for a file written before #45
    env_steps: np.ndarray | None = None

    def best_arrays(self, generation: int | None = None) -> dict[str, np.ndarray]:
        """A generation's best (default: the last) as the file stores it: its family's arrays,
        with a leading axis of 1."""
        done = self.generation_done
        g = done - 1 if generation is None else generation
        if not 0 <= g < done:
            raise RunFileError(f"{self.path.name} has generations 0..{done - 1}, not {g}")
        with h5py.File(self.path, "r", locking=False) as handle:
            best = handle["history/best"]
            return {name: best[name][g : g + 1] for name in best}

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


def read_task_run(path: str | Path) -> TaskRun:
    """Read a task run file's settings and history, checked: a regular file, its config valid
    JSON of bounded size and depth, `generations_done` within the config's generations and the
    rows held, every history dataset of the shape and type the config gives.

    Raises:
        RunFileError: missing, not a task run, of an unknown schema version, or holding
            contents of the wrong kind (named).
    """
    path = Path(path)
    check_regular(path, RunFileError, "run file")
    try:
        handle = h5py.File(path, "r", locking=False)
    except OSError as error:
        raise RunFileError(f"cannot read {path}: {error}") from None
    with handle:
        if handle.attrs.get("format") != FORMAT:
            raise RunFileError(f"{path} is not a task run file")
        try:
            return _task_run(path, handle)
        except ValidationError as error:
            problems = describe_problems(error, limit=3)
            raise RunFileError(f"{path} holds an invalid config: {problems}") from None
        except (KeyError, ValueError, TypeError, OverflowError, OSError) as error:
            raise RunFileError(f"corrupt task run file {path}: {error}") from None


def _task_run(path: Path, handle: h5py.File) -> TaskRun:
    version = int(handle.attrs["schema_version"])
    if version != SCHEMA_VERSION:
        raise RunFileError(f"{path} is task run schema {version}; this reads {SCHEMA_VERSION}")
    text = handle.attrs["config"]
    config = TaskRunConfig.model_validate(loads_json(text, RunFileError, f"{path}: config"))
    generations, population = config.training.generations, config.training.population
    done = check_progress(
        "generations_done", handle.attrs["generations_done"], 0, generations, path
    )
    fitness = plain_dataset(handle, "history/fitness")
    rows = fitness.shape[0] if fitness.ndim == 2 else -1
    if fitness.shape != (rows, population) or rows < done or fitness.dtype.kind != "f":
        raise RunFileError(f"{path}: history/fitness is {fitness.shape} {fitness.dtype}")
    columns = {name: plain_dataset(handle, f"history/{name}") for name in ("epsilon", "alpha")}
    for name, dataset in columns.items():
        if dataset.shape != (rows,) or dataset.dtype.kind != "f":
            raise RunFileError(f"{path}: history/{name} is {dataset.shape} {dataset.dtype}")
    steps = None
    if "env_steps" in handle["history"]:
        steps = plain_dataset(handle, "history/env_steps")
        if steps.ndim != 1 or steps.shape[0] < done or steps.dtype.kind not in "iu":
            raise RunFileError(f"{path}: history/env_steps is {steps.shape} {steps.dtype}")
    best = plain_group(handle, "history/best")
    for name in best:
        genes = plain_dataset(best, name)
        if genes.ndim < 1 or genes.shape[0] < done or genes.dtype.kind not in "biuf":
            raise RunFileError(f"{path}: history/best/{name} is {genes.shape} {genes.dtype}")
    return TaskRun(
        path=path,
        config=config,
        generation_done=done,
        fitness=fitness[:done],
        epsilon=columns["epsilon"][:done],
        alpha=columns["alpha"][:done],
        package_version=str(handle.attrs["package_version"]),
        env_steps=None if steps is None else np.asarray(steps[:done], np.int64),
    )
