"""Reading run files of any kind (a robot run, a task run), also while a SWMR writer is still
writing them."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import h5py
import numpy as np
from pydantic import ValidationError

from app.loop.recording import Trajectory
from app.settings.config import ImplementationSettings
from app.settings.loading import describe_problems, stored_config
from app.settings.user_files import loads_json
from app.store.files import RunFileError, open_for_read
from app.store.legacy import LEGACY_TASK_FORMAT
from app.store.schema import (
    FORMAT,
    KIND_ATTRIBUTE,
    ROBOT,
    RUN_KINDS,
    SCHEMA_VERSION,
    RunKind,
    layout_of,
    task_run_header,
)
from app.store.validation import check_implementation, check_progress, check_run_layout

_T = TypeVar("_T")

# A SWMR read can catch the writer mid-flush; HDF5 then reports a torn object ("invalid dataset
# size", a bad B-tree signature, an object it cannot find). It passes: read again after a pause,
# and reopen the file if it persists. The pauses add up to about 0.4 s.
_TORN_READ = (OSError, KeyError, ValueError, RuntimeError)
_PAUSES = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2)
_REOPEN_AFTER = 4  # failed reads, then reopen the file


@dataclass(frozen=True)
class History:
    """Per-generation arrays of the completed generations (length `generations_done`)."""

    best_fitness: np.ndarray  # (g,)
    mean_fitness: np.ndarray  # (g,)
    std_fitness: np.ndarray  # (g,)
    best_index: np.ndarray  # (g,) index of the best individual in its generation
    epsilon: np.ndarray  # (g,)
    alpha: np.ndarray  # (g,)
    fitness: np.ndarray  # (g, population)
    best_terms: dict[str, np.ndarray]  # term name -> (g,), mean per step of the best (robot)
    mean_terms: dict[str, np.ndarray]  # term name -> (g,), population mean (robot)
    #: (g,) a task run's env-steps per generation, −1 where not known (None: a robot run)
    env_steps: np.ndarray | None = None


@dataclass(frozen=True)
class Implementation:
    """One implementation phase of a run (stored under `implementation/<name>`)."""

    name: str
    settings: ImplementationSettings
    generation: int  # generation whose best individual was implemented
    reward_per_step: np.ndarray  # (T,) mean over trials
    trial_mean_reward: np.ndarray  # (N,) mean reward per step of each trial
    trial_mean_after_fault: np.ndarray  # (N,) mean from the fault step on
    start_index: np.ndarray  # (N,) start pose of each trial
    mean_reward: float
    mean_after_fault: float
    trials: Trajectory  # the recorded trials
    recorded: np.ndarray  # (k,) which trials were recorded


class RunReader:
    """Read a run file, also while it is being written (call `refresh()` to see new data).

    Reads that catch a live writer mid-flush are retried (and the file reopened if need be), so
    callers see consistent data or, if the file stays unreadable, a RunFileError.

    `kinds`: the kinds of run the caller reads (a robot run's by default); the file's own is
    `kind`. A task run's `config` is the robot run's config its family is bound with (seed,
    brain, sizes: `schema.task_run_header`), its whole config `task_config` (JSON, for
    `app.tasks` to read), its Gymnasium id `task` ("" for a robot run); it has no reward terms
    and no elite's life.

    Raises:
        RunFileError: missing, foreign (not a gnp-lab run), corrupt, or of a kind not in
            `kinds`.
    """

    def __init__(self, path: str | Path, kinds: tuple[RunKind, ...] = ROBOT) -> None:
        self.path = Path(path)
        self._kinds = kinds
        self._file = open_for_read(self.path)
        try:
            self._load_header()
        except RunFileError:
            self._file.close()
            raise
        except (KeyError, OSError, ValueError, TypeError, OverflowError) as error:
            self._file.close()
            raise RunFileError(f"corrupt run file {self.path}: {error}") from None

    def _load_header(self) -> None:
        attrs = self._file.attrs
        kind = _kind(self.path, attrs)
        if kind not in self._kinds:
            raise RunFileError(
                f"{self.path} is a task run (gnp-lab replay, export)"
                if kind == "task"
                else f"{self.path} is a robot run, not a task run"
            )
        version = int(attrs["schema_version"])
        if version != SCHEMA_VERSION:
            raise RunFileError(
                f"{self.path} has run-file schema {version}; this gnp-lab reads {SCHEMA_VERSION}"
            )
        self.kind: RunKind = kind
        self.task_config: str | None = None
        self.task = ""
        try:
            if kind == "task":
                self.task_config = str(attrs["config"])
                header = task_run_header(self.task_config)
                self.config, self.task = header.config, header.task
            else:
                self.config = stored_config(attrs["config"])
        except ValidationError as error:
            problems = describe_problems(error, limit=3)
            raise RunFileError(f"{self.path} holds an invalid config: {problems}") from None
        except ValueError as error:
            raise RunFileError(f"{self.path} holds an invalid config: {error}") from None
        self.seed = int(attrs["seed"])
        if self.seed != self.config.seed:
            raise RunFileError(f"{self.path}: seed {self.seed}, its config's {self.config.seed}")
        self.package_version = str(attrs["package_version"])
        terms = attrs["reward_terms"] if kind == "robot" else ()
        self.term_names = tuple(str(t) for t in np.atleast_1d(terms))
        self._rows = {row.path for row in layout_of(kind)}
        try:
            check_run_layout(self._file, self.config, self.term_names, kind)
        except RunFileError as error:
            raise RunFileError(f"{self.path}: {error}") from None
        # The inode of the open file (not of the path, which a rename may have moved on).
        self._inode = os.fstat(self._file.id.get_vfd_handle()).st_ino

    def _reopen(self) -> None:
        fresh = open_for_read(self.path)
        stale, self._file = self._file, fresh
        stale.close()
        self._load_header()

    def _steady(self, read: Callable[[], _T]) -> _T:
        """`read()`, retried while a live writer leaves the file torn (see _TORN_READ).

        Raises:
            RunFileError: the read fails in a file no writer holds, or never clears in one.
        """
        if not self._file.swmr_mode:  # opened plainly: no writer holds the file
            try:
                return read()
            except _TORN_READ as error:
                raise RunFileError(f"corrupt run file {self.path}: {error!r}") from error
        torn: Exception | None = None
        for attempt, pause in enumerate((0.0, *_PAUSES)):
            time.sleep(pause)
            try:
                if attempt == _REOPEN_AFTER:
                    self._reopen()
                return read()
            except _TORN_READ as error:
                torn = error
        raise RunFileError(f"cannot read {self.path.name} while it is being written: {torn}")

    # -- lifecycle --

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> RunReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def refresh(self) -> None:
        """See what the writer flushed since; reopen the file if it was replaced."""
        try:
            inode = os.stat(self.path).st_ino
        except FileNotFoundError:
            return
        if inode != self._inode:
            self._reopen()
        else:
            self._steady(self._generations_done)

    @property
    def file(self) -> h5py.File:
        """The open HDF5 file, for plain h5py reads and copies (replaced by `refresh()`)."""
        return self._file

    # -- contents --

    def _dataset(self, name: str) -> h5py.Dataset:
        dataset = self._file[name]
        if self._file.swmr_mode:
            dataset.refresh()  # drop what HDF5 cached of it before the writer's last flush
        return dataset

    def _read(self, name: str) -> np.ndarray:
        return np.asarray(self._dataset(name)[()])

    def _generations_done(self) -> int:
        done = self._read("progress/generations_done")
        generations = self.config.training.generations
        return check_progress("progress/generations_done", done, 0, generations, self.path)

    @property
    def generations_done(self) -> int:
        """Generations whose results are complete in the file."""
        return self._steady(self._generations_done)

    @property
    def finished(self) -> bool:
        """True once training completed and the final elite was recorded."""
        return self._steady(
            lambda: bool(
                check_progress(
                    "progress/finished", self._read("progress/finished"), 0, 1, self.path
                )
            )
        )

    def history(self) -> History:
        """Per-generation results of the completed generations."""
        return self._steady(self._history)

    def _history(self) -> History:
        done = self._generations_done()

        def rows(name: str) -> np.ndarray:
            # Only complete rows: the rest may be mid-write.
            return np.asarray(self._dataset(f"generations/{name}")[:done])

        terms = "generations/best_terms" in self._rows
        best_terms = rows("best_terms") if terms else np.zeros((done, 0))
        mean_terms = rows("mean_terms") if terms else np.zeros((done, 0))
        steps = rows("env_steps") if "generations/env_steps" in self._rows else None
        return History(
            best_fitness=rows("best_fitness"),
            mean_fitness=rows("mean_fitness"),
            std_fitness=rows("std_fitness"),
            best_index=rows("best_index"),
            epsilon=rows("epsilon"),
            alpha=rows("alpha"),
            fitness=rows("fitness"),
            best_terms={t: best_terms[:, i] for i, t in enumerate(self.term_names)},
            mean_terms={t: mean_terms[:, i] for i, t in enumerate(self.term_names)},
            env_steps=steps,
        )

    def best_genome_arrays(self, generation: int = -1) -> dict[str, np.ndarray]:
        """All genome arrays (Q tables included) of a generation's best, leading axis 1.

        The genome is the one after its evaluation, with what it learned (what the elite carries
        into the next generation). Negative generations count from the last completed one.
        """
        return self._steady(lambda: self._best_genome_arrays(generation))

    def _best_genome_arrays(self, generation: int) -> dict[str, np.ndarray]:
        done = self._generations_done()
        if generation < 0:
            generation += done
        if not 0 <= generation < done:
            raise RunFileError(
                f"generation {generation} is not complete in {self.path.name} "
                f"(generations 0..{done - 1} are)"
                if done
                else f"{self.path.name} has no completed generation yet"
            )
        return {
            name: np.asarray(self._dataset(f"genomes/best/{name}")[generation])[None]
            for name in self._file["genomes/best"]
        }

    def checkpoint(self) -> tuple[int, dict[str, np.ndarray]] | None:
        """(next generation to evaluate, full population arrays) of the last checkpoint."""
        return self._steady(self._checkpoint)

    def _checkpoint(self) -> tuple[int, dict[str, np.ndarray]] | None:
        slot_value, generation_value = self._read("progress/checkpoint")
        slot = check_progress("progress/checkpoint slot", slot_value, -1, 1, self.path)
        generations = self.config.training.generations
        generation = check_progress(
            "progress/checkpoint generation", generation_value, 0, generations, self.path
        )
        if slot < 0:
            return None
        group = f"checkpoint/slot{slot}"
        return generation, {name: self._read(f"{group}/{name}") for name in self._file[group]}

    def elite(self) -> Trajectory | None:
        """The final elite's recorded life (the evaluation that earned its fitness), if done (a
        task run records none)."""
        if "elite/generation" not in self._rows or not self.finished:
            return None
        return self._steady(lambda: self._trajectory("elite"))

    def _trajectory(self, group: str, recorded: bool = True) -> Trajectory:
        def read(name: str) -> np.ndarray:  # without `recorded`: no trial, shapes kept
            return self._read(name) if recorded else np.asarray(self._dataset(name)[:0])

        terms = read(f"{group}/terms")
        return Trajectory(
            poses=read(f"{group}/poses"),
            readings=read(f"{group}/readings"),
            observations=read(f"{group}/observations"),
            commands=read(f"{group}/commands"),
            terms={t: terms[..., i] for i, t in enumerate(self.term_names)},
            trace={name: read(f"{group}/trace/{name}") for name in self._file[f"{group}/trace"]},
            start_index=read(f"{group}/start_index"),
        )

    def implementation_names(self) -> list[str]:
        """Names of the implementation phases stored in this run."""
        group = self._file.get("implementation")
        if group is not None and not isinstance(group, h5py.Group):
            raise RunFileError(f"{self.path.name}: implementation is not a group")
        return sorted(group) if group is not None else []

    def implementation(self, name: str, recorded: bool = True) -> Implementation:
        """One stored implementation phase; with `recorded=False` without its recorded trials
        (`trials` and `recorded` hold none: a tenth of the reading time, for summaries)."""
        if name not in self.implementation_names():
            raise RunFileError(f"{self.path.name} has no implementation named {name!r}")
        return self._steady(lambda: self._implementation(name, recorded))

    def _implementation(self, name: str, recorded: bool) -> Implementation:
        base = f"implementation/{name}"
        group = self._file[base]
        if not isinstance(group, h5py.Group):
            raise RunFileError(f"{self.path.name}: {base} is not a group")
        attrs = group.attrs
        what = f"{self.path.name}: the settings of {base}"
        settings = ImplementationSettings.model_validate(
            loads_json(attrs["settings"], RunFileError, what)
        )
        try:
            check_implementation(group, self.term_names)
        except RunFileError as error:
            raise RunFileError(f"{self.path.name}: {error}") from None
        generations = self.config.training.generations
        generation = check_progress(
            f"{base} generation", attrs["generation"], 0, generations - 1, self.path
        )
        return Implementation(
            name=name,
            settings=settings,
            generation=generation,
            reward_per_step=self._read(f"{base}/reward_per_step"),
            trial_mean_reward=self._read(f"{base}/trial_mean_reward"),
            trial_mean_after_fault=self._read(f"{base}/trial_mean_after_fault"),
            start_index=self._read(f"{base}/start_index"),
            mean_reward=float(attrs["mean_reward"]),
            mean_after_fault=float(attrs["mean_after_fault"]),
            trials=self._trajectory(f"{base}/trials", recorded),
            recorded=self._read(f"{base}/recorded")[: None if recorded else 0],
        )


def _kind(path: Path, attrs: h5py.AttributeManager) -> RunKind:
    """The kind of run a file records (its `kind` attribute; none: a robot run's).

    Raises:
        RunFileError: not a gnp-lab run, or of an unknown kind.
    """
    if attrs.get("format") == LEGACY_TASK_FORMAT:
        raise RunFileError(f"{path} is a task run (gnp-lab replay, export)")
    if attrs.get("format") != FORMAT:
        raise RunFileError(f"{path} is an HDF5 file but not a gnp-lab run")
    kind = attrs.get(KIND_ATTRIBUTE, "robot")
    for known in RUN_KINDS:
        if kind == known:
            return known
    raise RunFileError(
        f"{path} is a run of an unknown kind {kind!r}; this gnp-lab reads {RUN_KINDS}"
    )


def file_kind(path: str | Path) -> RunKind:
    """The kind of run the file at `path` holds (an old-format task run's too: "task"), read
    without checking the rest of it; also while a writer holds it.

    Raises:
        RunFileError: missing, not a gnp-lab run, or of an unknown kind.
    """
    path = Path(path)
    with open_for_read(path) as handle:
        if handle.attrs.get("format") == LEGACY_TASK_FORMAT:
            return "task"
        return _kind(path, handle.attrs)
