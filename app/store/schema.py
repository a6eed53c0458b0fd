"""The layout of a run file as one table: each dataset's path, shape, type, storage and unit.

The writer builds files from these rows, the `units` attribute is read off them, and
docs/run-format.md describes the same rows. Every dataset of a training run exists from the
start (SWMR cannot create objects later), so shapes are given in terms of the run's config and
of a template individual. Changing a row changes the file format: bump SCHEMA_VERSION.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from importlib import metadata
from types import EllipsisType

import h5py
import numpy as np

from app.settings.config import RunConfig
from sim import IR_MAX, TERM_NAMES

FORMAT = "gnp-lab-run"
SCHEMA_VERSION = 1


def package_version() -> str:
    """The installed gnp-lab version, recorded in every run file."""
    try:
        return metadata.version("gnp-lab")
    except metadata.PackageNotFoundError:
        return "0+unknown"


@dataclass(frozen=True)
class Unit:
    """One entry of the `units` attribute: the datasets it covers (its key) and the unit."""

    covers: str
    text: str


FITNESS = Unit("generations/*_fitness", "mean reward per step (Eq. 2.8), 0..1")
TERMS = Unit("generations/*_terms", "mean per step of each reward term, 0..1")
EPSILON = Unit("generations/epsilon", "ε-greedy probability")
ALPHA = Unit("generations/alpha", "learning rate α")
POSE = Unit("elite/poses, trials/poses", "x mm, y mm, heading rad")
IR = Unit("elite/readings, elite/observations", f"IR reading 0..{IR_MAX:g}")
WHEELS = Unit("elite/commands", "wheel angular speed rad/s (left, right), −10..10")
REWARD_PER_STEP = Unit("implementation/*/reward_per_step", "reward per step, mean over trials")

Axis = str | int | EllipsisType


@dataclass(frozen=True)
class Dataset:
    """One row of the layout.

        A `{genome}` or `{trace}` in the path makes one dataset per array of the template's genome
        or step trace; `...` in the shape then stands for that array's own axes (after its leading
        one) and a `dtype` of None for its type. Named axes are lengths of the file (`Dims`); a
    last axis "terms" holds one column per reward term, named by a `columns` attribute.
    """

    path: str
    shape: tuple[Axis, ...]
    dtype: str | None
    # Rows per chunk along axis 0 (a number or an axis name); None: contiguous.
    chunk_rows: int | str | None = None
    compress: bool = False  # gzip, level 4
    fill: float | None = None  # value of rows not yet written (None: HDF5's zero)
    initial: int | tuple[int, ...] | None = None  # value written at creation
    unit: Unit | None = None


NAN = float("nan")


def _lives(group: str) -> tuple[Dataset, ...]:
    """Recorded lives (the elite's, or an implementation's recorded trials), step by step."""

    def per_step(
        name: str, tail: tuple[Axis, ...], dtype: str | None, unit: Unit | None = None
    ) -> Dataset:
        shape = ("lives", "steps", *tail)
        return Dataset(f"{group}/{name}", shape, dtype, chunk_rows=1, compress=True, unit=unit)

    return (
        per_step("poses", (3,), "f8", POSE),
        per_step("readings", (8,), "f8", IR),
        per_step("observations", (8,), "f8", IR),
        per_step("commands", (2,), "f8", WHEELS),
        per_step("terms", ("terms",), "f8"),
        per_step("trace/{trace}", (...,), None),
        Dataset(f"{group}/start_index", ("lives",), "i8"),
    )


#: A training run (axes: generations, population, steps; lives = 1, the elite).
RUN_LAYOUT: tuple[Dataset, ...] = (
    Dataset("progress/generations_done", (), "i8", initial=0),
    Dataset("progress/checkpoint", (2,), "i8", initial=(-1, 0)),  # [slot, generation]
    Dataset("progress/finished", (), "i1", initial=0),
    Dataset("generations/best_fitness", ("generations",), "f8", 1024, fill=NAN, unit=FITNESS),
    Dataset("generations/mean_fitness", ("generations",), "f8", 1024, fill=NAN, unit=FITNESS),
    Dataset("generations/std_fitness", ("generations",), "f8", 1024, fill=NAN, unit=FITNESS),
    Dataset("generations/best_terms", ("generations", "terms"), "f8", 256, fill=NAN, unit=TERMS),
    Dataset("generations/mean_terms", ("generations", "terms"), "f8", 256, fill=NAN, unit=TERMS),
    Dataset("generations/epsilon", ("generations",), "f8", 1024, fill=NAN, unit=EPSILON),
    Dataset("generations/alpha", ("generations",), "f8", 1024, fill=NAN, unit=ALPHA),
    Dataset("generations/best_index", ("generations",), "i8", 1024, fill=-1),
    Dataset("generations/fitness", ("generations", "population"), "f8", 8, fill=NAN, unit=FITNESS),
    Dataset("genomes/best/{genome}", ("generations", ...), None, chunk_rows=1, compress=True),
    # Two whole-population checkpoints, each one chunk: written in one go, read in one go.
    Dataset("checkpoint/slot0/{genome}", ("population", ...), None, chunk_rows="population"),
    Dataset("checkpoint/slot1/{genome}", ("population", ...), None, chunk_rows="population"),
    Dataset("elite/generation", (), "i8", initial=-1),
    *_lives("elite"),
)

#: One implementation phase, under `implementation/<name>/` (axes: steps, trials; lives = the
#: recorded trials).
IMPLEMENTATION_LAYOUT: tuple[Dataset, ...] = (
    Dataset("reward_per_step", ("steps",), "f8", unit=REWARD_PER_STEP),
    Dataset("trial_mean_reward", ("trials",), "f8"),
    Dataset("trial_mean_after_fault", ("trials",), "f8"),
    Dataset("start_index", ("trials",), "i8"),
    Dataset("recorded", ("lives",), "i8"),
    *_lives("trials"),
)

Dims = Mapping[str, int]  # axis name -> length
Arrays = Mapping[str, Mapping[str, np.ndarray]]  # "genome"/"trace" -> name -> (1, ...) sample


@dataclass(frozen=True)
class RunTemplate:
    """Shapes the file needs before training starts (SWMR cannot create objects later)."""

    config: RunConfig
    genome: Mapping[str, np.ndarray]  # population_to_arrays of 1 individual: (1, ...) arrays
    trace: Mapping[str, np.ndarray]  # one step's StepTrace of 1 controller: (1, ...) arrays

    def dims(self) -> dict[str, int]:
        training = self.config.training
        return {
            "generations": training.generations,
            "population": training.population,
            "steps": training.steps,
            "lives": 1,
            "terms": len(TERM_NAMES),
        }

    def arrays(self) -> dict[str, Mapping[str, np.ndarray]]:
        return {"genome": self.genome, "trace": self.trace}


@dataclass(frozen=True)
class Placed:
    """A row of the layout made concrete for one file."""

    path: str
    shape: tuple[int, ...]
    dtype: np.dtype
    row: Dataset


_PER_ARRAY = re.compile(r"\{(\w+)\}")


def place(rows: Iterable[Dataset], dims: Dims, arrays: Arrays) -> list[Placed]:
    """The concrete datasets of `rows`: named axes resolved, per-array rows expanded."""
    placed = []
    for row in rows:
        match = _PER_ARRAY.search(row.path)
        if match is None:
            shape = _resolve(row.shape, dims, None)
            placed.append(Placed(row.path, shape, np.dtype(row.dtype), row))
            continue
        for name, sample in arrays[match[1]].items():
            shape = _resolve(row.shape, dims, sample.shape[1:])
            dtype = np.dtype(row.dtype or sample.dtype)
            placed.append(Placed(row.path.replace(match[0], name), shape, dtype, row))
    return placed


def _resolve(shape: tuple[Axis, ...], dims: Dims, tail: tuple[int, ...] | None) -> tuple[int, ...]:
    lengths: list[int] = []
    for axis in shape:
        if isinstance(axis, EllipsisType):
            if tail is None:
                raise ValueError(f"`...` in {shape} stands for nothing outside a per-array row")
            lengths.extend(tail)
        else:
            lengths.append(dims[axis] if isinstance(axis, str) else axis)
    return tuple(lengths)


def create_datasets(group: h5py.Group, rows: Iterable[Dataset], dims: Dims, arrays: Arrays) -> None:
    """Create every dataset of `rows` (paths relative to `group`)."""
    for spec in place(rows, dims, arrays):
        row = spec.row
        if row.initial is not None:
            dataset = group.create_dataset(spec.path, data=np.array(row.initial, spec.dtype))
        else:
            chunks = _chunks(row, spec.shape, dims)
            gzip = row.compress and chunks is not None
            dataset = group.create_dataset(
                spec.path,
                spec.shape,
                spec.dtype,
                chunks=chunks,
                fillvalue=row.fill,
                compression="gzip" if gzip else None,
                compression_opts=4 if gzip else None,
            )
        if row.shape[-1:] == ("terms",):
            dataset.attrs["columns"] = list(TERM_NAMES)


def _chunks(row: Dataset, shape: tuple[int, ...], dims: Dims) -> tuple[int, ...] | None:
    if row.chunk_rows is None or 0 in shape:  # HDF5 cannot chunk an empty dataset
        return None
    rows = dims[row.chunk_rows] if isinstance(row.chunk_rows, str) else row.chunk_rows
    return (min(shape[0], rows), *shape[1:])


def units_attribute() -> str:
    """The `units` attribute: every unit of the layout, keyed by the datasets it covers."""
    rows = (*RUN_LAYOUT, *IMPLEMENTATION_LAYOUT)
    units = dict.fromkeys(row.unit for row in rows if row.unit is not None)
    return json.dumps({unit.covers: unit.text for unit in units}, ensure_ascii=False)


def build_run_layout(handle: h5py.File, template: RunTemplate) -> None:
    """Write the root attributes and create every dataset of a training run."""
    config = template.config
    handle.attrs["format"] = FORMAT
    handle.attrs["schema_version"] = SCHEMA_VERSION
    handle.attrs["package_version"] = package_version()
    handle.attrs["seed"] = config.seed
    handle.attrs["config"] = config.model_dump_json()
    handle.attrs["units"] = units_attribute()
    handle.attrs["reward_terms"] = list(TERM_NAMES)
    create_datasets(handle, RUN_LAYOUT, template.dims(), template.arrays())


def implementation_dims(steps: int, trials: int, recorded: int) -> dict[str, int]:
    """The axes of an implementation group: its life length, trial count, recorded trials."""
    return {"steps": steps, "trials": trials, "lives": recorded, "terms": len(TERM_NAMES)}
