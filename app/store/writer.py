"""Writing run files: the SWMR writer of a training run, and adding implementation results.

Every dataset of a training run is created before training starts (`schema.RUN_LAYOUT`), so that
the writer can stay in SWMR mode for the whole run (SWMR forbids creating objects later); rows
past `progress/generations_done` are not yet valid. Anything that creates objects afterwards (an
implementation result, a resume) writes a new file and renames it over the old one.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import h5py
import numpy as np

from app.loop.recording import Trajectory
from app.store.files import RunFileError, WriterLock, atomic_file, create_file
from app.store.legacy import fill_run_file, is_legacy_task_run, read_legacy_task_run
from app.store.reader import Implementation, RunReader
from app.store.schema import (
    IMPLEMENTATION_LAYOUT,
    RUN_KINDS,
    RunTemplate,
    build_run_layout,
    create_datasets,
    implementation_dims,
)
from app.store.space import file_size, require_space, run_growth
from sim import TERM_NAMES


class RunWriter:
    """The single writer of a run file, in SWMR mode for the whole training."""

    def __init__(
        self, path: Path, handle: h5py.File, template: RunTemplate, lock: WriterLock
    ) -> None:
        self.path = path
        self.config = template.config
        self.task_config = template.task_config  # a task run's whole config (JSON)
        self._file = handle
        self._lock = lock
        self._next_slot = 0
        self._growth = run_growth(template)
        # Datasets by path, looked up once: a generation's writes are ~20 small ones, and
        # h5py's lookup by path cost as much as the writes themselves (~1 ms a generation).
        self._datasets: dict[str, h5py.Dataset] = {}
        self._allocated: set[int] = set()  # checkpoint slots whose storage exists

    def _ds(self, path: str) -> h5py.Dataset:
        found = self._datasets.get(path)
        if found is None:
            found = self._datasets[path] = self._file[path]
        return found

    @classmethod
    def create(cls, path: str | Path, template: RunTemplate) -> RunWriter:
        """Create a new run file (refusing to overwrite one) and start SWMR writing.

        Raises:
            RunFileError: `path` exists or its folder cannot be written.
        """
        path = Path(path)
        exists = f"{path} already exists; choose another --out or --resume it"
        if path.exists():
            raise RunFileError(exists)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise RunFileError(f"cannot create {path}: {error}") from None
        lock = WriterLock(path)
        try:
            # The file and its first checkpoint (`train` writes it at once).
            require_space(path.parent, run_growth(template).slot, f"a new run {path.name}")
            try:
                handle = _publish(path, template, overwrite=False)
            except FileExistsError:
                raise RunFileError(exists) from None
            except OSError as error:
                raise RunFileError(f"cannot create {path}: {error}") from None
        except BaseException:
            lock.release()
            raise
        return cls(path, handle, template, lock)

    @classmethod
    def resume(cls, path: str | Path) -> tuple[RunWriter, int, dict[str, np.ndarray]]:
        """Reopen an interrupted run of any kind for writing, from its last checkpoint.

        The file is rebuilt from a (SWMR) read into a new file renamed over it, which clears the
        consistency flags a killed writer leaves; an old-format task run (`app.store.legacy`) is
        so rewritten into the run format. Returns (writer, next generation, population).

        Raises:
            RunFileError: not a resumable run (missing, foreign, finished, no checkpoint).
        """
        path = Path(path)
        legacy = is_legacy_task_run(path)
        if not legacy:  # a clear error for a missing, foreign or corrupt file
            RunReader(path, RUN_KINDS).close()
        lock = WriterLock(path)
        try:
            return cls._upgrade(path, lock) if legacy else cls._rebuild(path, lock)
        except BaseException:
            lock.release()
            raise

    @classmethod
    def _rebuild(cls, path: Path, lock: WriterLock) -> tuple[RunWriter, int, dict[str, np.ndarray]]:
        with RunReader(path, RUN_KINDS) as run:
            if run.finished:
                raise RunFileError(f"{path} is a finished run; there is nothing to resume")
            require_space(path.parent, file_size(path), f"a resumed copy of {path.name}")
            point = run.checkpoint()
            if point is None:
                raise RunFileError(f"{path} has no checkpoint yet; start the run again")
            generation, population = point
            elite = run.file.get("elite/trace", {})  # a task run has no elite
            template = RunTemplate(
                config=run.config,
                genome={k: v[:1] for k, v in population.items()},
                trace={name: np.asarray(ds[0, :1]) for name, ds in elite.items()},
                task_config=run.task_config,
            )

            def restore(handle: h5py.File) -> None:
                _copy_values(run.file, handle)
                handle["progress/generations_done"][()] = generation

            handle = _publish(path, template, overwrite=True, fill=restore)
        writer = cls(path, handle, template, lock)
        slot = int(handle["progress/checkpoint"][0])
        writer._next_slot = 1 - slot
        return writer, generation, population

    @classmethod
    def _upgrade(cls, path: Path, lock: WriterLock) -> tuple[RunWriter, int, dict[str, np.ndarray]]:
        """`_rebuild` of an old-format task run: its generations up to its checkpoint and the
        checkpoint, in a task run of the run format."""
        run = read_legacy_task_run(path)
        if run.generations_done >= run.config.training.generations:
            raise RunFileError(f"{path} is a finished run; there is nothing to resume")
        generation, population = run.checkpoint()
        run = read_legacy_task_run(path, rows=generation)
        template = RunTemplate(
            config=run.config,
            genome={k: v[:1] for k, v in population.items()},
            trace={},
            task_config=run.task_config,
        )
        # What the old file holds, in the new layout, and the checkpoint slot it fills now.
        need = file_size(path) + run_growth(template).slot
        require_space(path.parent, need, f"a resumed copy of {path.name}")
        try:
            handle = _publish(
                path,
                template,
                overwrite=True,
                fill=lambda handle: fill_run_file(handle, run, generation, population),
            )
        except (KeyError, ValueError, TypeError) as error:
            raise RunFileError(f"{path.name}: cannot be resumed: {error}") from None
        writer = cls(path, handle, template, lock)
        writer._next_slot = 1
        return writer, generation, population

    def fitness(self, generations: int) -> np.ndarray:
        """(generations, P) fitness of the first `generations` generations in the file (a
        resumed run's before its checkpoint)."""
        return np.asarray(self._ds("generations/fitness")[:generations])

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
        epsilon: float,
        alpha: float,
        best_genome: Mapping[str, np.ndarray],
        best_terms: Mapping[str, float] | None = None,
        mean_terms: Mapping[str, float] | None = None,
        env_steps: int | None = None,
    ) -> None:
        """Record one evaluated generation (not yet counted as done): a robot run's with its
        best's and mean reward terms, a task run's with the env-steps its episodes took.

        Raises:
            DiskFullError: the disk cannot hold this generation (nothing of it was written;
                the file holds the generations before it).
        """
        growth = self._growth
        last = generation + 1 == self.config.training.generations
        self._require(
            growth.generation(generation) + (growth.elite if last else self._slot_growth()),
            f"generation {generation}",
            generation,
        )
        ds = self._ds
        best = int(np.argmax(fitness))
        ds("generations/fitness")[generation] = fitness
        ds("generations/best_fitness")[generation] = fitness[best]
        ds("generations/mean_fitness")[generation] = fitness.mean()
        ds("generations/std_fitness")[generation] = fitness.std()
        ds("generations/best_index")[generation] = best
        ds("generations/epsilon")[generation] = epsilon
        ds("generations/alpha")[generation] = alpha
        if best_terms is not None and mean_terms is not None:
            ds("generations/best_terms")[generation] = [best_terms[t] for t in TERM_NAMES]
            ds("generations/mean_terms")[generation] = [mean_terms[t] for t in TERM_NAMES]
        if env_steps is not None:
            ds("generations/env_steps")[generation] = env_steps
        for name, values in best_genome.items():
            ds(f"genomes/best/{name}")[generation] = values[0]

    def write_checkpoint(self, next_generation: int, population: Mapping[str, np.ndarray]) -> None:
        """Store the population to evaluate next in the free slot, then point at it."""
        self._require(self._slot_growth(), "a checkpoint", next_generation - 1)
        slot = self._next_slot
        for name, values in population.items():
            self._ds(f"checkpoint/slot{slot}/{name}")[...] = values
        self._file.flush()  # the slot is complete on disk before the pointer names it
        self._ds("progress/checkpoint")[...] = [slot, next_generation]
        self._next_slot = 1 - slot

    def _slot_growth(self) -> int:
        """Bytes the next checkpoint adds: a slot's storage is allocated at its first write."""
        slot = self._next_slot
        if slot in self._allocated:  # storage once allocated stays
            return 0
        unwritten = self._file[f"checkpoint/slot{slot}"].values()
        if any(d.id.get_storage_size() == 0 for d in unwritten):
            return self._growth.slot
        self._allocated.add(slot)
        return 0

    def _require(self, need: int, what: str, done: int) -> None:
        require_space(
            self.path.parent,
            need,
            f"{what} of {self.path.name} (it holds {max(done, 0)} generations; free some space, "
            f"then resume it: gnp-lab train --resume {self.path})",
        )

    def mark_done(self, generations_done: int) -> None:
        """Publish generations 0..generations_done−1 to readers (written last, then flushed)."""
        self._file.flush()
        self._ds("progress/generations_done")[()] = generations_done
        self._file.flush()

    def write_elite(self, generation: int, life: Trajectory) -> None:
        """Record the final elite's life and mark the run finished."""
        elite = self._file["elite"]
        _write_lives(elite, life)
        elite["generation"][()] = generation
        self._file.flush()
        self.finish()

    def finish(self) -> None:
        """Mark the run finished (a robot run's once its elite is written: `write_elite`)."""
        self._file["progress/finished"][()] = 1
        self._file.flush()


