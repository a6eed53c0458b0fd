"""HDF5 run files: one self-describing file per run, written by SWMR, read while written.

Layout (see docs/run-format.md): every dataset is created before training starts, so that the
writer can stay in SWMR mode for the whole run (SWMR forbids creating objects later); rows past
`progress/generations_done` are not yet valid. A file only ever appears at its final path fully
formed (built under a temporary name, then renamed), and a later change that adds objects
(an implementation result, a resume) rewrites a copy and renames it over the original, so a
crash at any moment leaves the old file or the new one, never half of either.

A SWMR writer killed by SIGKILL leaves the file's consistency flags set: HDF5 then refuses plain
opens ("file is already open for write") but SWMR reads work, so readers here always read in
SWMR mode, and `RunWriter.resume` rebuilds the file from such a read.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from app.config import ImplementationSettings, RunConfig
from app.recording import Trajectory
from gnp.config import GnpConfig
from sim import TERM_NAMES

FORMAT = "gnp-lab-run"
SCHEMA_VERSION = 1
#: Reward terms logged per generation and per step, in column order (sim.reward_terms keys).
UNITS = {
    "generations/*_fitness": "mean reward per step (Eq. 2.8), 0..1",
    "generations/*_terms": "mean per step of each reward term, 0..1",
    "generations/epsilon": "ε-greedy probability",
    "generations/alpha": "learning rate α",
    "elite/poses, trials/poses": "x mm, y mm, heading rad",
    "elite/readings, elite/observations": "IR reading 0..1023",
    "elite/commands": "wheel angular speed rad/s (left, right), −10..10",
    "implementation/*/reward_per_step": "reward per step, mean over trials",
}
_SUFFIX = ".h5"
# The HDF5 1.10 file format: the oldest with SWMR, and what h5dump of Debian 12 (1.10.8) reads.
_LIBVER = ("v110", "v110")


class RunFileError(Exception):
    """A run file or name is missing, foreign, corrupt, or cannot be used as asked."""


def package_version() -> str:
    """The installed gnp-lab version, recorded in every run file."""
    try:
        return metadata.version("gnp-lab")
    except metadata.PackageNotFoundError:
        return "0+unknown"


# --- names and listing ----------------------------------------------------------------------


def resolve_run(runs_dir: str | Path, name: str) -> Path:
    """Path of the run `name` ("demo" or "demo.h5") inside `runs_dir`.

    Raises:
        RunFileError: the name holds a path (no escaping `runs_dir`) or the run does not exist.
    """
    if not name or "/" in name or "\\" in name or name.startswith(".") or "\x00" in name:
        raise RunFileError(f"run name {name!r} must be a plain file name inside {runs_dir}")
    file_name = name if name.endswith(_SUFFIX) else name + _SUFFIX
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


def list_runs(runs_dir: str | Path) -> list[RunSummary]:
    """Every `*.h5` file in `runs_dir`, sorted by name; unreadable ones carry an `error`."""
    runs_dir = Path(runs_dir)
    if not runs_dir.is_dir():
        return []
    summaries = []
    for path in sorted(runs_dir.glob("*" + _SUFFIX)):
        name = path.name[: -len(_SUFFIX)]
        try:
            with RunReader(path) as run:
                history = run.history()
                best = float(history.best_fitness.max()) if len(history.best_fitness) else np.nan
                summaries.append(
                    RunSummary(
                        name=name,
                        path=path,
                        method=run.config.controller.method,
                        fuzzy=run.config.controller.fuzzy,
                        generations_done=run.generations_done,
                        generations=run.config.training.generations,
                        finished=run.finished,
                        best_fitness=best,
                        implementations=tuple(run.implementation_names()),
                    )
                )
        except RunFileError as error:
            summaries.append(RunSummary(name=name, path=path, error=str(error)))
    return summaries


# --- reading --------------------------------------------------------------------------------


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
    best_terms: dict[str, np.ndarray]  # term name -> (g,), mean per step of the best
    mean_terms: dict[str, np.ndarray]  # term name -> (g,), population mean


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


def _open_for_read(path: Path) -> h5py.File:
    if not path.exists():
        raise RunFileError(f"run file not found: {path}")
    if not path.is_file():
        raise RunFileError(f"not a file: {path}")
    if not h5py.is_hdf5(path):
        raise RunFileError(f"not an HDF5 file: {path}")
    try:
        return h5py.File(path, "r", locking=False)
    except OSError as error:
        if "already open for write" not in str(error):
            raise RunFileError(f"cannot open {path}: {error}") from None
    # A SWMR writer is live, or was killed: only a SWMR read opens the file. It skips HDF5's
    # end-of-file check (the file grows), and on a truncated file it would retry reads for a
    # long time, so check the length against the superblock first.
    _check_length(path)
    try:
        return h5py.File(path, "r", libver=_LIBVER, swmr=True, locking=False)
    except OSError as error:
        raise RunFileError(f"cannot open {path}: {error}") from None


def _check_length(path: Path) -> None:
    """Refuse a file shorter than the end-of-file address in its (v2/v3) superblock."""
    with path.open("rb") as handle:
        head = handle.read(48)
    if head[:8] != b"\x89HDF\r\n\x1a\n" or head[8] < 2 or head[9] != 8:
        return  # a superblock this check does not parse (not written by gnp-lab)
    stored_eof = int.from_bytes(head[28:36], "little")
    if path.stat().st_size < stored_eof:
        raise RunFileError(f"corrupt run file {path}: truncated")


class RunReader:
    """Read a run file, also while it is being written (call `refresh()` to see new data).

    Raises:
        RunFileError: missing, foreign (not a gnp-lab run) or corrupt file.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = _open_for_read(self.path)
        try:
            self._load_header()
        except RunFileError:
            self._file.close()
            raise
        except (KeyError, OSError, ValueError, TypeError) as error:
            self._file.close()
            raise RunFileError(f"corrupt run file {self.path}: {error}") from None

    def _load_header(self) -> None:
        attrs = self._file.attrs
        if attrs.get("format") != FORMAT:
            raise RunFileError(f"{self.path} is an HDF5 file but not a gnp-lab run")
        version = int(attrs["schema_version"])
        if version != SCHEMA_VERSION:
            raise RunFileError(
                f"{self.path} has run-file schema {version}; this gnp-lab reads {SCHEMA_VERSION}"
            )
        try:
            self.config = RunConfig.model_validate_json(attrs["config"])
        except ValueError as error:
            raise RunFileError(f"{self.path} holds an invalid config: {error}") from None
        self.seed = int(attrs["seed"])
        self.package_version = str(attrs["package_version"])
        self.term_names = tuple(str(t) for t in attrs["reward_terms"])
        self._inode = os.stat(self.path).st_ino
        self._file["progress/generations_done"].refresh()

    # -- lifecycle --

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> RunReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def refresh(self) -> None:
        """See what the writer flushed since: reopen if the file was replaced, else refresh."""
        try:
            inode = os.stat(self.path).st_ino
        except FileNotFoundError:
            return
        if inode != self._inode:
            self._file.close()
            self._file = _open_for_read(self.path)
            self._load_header()
            return
        if self._file.swmr_mode:
            self._file.visititems(
                lambda _name, obj: obj.refresh() if isinstance(obj, h5py.Dataset) else None
            )

    # -- contents --

    def _read(self, name: str) -> np.ndarray:
        dataset = self._file[name]
        if self._file.swmr_mode:
            dataset.refresh()
        return np.asarray(dataset[()])

    @property
    def generations_done(self) -> int:
        """Generations whose results are complete in the file."""
        return int(self._read("progress/generations_done"))

    @property
    def finished(self) -> bool:
        """True once training completed and the final elite was recorded."""
        return bool(self._read("progress/finished"))

    @property
    def gnp_config(self) -> GnpConfig:
        return self.config.controller.gnp_config()

    def history(self) -> History:
        """Per-generation results of the completed generations."""
        done = self.generations_done
        group = "generations/"

        def rows(name: str) -> np.ndarray:
            return self._read(group + name)[:done]

        best_terms, mean_terms = rows("best_terms"), rows("mean_terms")
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
        )

    def best_genome_arrays(self, generation: int = -1) -> dict[str, np.ndarray]:
        """All genome arrays (Q tables included) of a generation's best, leading axis 1.

        The genome is the one after its evaluation, with what it learned (what the elite carries
        into the next generation). Negative generations count from the last completed one.
        """
        done = self.generations_done
        if generation < 0:
            generation += done
        if not 0 <= generation < done:
            raise RunFileError(
                f"generation {generation} is not complete in {self.path.name} "
                f"(generations 0..{done - 1} are)"
                if done
                else f"{self.path.name} has no completed generation yet"
            )
        arrays = {}
        for name, dataset in self._file["genomes/best"].items():
            if self._file.swmr_mode:
                dataset.refresh()
            arrays[name] = np.asarray(dataset[generation])[None]
        return arrays

    def best_genome(self, generation: int = -1) -> tuple[GnpConfig, Any]:
        """(`gnp.GnpConfig`, a 1-individual `gnp.Population`) of a generation's best."""
        import gnp

        cfg = self.gnp_config
        return cfg, gnp.population_from_arrays(cfg, self.best_genome_arrays(generation))

    def checkpoint(self) -> tuple[int, dict[str, np.ndarray]] | None:
        """(next generation to evaluate, full population arrays) of the last checkpoint."""
        slot, generation = (int(v) for v in self._read("progress/checkpoint"))
        if slot < 0:
            return None
        group = self._file[f"checkpoint/slot{slot}"]
        return generation, {name: self._read(f"checkpoint/slot{slot}/{name}") for name in group}

    def elite(self) -> Trajectory | None:
        """The final elite's recorded life (the evaluation that earned its fitness), if done."""
        if not self.finished:
            return None
        return self._trajectory("elite")

    @property
    def elite_generation(self) -> int:
        return int(self._read("elite/generation"))

    def _trajectory(self, group: str) -> Trajectory:
        terms = self._read(f"{group}/terms")
        trace_group = self._file[f"{group}/trace"]
        return Trajectory(
            poses=self._read(f"{group}/poses"),
            readings=self._read(f"{group}/readings"),
            observations=self._read(f"{group}/observations"),
            commands=self._read(f"{group}/commands"),
            terms={t: terms[..., i] for i, t in enumerate(self.term_names)},
            trace={name: self._read(f"{group}/trace/{name}") for name in trace_group},
            start_index=self._read(f"{group}/start_index"),
        )

    def implementation_names(self) -> list[str]:
        """Names of the implementation phases stored in this run."""
        group = self._file.get("implementation")
        return sorted(group) if group is not None else []

    def implementation(self, name: str) -> Implementation:
        """One stored implementation phase."""
        if name not in self.implementation_names():
            raise RunFileError(f"{self.path.name} has no implementation named {name!r}")
        base = f"implementation/{name}"
        attrs = self._file[base].attrs
        return Implementation(
            name=name,
            settings=ImplementationSettings.model_validate_json(attrs["settings"]),
            generation=int(attrs["generation"]),
            reward_per_step=self._read(f"{base}/reward_per_step"),
            trial_mean_reward=self._read(f"{base}/trial_mean_reward"),
            trial_mean_after_fault=self._read(f"{base}/trial_mean_after_fault"),
            start_index=self._read(f"{base}/start_index"),
            mean_reward=float(attrs["mean_reward"]),
            mean_after_fault=float(attrs["mean_after_fault"]),
            trials=self._trajectory(f"{base}/trials"),
            recorded=self._read(f"{base}/recorded"),
        )


