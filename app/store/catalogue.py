"""The runs folder: naming new runs, finding a run by name, listing what is there."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

import gnp
from app.config import RunConfig
from app.store.files import RunFileError
from app.store.reader import RunReader

SUFFIX = ".h5"


def run_name(config: RunConfig, now: datetime) -> str:
    """The default name of a run started at `now`: method, judgment, seed and UTC time.

    E.g. "CS-fuzzy-seed7-20260102T030405Z". A naive `now` is taken as local time.
    """
    controller = config.controller
    kind = (
        f"{controller.method}-{gnp.judgment_name(controller.fuzzy)}"
        if config.neuro is None
        else config.brain
    )
    stamp = now.astimezone(UTC).strftime("%Y%m%dT%H%M%SZ")
    return f"{kind}-seed{config.seed}-{stamp}"


def new_run_path(runs_dir: str | Path, config: RunConfig, now: datetime) -> Path:
    """A free path for a new run in `runs_dir`: `run_name`, with "-2", "-3", ... if taken."""
    name = run_name(config, now)
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
    method: str = ""
    fuzzy: bool = True
    generations_done: int = 0
    generations: int = 0
    finished: bool = False
    best_fitness: float = float("nan")
    implementations: tuple[str, ...] = ()
    error: str | None = None
    brain: str = "gnp"  # or the neural optimiser (then `method` and `fuzzy` do not apply)


def list_runs(runs_dir: str | Path) -> list[RunSummary]:
    """Every `*.h5` file in `runs_dir`, sorted by name; unreadable ones carry an `error`."""
    runs_dir = Path(runs_dir)
    if not runs_dir.is_dir():
        return []
    return [_summary(path) for path in sorted(runs_dir.glob("*" + SUFFIX))]


def _summary(path: Path) -> RunSummary:
    name = path.name[: -len(SUFFIX)]
    try:
        with RunReader(path) as run:
            history = run.history()
            best = float(history.best_fitness.max()) if len(history.best_fitness) else np.nan
            return RunSummary(
                name=name,
                path=path,
                method=run.config.controller.method,
                fuzzy=run.config.controller.fuzzy,
                generations_done=len(history.best_fitness),
                generations=run.config.training.generations,
                finished=run.finished,
                best_fitness=best,
                implementations=tuple(run.implementation_names()),
                brain=run.config.brain,
            )
    except RunFileError as error:
        return RunSummary(name=name, path=path, error=str(error))