def _publish(
    path: Path,
    template: RunTemplate,
    *,
    overwrite: bool,
    fill: Callable[[h5py.File], None] | None = None,
) -> h5py.File:
    """Build a run file beside `path`, `fill` it, switch it to SWMR writing, then give it the
    name `path` (see `atomic_file`). Returns the open file, ready for the writer."""
    handle = None
    try:
        with atomic_file(path, overwrite=overwrite) as tmp:
            handle = create_file(tmp)
            build_run_layout(handle, template)
            if fill is not None:
                fill(handle)
            handle.swmr_mode = True
            handle.flush()
    except BaseException:
        if handle is not None:
            handle.close()
        raise
    return handle


def _copy_values(source: h5py.File, target: h5py.File) -> None:
    """Copy every dataset's values from `source` into the same-shaped datasets of `target`."""

    def copy(name: str, obj: h5py.Group | h5py.Dataset) -> None:
        if not isinstance(obj, h5py.Dataset):
            return
        if name not in target or target[name].shape != obj.shape:
            raise RunFileError(f"dataset {name} does not match this gnp-lab's layout")
        if obj.shape == () or obj.size:
            target[name][()] = obj[()]

    source.visititems(copy)


def _write_lives(group: h5py.Group, lives: Trajectory) -> None:
    group["poses"][...] = lives.poses
    group["readings"][...] = lives.readings
    group["observations"][...] = lives.observations
    group["commands"][...] = lives.commands
    group["terms"][...] = np.stack([lives.terms[t] for t in TERM_NAMES], axis=-1)
    for name, values in lives.trace.items():
        group[f"trace/{name}"][...] = values
    group["start_index"][...] = lives.start_index


