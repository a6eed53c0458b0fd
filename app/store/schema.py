"""The layout of a run file as one table: each dataset's path, shape, type, storage and unit.

The writer builds files from these rows, the `units` attribute is read off them, and
docs/run-format.md describes the same rows. Every dataset of a training run exists from the
start (SWMR cannot create objects later), so shapes are given in terms of the run's config and
of a template individual. Changing a row changes the file format: bump SCHEMA_VERSION.

One table serves every kind of run (`RunKind`): the robot's, and a Gymnasium task's (any brain
family on a task, `app.tasks`). Each row names the kinds it belongs to; a task run's file
records its kind once, in the root attribute `kind` (a robot run's has none, as every file
before task runs shared the format), and its units are its own (a fitness is an episode's
return).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from importlib import metadata
from types import EllipsisType
from typing import Literal, get_args

import h5py
import numpy as np

from app.settings.config import RunConfig
from app.settings.layouts import layout_2
from app.settings.user_files import loads_json
from sim import IR_MAX, TERM_NAMES

FORMAT = "gnp-lab-run"
SCHEMA_VERSION = 1

RunKind = Literal["robot", "task"]
"""What a run trains in: the robot's arena, or a Gymnasium task (`app.tasks`)."""
RUN_KINDS: tuple[RunKind, ...] = get_args(RunKind)
ROBOT: tuple[RunKind, ...] = ("robot",)
TASK: tuple[RunKind, ...] = ("task",)
KIND_ATTRIBUTE = "kind"
"""The root attribute naming a run's kind; absent: "robot" (every file before task runs)."""


def package_version() -> str:
    """The installed gnp-lab version, recorded in every run file."""
    try:
        return metadata.version("gnp-lab")
    except metadata.PackageNotFoundError:
        return "0+unknown"


EPISODE_RETURN = "episode return"
"""The unit of a task run's fitness (and of a task experiment's test returns)."""
ENV_STEPS_UNIT = "env steps"
"""The unit of what a task's episodes took: steps of its environment."""


@dataclass(frozen=True)
class Unit:
    """One entry of the `units` attribute: the datasets it covers (its key) and the unit (in a
    task run `task_text`, where that differs)."""

    covers: str
    text: str
    task_text: str | None = None

    def text_in(self, kind: RunKind) -> str:
        return self.task_text if kind == "task" and self.task_text is not None else self.text


FITNESS = Unit(
    "generations/*_fitness", "mean reward per step (Eq. 2.8), 0..1", task_text=EPISODE_RETURN
)
TERMS = Unit("generations/*_terms", "mean per step of each reward term, 0..1")
EPSILON = Unit("generations/epsilon", "ε-greedy probability")
ALPHA = Unit("generations/alpha", "learning rate α")
POSE = Unit("elite/poses, trials/poses", "x mm, y mm, heading rad")
IR = Unit("elite/readings, elite/observations", f"IR reading 0..{IR_MAX:g}")
WHEELS = Unit("elite/commands", "wheel angular speed rad/s (left, right), −10..10")
REWARD_PER_STEP = Unit("implementation/*/reward_per_step", "reward per step, mean over trials")
ENV_STEPS = Unit("generations/env_steps", ENV_STEPS_UNIT)

Axis = str | int | EllipsisType


@dataclass(frozen=True)
class Dataset:
    """One row of the layout.

        A `{genome}` or `{trace}` in the path makes one dataset per array of the template's genome
        or step trace; `...` in the shape then stands for that array's own axes (after its leading
        one) and a `dtype` of None for its type. Named axes are lengths of the file (`Dims`); a
    last axis "terms" holds one column per reward term, named by a `columns` attribute. `kinds`:
    the kinds of run whose files hold the row.
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
    kinds: tuple[RunKind, ...] = RUN_KINDS


NAN = float("nan")


def _lives(group: str) -> tuple[Dataset, ...]:
    """Recorded lives (the elite's, or an implementation's recorded trials), step by step: the
    robot's only."""

    def per_step(
        name: str, tail: tuple[Axis, ...], dtype: str | None, unit: Unit | None = None
    ) -> Dataset:
        shape = ("lives", "steps", *tail)
        return Dataset(
            f"{group}/{name}", shape, dtype, chunk_rows=1, compress=True, unit=unit, kinds=ROBOT
        )

    return (
        per_step("poses", (3,), "f8", POSE),
        per_step("readings", (8,), "f8", IR),
        per_step("observations", (8,), "f8", IR),
        per_step("commands", (2,), "f8", WHEELS),
        per_step("terms", ("terms",), "f8"),
        per_step("trace/{trace}", (...,), None),
        Dataset(f"{group}/start_index", ("lives",), "i8", kinds=ROBOT),
    )


_TERM_ROWS: tuple[Axis, ...] = ("generations", "terms")  # a generation's reward terms

