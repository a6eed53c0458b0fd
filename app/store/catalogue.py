"""The runs folder: naming new runs, finding a run by name, listing what is there."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from app.settings.config import RunConfig
from app.settings.user_files import check_regular
from app.store.files import RunFileError
from app.store.legacy import is_legacy_task_run, read_legacy_task_run
from app.store.reader import RunReader, file_kind
from app.store.schema import RUN_KINDS, RunKind

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
    return [summarize(path) for path in run_files(runs_dir)]


def run_files(runs_dir: str | Path) -> list[Path]:
    """The `*.h5` files of `runs_dir` (not of its subfolders), sorted by name."""
    runs_dir = Path(runs_dir)
    if not runs_dir.is_dir():
        return []
    return sorted(runs_dir.glob("*" + SUFFIX))


def summarize(path: Path) -> RunSummary:
    """The `list_runs` line of run file `path` (an unreadable one carries an `error`)."""
    name = path.name[: -len(SUFFIX)]
    kind: RunKind | None = None
    try:
        check_regular(path, RunFileError, "run file")  # a FIFO named *.h5 would hang h5py
        if is_legacy_task_run(path):
            return _legacy_summary(path, name)
        kind = file_kind(path)
        with RunReader(path, RUN_KINDS) as run:
            history = run.history()
            best = float(history.best_fitness.max()) if len(history.best_fitness) else np.nan
            return RunSummary(
                name=name,
                path=path,
                config=run.config if run.kind == "robot" else None,
                generations_done=len(history.best_fitness),
                generations=run.config.training.generations,
                finished=run.finished,
                best_fitness=best,
                implementations=tuple(run.implementation_names()),
                task=run.task,
                task_family=run.config.brain.family if run.kind == "task" else "",
            )
    except RunFileError as error:
        said = f"task run: {error}" if kind == "task" else str(error)
        return RunSummary(name=name, path=path, error=said)


def _legacy_summary(path: Path, name: str) -> RunSummary:
    """The line of an old-format task run file (`app.store.legacy`)."""
    try:
        run = read_legacy_task_run(path)
    except RunFileError as error:
        return RunSummary(name=name, path=path, error=f"task run: {error}")
    rows, generations = run.fitness, run.config.training.generations
    return RunSummary(
        name=name,
        path=path,
        generations_done=run.generations_done,
        generations=generations,
        finished=run.generations_done >= generations,
        best_fitness=float(rows.max()) if rows.size else float("nan"),
        task=run.task,
        task_family=run.config.brain.family,
    )
