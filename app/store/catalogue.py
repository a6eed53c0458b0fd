"""The runs folder: naming new runs, finding a run by name, listing what is there."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import h5py
import numpy as np

from app.settings.config import RunConfig
from app.settings.families import DEFAULT_BRAIN
from app.settings.user_files import check_regular, loads_json
from app.store.files import TASK_RUN_FORMAT, RunFileError
from app.store.reader import RunReader
from app.store.validation import check_progress, plain_dataset

SUFFIX = ".h5"

BEST_OF_RUN = "best of all generations"
"""What a run's best fitness is called wherever it is shown (`gnp-lab`, the dashboard): the best
individual's fitness over every generation done (`RunSummary.best_fitness`), as against
`LAST_BEST`."""

LAST_BEST = "last generation's best"
"""What the best fitness of a run's last generation done is called beside `BEST_OF_RUN`."""


def best_words(best_per_generation: np.ndarray) -> str:
    """A run's best fitness and its last generation's, both named: "best of all generations
    0.4065 (generation 812); last generation's best 0.3612" (generations counted from 0)."""
    if not len(best_per_generation):
        return f"{BEST_OF_RUN}: none yet (no generation done)"
    at = int(np.argmax(best_per_generation))
    return (
        f"{BEST_OF_RUN} {best_per_generation[at]:.4f} (generation {at}); "
        f"{LAST_BEST} {best_per_generation[-1]:.4f}"
    )


def run_name(stem: str, seed: int, now: datetime) -> str:
    """The default name of a run started at `now`: its brain's stem (`family.file_stem`), seed
    and UTC time.

    E.g. "CS-fuzzy-seed7-20260102T030405Z". A naive `now` is taken as local time.
    """
    stamp = now.astimezone(UTC).strftime("%Y%m%dT%H%M%SZ")
    return f"{stem}-seed{seed}-{stamp}"


def new_run_path(runs_dir: str | Path, stem: str, seed: int, now: datetime) -> Path:
    """A free path for a new run in `runs_dir`: `run_name`, with "-2", "-3", ... if taken."""
    name = run_name(stem, seed, now)
    path = Path(runs_dir) / (name + SUFFIX)
    copy = 1
    while path.exists():
        copy += 1
        path = path.with_name(f"{name}-{copy}{SUFFIX}")
    return path


def resolve_run(runs_dir: str | Path, name: str) -> Path:
    """Path of the run `name` ("demo" or "demo.h5") inside `runs_dir`.

    Raises:
        RunFileError: the name holds a path (no escaping `runs_dir`) or the run does not exist.
    """
    if not name or "/" in name or "\\" in name or name.startswith(".") or "\x00" in name:
        raise RunFileError(f"run name {name!r} must be a plain file name inside {runs_dir}")
    file_name = name if name.endswith(SUFFIX) else name + SUFFIX
    path = Path(runs_dir) / file_name
    if not path.is_file():
        raise RunFileError(f"no run named {name!r} in {runs_dir}")
    return path


@dataclass(frozen=True)
class RunSummary:
    """One line of `list_runs`: a run file and what it holds, or why it cannot be read."""

    name: str
    path: Path
    config: RunConfig | None = None  # a robot run's (None: a task run, or unreadable)
    generations_done: int = 0
    generations: int = 0
    finished: bool = False
    best_fitness: float = float("nan")
    implementations: tuple[str, ...] = ()
    error: str | None = None
    task: str = ""  # a task run's Gymnasium id (app.tasks); "" for the robot's runs
    task_family: str = ""  # a task run's brain family (its config's `brain.family`)

    @property
    def brain(self) -> str:
        """The name of the run's brain family (`RunConfig.brain.family`, a task run's config's);
        "" for an unreadable run."""
        return self.config.brain.family if self.config is not None else self.task_family


def list_runs(runs_dir: str | Path) -> list[RunSummary]:
    """Every `*.h5` file in `runs_dir`, sorted by name; unreadable ones carry an `error`."""
    runs_dir = Path(runs_dir)
    if not runs_dir.is_dir():
        return []
    return [_summary(path) for path in sorted(runs_dir.glob("*" + SUFFIX))]


def _summary(path: Path) -> RunSummary:
    name = path.name[: -len(SUFFIX)]
    try:
        check_regular(path, RunFileError, "run file")  # a FIFO named *.h5 would hang h5py
    except RunFileError as error:
        return RunSummary(name=name, path=path, error=str(error))
    task = _task_summary(path, name)
    if task is not None:
        return task
    try:
        with RunReader(path) as run:
            history = run.history()
            best = float(history.best_fitness.max()) if len(history.best_fitness) else np.nan
            return RunSummary(
                name=name,
                path=path,
                config=run.config,
                generations_done=len(history.best_fitness),
                generations=run.config.training.generations,
                finished=run.finished,
                best_fitness=best,
                implementations=tuple(run.implementation_names()),
            )
    except RunFileError as error:
        return RunSummary(name=name, path=path, error=str(error))


def _task_summary(path: Path, name: str) -> RunSummary | None:
    """The line of a task run file (`app.tasks.store`'s format, read here with h5py alone so
    that listing runs needs no Gymnasium), or None for any other file."""
    try:
        handle = h5py.File(path, "r", locking=False)
    except (OSError, ValueError):
        return None
    with handle:
        if handle.attrs.get("format") != TASK_RUN_FORMAT:
            return None
        task = str(handle.attrs.get("task", "?"))
        try:
            config = loads_json(handle.attrs["config"], RunFileError, "its config")
            generations = int(config["training"]["generations"])
            done = check_progress(
                "generations_done", handle.attrs["generations_done"], 0, generations, path
            )
            fitness = plain_dataset(handle, "history/fitness")
            if fitness.ndim != 2 or fitness.shape[0] < done or fitness.dtype.kind != "f":
                raise RunFileError(f"history/fitness is {fitness.shape} {fitness.dtype}")
            rows = fitness[:done]
            best = float(rows.max()) if rows.size else float("nan")
            brain = config.get("brain")  # none in layout 1 (GNP's, before #46)
            family = (
                brain.get("family", DEFAULT_BRAIN) if isinstance(brain, dict) else DEFAULT_BRAIN
            )
        except (RunFileError, KeyError, ValueError, TypeError, OverflowError, OSError) as error:
            return RunSummary(name=name, path=path, task=task, error=f"task run: {error}")
        return RunSummary(
            name=name,
            path=path,
            generations_done=done,
            generations=generations,
            finished=done >= generations,
            best_fitness=best,
            task=task,
            task_family=str(family),
        )