#: A training run of any kind (axes: generations, population, steps; lives = 1, the elite).
LAYOUT: tuple[Dataset, ...] = (
    Dataset("progress/generations_done", (), "i8", initial=0),
    Dataset("progress/checkpoint", (2,), "i8", initial=(-1, 0)),  # [slot, generation]
    Dataset("progress/finished", (), "i1", initial=0),
    Dataset("generations/best_fitness", ("generations",), "f8", 1024, fill=NAN, unit=FITNESS),
    Dataset("generations/mean_fitness", ("generations",), "f8", 1024, fill=NAN, unit=FITNESS),
    Dataset("generations/std_fitness", ("generations",), "f8", 1024, fill=NAN, unit=FITNESS),
    Dataset("generations/best_terms", _TERM_ROWS, "f8", 256, fill=NAN, unit=TERMS, kinds=ROBOT),
    Dataset("generations/mean_terms", _TERM_ROWS, "f8", 256, fill=NAN, unit=TERMS, kinds=ROBOT),
    Dataset("generations/epsilon", ("generations",), "f8", 1024, fill=NAN, unit=EPSILON),
    Dataset("generations/alpha", ("generations",), "f8", 1024, fill=NAN, unit=ALPHA),
    # The env-steps each generation's episodes took (the sum of their lengths); −1: not known
    # (a generation of a task run begun in the old format, app.store.legacy).
    Dataset(
        "generations/env_steps", ("generations",), "i8", 1024, fill=-1, unit=ENV_STEPS, kinds=TASK
    ),
    Dataset("generations/best_index", ("generations",), "i8", 1024, fill=-1),
    Dataset("generations/fitness", ("generations", "population"), "f8", 8, fill=NAN, unit=FITNESS),
    Dataset("genomes/best/{genome}", ("generations", ...), None, chunk_rows=1, compress=True),
    # Two whole-population checkpoints, each one chunk: written in one go, read in one go.
    Dataset("checkpoint/slot0/{genome}", ("population", ...), None, chunk_rows="population"),
    Dataset("checkpoint/slot1/{genome}", ("population", ...), None, chunk_rows="population"),
    Dataset("elite/generation", (), "i8", initial=-1, kinds=ROBOT),
    *_lives("elite"),
)

#: A robot run's rows, and a task run's (the rows of `LAYOUT` of each kind).
RUN_LAYOUT = tuple(row for row in LAYOUT if "robot" in row.kinds)
TASK_RUN_LAYOUT = tuple(row for row in LAYOUT if "task" in row.kinds)


def layout_of(kind: RunKind) -> tuple[Dataset, ...]:
    """The rows of a run of `kind`."""
    return RUN_LAYOUT if kind == "robot" else TASK_RUN_LAYOUT


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
    """Shapes the file needs before training starts (SWMR cannot create objects later).

    A task run's `config` is the robot run's config its family is bound with (its seed, brain
    and sizes: `task_run_header`); its whole config is `task_config`, stored as it is.
    """

    config: RunConfig
    genome: Mapping[str, np.ndarray]  # population_to_arrays of 1 individual: (1, ...) arrays
    trace: Mapping[str, np.ndarray]  # one step's StepTrace of 1 controller: (1, ...) arrays
    task_config: str | None = None  # a task run's config as JSON (app.tasks.TaskRunConfig)

    @property
    def kind(self) -> RunKind:
        return "robot" if self.task_config is None else "task"

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


def units_attribute(kind: RunKind = "robot") -> str:
    """The `units` attribute of a run of `kind`: every unit of its rows (a robot run's
    implementations' too), keyed by the datasets it covers."""
    rows = (*RUN_LAYOUT, *IMPLEMENTATION_LAYOUT) if kind == "robot" else layout_of(kind)
    units = dict.fromkeys(row.unit for row in rows if row.unit is not None)
    return json.dumps({unit.covers: unit.text_in(kind) for unit in units}, ensure_ascii=False)


def build_run_layout(handle: h5py.File, template: RunTemplate) -> None:
    """Write the root attributes and create every dataset of a training run of its kind."""
    config, kind = template.config, template.kind
    handle.attrs["format"] = FORMAT
    handle.attrs["schema_version"] = SCHEMA_VERSION
    handle.attrs["package_version"] = package_version()
    handle.attrs["seed"] = config.seed
    if template.task_config is None:
        handle.attrs["config"] = config.model_dump_json()
        handle.attrs["units"] = units_attribute()
        handle.attrs["reward_terms"] = list(TERM_NAMES)
    else:
        handle.attrs[KIND_ATTRIBUTE] = kind
        handle.attrs["config"] = template.task_config
        handle.attrs["units"] = units_attribute(kind)
    create_datasets(handle, layout_of(kind), template.dims(), template.arrays())


TASK_SIZES = ("population", "generations", "steps")
"""What of a task run's `training` its family is bound with (`task_run_header`)."""


@dataclass(frozen=True)
class TaskRunHeader:
    """What the store reads of a task run's config (`task_run_header`)."""

    task: str  # the Gymnasium id
    config: RunConfig  # the robot run's config its family is bound with


def task_run_header(text: str) -> TaskRunHeader:
    """A task run's stored config (JSON, either layout) as the store reads it: its task id and
    the robot run's config its family is bound with, of its seed, its brain and of its training
    `TASK_SIZES` (the rest of the lab's settings at their defaults, unused;
    `app.tasks.TaskRunConfig.run_config` binds the same). The store reads a task run through
    it without Gymnasium; `app.tasks` reads the whole config.

    Raises:
        ValueError: not JSON (or too large or deep), or not a task run's config.
        pydantic.ValidationError: a brain or size out of its range.
    """
    data = loads_json(text, ValueError, "the stored task config")
    if not isinstance(data, dict):
        raise ValueError("a stored task config is a JSON object")
    data = layout_2(data)  # a task run before issue #46 is GNP's, in layout 1
    training, task = data.get("training"), data.get("task")
    if not isinstance(training, dict) or not isinstance(task, dict):
        raise ValueError("a stored task config has a task and a training section")
    try:
        sizes = {name: training[name] for name in TASK_SIZES}
    except KeyError as error:
        raise ValueError(f"a stored task config's training has no {error}") from None
    bound = {key: data[key] for key in ("seed", "brain") if key in data}
    return TaskRunHeader(
        str(task.get("id", "?")), RunConfig.model_validate({**bound, "training": sizes})
    )


def implementation_dims(steps: int, trials: int, recorded: int) -> dict[str, int]:
    """The axes of an implementation group: its life length, trial count, recorded trials."""
    return {"steps": steps, "trials": trials, "lives": recorded, "terms": len(TERM_NAMES)}