# --- writing --------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunTemplate:
    """Shapes the file needs before training starts (SWMR cannot create objects later)."""

    config: RunConfig
    genome: Mapping[str, np.ndarray]  # population_to_arrays of 1 individual: (1, ...) arrays
    trace: Mapping[str, np.ndarray]  # one step's StepTrace of 1 controller: (1, ...) arrays


def _tmp_path(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


class _WriterLock:
    """An advisory lock (`.NAME.h5.lock` beside the run) held by whoever writes the run.

    Readers never take it. The kernel drops it when its holder dies, even by SIGKILL, so a
    killed run can be resumed while a live (or paused) one cannot get a second writer.
    """

    def __init__(self, path: Path) -> None:
        lock_path = path.with_name(f".{path.name}.lock")
        try:
            self._handle = lock_path.open("a")
        except OSError as error:
            raise RunFileError(f"cannot write beside {path}: {error}") from None
        try:
            fcntl.flock(self._handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._handle.close()
            raise RunFileError(
                f"{path.name} is being written by another gnp-lab process (training, resume "
                "or implementation); wait for it to finish or stop it"
            ) from None

    def release(self) -> None:
        if not self._handle.closed:
            fcntl.flock(self._handle, fcntl.LOCK_UN)
            self._handle.close()


def _chunked(
    group: h5py.Group,
    name: str,
    shape: tuple[int, ...],
    dtype: Any,
    *,
    chunk_rows: int,
    compress: bool = False,
    fill: Any = 0,
) -> h5py.Dataset:
    if not shape or 0 in shape:
        return group.create_dataset(name, shape=shape, dtype=dtype, fillvalue=fill)
    chunks = (min(shape[0], chunk_rows), *shape[1:])
    return group.create_dataset(
        name,
        shape=shape,
        dtype=dtype,
        chunks=chunks,
        fillvalue=fill,
        compression="gzip" if compress else None,
        compression_opts=4 if compress else None,
    )


def _create_trajectory(
    group: h5py.Group, k: int, steps: int, trace: Mapping[str, np.ndarray]
) -> None:
    def make(name: str, tail: tuple[int, ...], dtype: Any) -> None:
        _chunked(group, name, (k, steps, *tail), dtype, chunk_rows=1, compress=True)

    make("poses", (3,), "f8")
    make("readings", (8,), "f8")
    make("observations", (8,), "f8")
    make("commands", (2,), "f8")
    make("terms", (len(TERM_NAMES),), "f8")
    group["terms"].attrs["columns"] = list(TERM_NAMES)
    traces = group.create_group("trace")
    for name, sample in trace.items():
        _chunked(
            traces, name, (k, steps, *sample.shape[1:]), sample.dtype, chunk_rows=1, compress=True
        )
    group.create_dataset("start_index", shape=(k,), dtype="i8")


def _build_layout(handle: h5py.File, template: RunTemplate) -> None:
    config = template.config
    generations, population = config.training.generations, config.training.population
    handle.attrs["format"] = FORMAT
    handle.attrs["schema_version"] = SCHEMA_VERSION
    handle.attrs["package_version"] = package_version()
    handle.attrs["seed"] = config.seed
    handle.attrs["config"] = config.model_dump_json()
    handle.attrs["units"] = json.dumps(UNITS, ensure_ascii=False)
    handle.attrs["reward_terms"] = list(TERM_NAMES)

    progress = handle.create_group("progress")
    progress.create_dataset("generations_done", data=np.int64(0))
    progress.create_dataset("checkpoint", data=np.array([-1, 0], dtype=np.int64))
    progress.create_dataset("finished", data=np.int8(0))

    gens = handle.create_group("generations")
    for name in ("best_fitness", "mean_fitness", "std_fitness", "epsilon", "alpha"):
        _chunked(gens, name, (generations,), "f8", chunk_rows=1024, fill=np.nan)
    _chunked(gens, "best_index", (generations,), "i8", chunk_rows=1024, fill=-1)
    _chunked(gens, "fitness", (generations, population), "f8", chunk_rows=8, fill=np.nan)
    for name in ("best_terms", "mean_terms"):
        _chunked(gens, name, (generations, len(TERM_NAMES)), "f8", chunk_rows=256, fill=np.nan)
        gens[name].attrs["columns"] = list(TERM_NAMES)

    best = handle.create_group("genomes").create_group("best")
    for name, sample in template.genome.items():
        shape = (generations, *sample.shape[1:])
        _chunked(best, name, shape, sample.dtype, chunk_rows=1, compress=True)
    for slot in (0, 1):
        group = handle.create_group(f"checkpoint/slot{slot}")
        for name, sample in template.genome.items():
            shape = (population, *sample.shape[1:])
            group.create_dataset(name, shape=shape, dtype=sample.dtype, chunks=shape)

    elite = handle.create_group("elite")
    elite.create_dataset("generation", data=np.int64(-1))
    _create_trajectory(elite, 1, config.training.steps, template.trace)


def _copy_contents(source: h5py.File, target: h5py.File) -> None:
    """Copy every dataset's values from `source` into the same-shaped datasets of `target`."""

    def copy(name: str, obj: Any) -> None:
        if not isinstance(obj, h5py.Dataset):
            return
        if name not in target or target[name].shape != obj.shape:
            raise RunFileError(f"dataset {name} does not match this gnp-lab's layout")
        if obj.shape == () or obj.size:
            target[name][()] = obj[()]

    source.visititems(copy)


class RunWriter:
    """The single writer of a run file, in SWMR mode for the whole training."""

    def __init__(self, path: Path, handle: h5py.File, config: RunConfig, lock: _WriterLock) -> None:
        self.path = path
        self.config = config
        self._file = handle
        self._lock = lock
        self._next_slot = 0

    @classmethod
    def create(cls, path: str | Path, template: RunTemplate) -> RunWriter:
        """Create a new run file (refusing to overwrite one) and start SWMR writing.

        Raises:
            RunFileError: `path` exists or its folder cannot be written.
        """
        path = Path(path)
        if path.exists():
            raise RunFileError(f"{path} already exists; choose another --out or --resume it")
        tmp = _tmp_path(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise RunFileError(f"cannot create {path}: {error}") from None
        lock = _WriterLock(path)
        try:
            handle = h5py.File(tmp, "w", libver=_LIBVER, locking=False)
        except OSError as error:
            lock.release()
            raise RunFileError(f"cannot create {path}: {error}") from None
        try:
            _build_layout(handle, template)
            handle.swmr_mode = True
            handle.flush()
            # Link only now: the file appears complete. os.link fails rather than overwrite.
            os.link(tmp, path)
        except FileExistsError:
            handle.close()
            lock.release()
            raise RunFileError(
                f"{path} already exists; choose another --out or --resume it"
            ) from None
        except BaseException:
            handle.close()
            lock.release()
            raise
        finally:
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
        return cls(path, handle, template.config, lock)

    @classmethod
    def resume(cls, path: str | Path) -> tuple[RunWriter, int, dict[str, np.ndarray]]:
        """Reopen an interrupted run for writing, from its last checkpoint.

        The file is rebuilt from a (SWMR) read into a new file renamed over it, which clears the
        consistency flags a killed writer leaves. Returns (writer, next generation, population).

        Raises:
            RunFileError: not a resumable run (missing, foreign, finished, no checkpoint).
        """
        path = Path(path)
        RunReader(path).close()  # a clear error for a missing, foreign or corrupt file
        lock = _WriterLock(path)
        try:
            return cls._rebuild(path, lock)
        except BaseException:
            lock.release()
            raise

    @classmethod
    def _rebuild(
        cls, path: Path, lock: _WriterLock
    ) -> tuple[RunWriter, int, dict[str, np.ndarray]]:
        with RunReader(path) as run:
            if run.finished:
                raise RunFileError(f"{path} is a finished run; there is nothing to resume")
            point = run.checkpoint()
            if point is None:
                raise RunFileError(f"{path} has no checkpoint yet; start the run again")
            generation, population = point
            template = RunTemplate(
                config=run.config,
                genome={k: v[:1] for k, v in population.items()},
                trace={
                    name: np.asarray(ds[0, :1]) for name, ds in run._file["elite/trace"].items()
                },
            )
            tmp = _tmp_path(path)
            handle = h5py.File(tmp, "w", libver=_LIBVER, locking=False)
            try:
                _build_layout(handle, template)
                _copy_contents(run._file, handle)
                handle.attrs["package_version"] = package_version()
                handle["progress/generations_done"][()] = generation
                handle.swmr_mode = True
                handle.flush()
                os.replace(tmp, path)
            except BaseException:
                handle.close()
                with contextlib.suppress(FileNotFoundError):
                    tmp.unlink()
                raise
        writer = cls(path, handle, template.config, lock)
        slot = int(handle["progress/checkpoint"][0])
        writer._next_slot = 1 - slot
        return writer, generation, population

    def close(self) -> None:
        if self._file.id.valid:
            self._file.flush()
            self._file.close()
        self._lock.release()

    def __enter__(self) -> RunWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def write_generation(
        self,
        generation: int,
        *,
        fitness: np.ndarray,
        best_terms: Mapping[str, float],
        mean_terms: Mapping[str, float],
        epsilon: float,
        alpha: float,
        best_genome: Mapping[str, np.ndarray],
    ) -> None:
        """Record one evaluated generation (not yet counted as done)."""
        gens = self._file["generations"]
        best = int(np.argmax(fitness))
        gens["fitness"][generation] = fitness
        gens["best_fitness"][generation] = fitness[best]
        gens["mean_fitness"][generation] = fitness.mean()
        gens["std_fitness"][generation] = fitness.std()
        gens["best_index"][generation] = best
        gens["epsilon"][generation] = epsilon
        gens["alpha"][generation] = alpha
        gens["best_terms"][generation] = [best_terms[t] for t in TERM_NAMES]
        gens["mean_terms"][generation] = [mean_terms[t] for t in TERM_NAMES]
        genomes = self._file["genomes/best"]
        for name, values in best_genome.items():
            genomes[name][generation] = values[0]

    def write_checkpoint(self, next_generation: int, population: Mapping[str, np.ndarray]) -> None:
        """Store the population to evaluate next in the free slot, then point at it."""
        slot = self._next_slot
        group = self._file[f"checkpoint/slot{slot}"]
        for name, values in population.items():
            group[name][...] = values
        self._file.flush()  # the slot is complete on disk before the pointer names it
        self._file["progress/checkpoint"][...] = [slot, next_generation]
        self._next_slot = 1 - slot

    def mark_done(self, generations_done: int) -> None:
        """Publish generations 0..generations_done−1 to readers (written last, then flushed)."""
        self._file.flush()
        self._file["progress/generations_done"][()] = generations_done
        self._file.flush()

    def write_elite(self, generation: int, life: Trajectory) -> None:
        """Record the final elite's life and mark the run finished."""
        elite = self._file["elite"]
        _write_trajectory(elite, life)
        elite["generation"][()] = generation
        self._file.flush()
        self._file["progress/finished"][()] = 1
        self._file.flush()


def _write_trajectory(group: h5py.Group, life: Trajectory) -> None:
    group["poses"][...] = life.poses
    group["readings"][...] = life.readings
    group["observations"][...] = life.observations
    group["commands"][...] = life.commands
    group["terms"][...] = np.stack([life.terms[t] for t in TERM_NAMES], axis=-1)
    for name, values in life.trace.items():
        group[f"trace/{name}"][...] = values
    group["start_index"][...] = life.start_index


def add_implementation(path: str | Path, result: Implementation) -> None:
    """Store an implementation phase under `implementation/<name>` of a finished run.

    The file is copied, extended and renamed over the original, so a crash leaves it intact.

    Raises:
        RunFileError: the run is not finished, or the name is taken.
    """
    path = Path(path)
    lock = _WriterLock(path)
    try:
        with RunReader(path) as run:
            if not run.finished:
                raise RunFileError(f"{path.name} has not finished training")
            if result.name in run.implementation_names():
                raise RunFileError(
                    f"{path.name} already has an implementation named {result.name!r}; "
                    "choose another --name"
                )
        tmp = _tmp_path(path)
        try:
            with (
                _open_for_read(path) as source,
                h5py.File(tmp, "w", libver=_LIBVER, locking=False) as target,
            ):
                for key, value in source.attrs.items():
                    target.attrs[key] = value
                for key in source:
                    source.copy(source[key], target, name=key)
                _store_implementation(target, result)
            os.replace(tmp, path)
        except OSError as error:
            raise RunFileError(f"cannot write {path}: {error}") from None
        finally:
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
    finally:
        lock.release()


def _store_implementation(handle: h5py.File, result: Implementation) -> None:
    group = handle.require_group("implementation").create_group(result.name)
    group.attrs["settings"] = result.settings.model_dump_json()
    group.attrs["generation"] = result.generation
    group.attrs["mean_reward"] = result.mean_reward
    group.attrs["mean_after_fault"] = result.mean_after_fault
    group.create_dataset("reward_per_step", data=result.reward_per_step)
    group.create_dataset("trial_mean_reward", data=result.trial_mean_reward)
    group.create_dataset("trial_mean_after_fault", data=result.trial_mean_after_fault)
    group.create_dataset("start_index", data=result.start_index)
    group.create_dataset("recorded", data=result.recorded)
    trials = group.create_group("trials")
    k, steps = result.trials.poses.shape[:2]
    _create_trajectory(
        trials, k, steps, {n: v[:, 0] if v.ndim > 1 else v for n, v in result.trials.trace.items()}
    )
    _write_trajectory(trials, result.trials)