def add_implementation(path: str | Path, result: Implementation) -> None:
    """Store an implementation phase under `implementation/<name>` of a finished run.

    The file is copied, extended and renamed over the original, so a crash leaves it intact.

    Raises:
        RunFileError: the run is not finished, the name is taken, or the file cannot be written.
    """
    path = Path(path)
    lock = WriterLock(path)
    try:
        with RunReader(path) as run:
            if not run.finished:
                raise RunFileError(f"{path.name} has not finished training")
            need = file_size(path) + _implementation_bytes(result)
            require_space(path.parent, need, f"implementation {result.name!r} of {path.name}")
            if result.name in run.implementation_names():
                raise RunFileError(
                    f"{path.name} already has an implementation named {result.name!r}; "
                    "choose another --name"
                )
            with atomic_file(path, overwrite=True) as tmp, create_file(tmp) as target:
                source = run.file
                for key, value in source.attrs.items():
                    target.attrs[key] = value
                for key in source:
                    source.copy(source[key], target, name=key)
                _store_implementation(target, result)
    except OSError as error:
        raise RunFileError(f"cannot write {path}: {error}") from None
    finally:
        lock.release()


def _implementation_bytes(result: Implementation) -> int:
    """Uncompressed bytes of an implementation's arrays: a bound of what storing it adds."""
    trials = result.trials
    arrays = [
        result.reward_per_step,
        result.trial_mean_reward,
        result.trial_mean_after_fault,
        result.start_index,
        result.recorded,
        trials.poses,
        trials.readings,
        trials.observations,
        trials.commands,
        *trials.terms.values(),
        *trials.trace.values(),
    ]
    return sum(int(np.asarray(a).nbytes) for a in arrays)


def _store_implementation(handle: h5py.File, result: Implementation) -> None:
    group = handle.require_group("implementation").create_group(result.name)
    group.attrs["settings"] = result.settings.model_dump_json()
    group.attrs["generation"] = result.generation
    group.attrs["mean_reward"] = result.mean_reward
    group.attrs["mean_after_fault"] = result.mean_after_fault
    trials = result.trials
    dims = implementation_dims(
        steps=len(result.reward_per_step),
        trials=len(result.start_index),
        recorded=len(trials.poses),
    )
    one_step = {name: values[:, 0] for name, values in trials.trace.items()}
    create_datasets(group, IMPLEMENTATION_LAYOUT, dims, {"trace": one_step})
    group["reward_per_step"][...] = result.reward_per_step
    group["trial_mean_reward"][...] = result.trial_mean_reward
    group["trial_mean_after_fault"][...] = result.trial_mean_after_fault
    group["start_index"][...] = result.start_index
    group["recorded"][...] = result.recorded
    _write_lives(group["trials"], trials)
