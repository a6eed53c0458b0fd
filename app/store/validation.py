"""A run file checked against its layout (`schema.RUN_LAYOUT`) before anything is read from it.

Every dataset `RunReader` reads is checked once, when the file is opened: present, a plain
dataset of the file itself (no link or storage that would make HDF5 read another file), of the
shape the run's config gives and of the layout's type. Values that change while a writer runs
(`progress/*`) are checked where they are read (`check_progress`). So a file with the right
groups and the wrong contents is a `RunFileError` naming the dataset, never a numpy or h5py
error further on.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from app.settings.config import RunConfig
from app.store.files import RunFileError
from app.store.schema import (
    IMPLEMENTATION_LAYOUT,
    Dataset,
    RunKind,
    implementation_dims,
    layout_of,
    place,
)

_NUMERIC = "biuf"
# Per-array rows (`{genome}`, `{trace}`) are checked on their leading axes: a 1-element sample
# array stands for each (its own axes, `...`, are the brain's to check when it builds a genome).
_SAMPLE = {"genome": {"*": np.zeros(1)}, "trace": {"*": np.zeros(1)}}


def check_run_layout(
    file: h5py.File, config: RunConfig, term_names: tuple[str, ...], kind: RunKind = "robot"
) -> None:
    """Every dataset of a run of `kind` (`layout_of`) in `file`, as the config shapes it.

    Raises:
        RunFileError: naming the first dataset missing, linked elsewhere, or of the wrong
            shape or type.
    """
    training = config.training
    dims = {
        "generations": training.generations,
        "population": training.population,
        "steps": training.steps,
        "lives": 1,
        "terms": len(term_names),
    }
    _check_rows(file, layout_of(kind), dims)


def check_implementation(group: h5py.Group, term_names: tuple[str, ...]) -> None:
    """Every dataset of `IMPLEMENTATION_LAYOUT` in one implementation group, its axes (steps,
    trials, recorded trials) as its 1-D datasets give them.

    Raises:
        RunFileError: as `check_run_layout`.
    """
    steps = plain_dataset(group, "reward_per_step").shape[:1]
    trials = plain_dataset(group, "trial_mean_reward").shape[:1]
    recorded = plain_dataset(group, "recorded").shape[:1]
    if len(steps) != 1 or len(trials) != 1 or len(recorded) != 1:
        raise RunFileError(f"{group.name}: reward_per_step, trial_mean_reward, recorded: 1-D")
    dims = implementation_dims(steps[0], trials[0], recorded[0])
    dims["terms"] = len(term_names)
    _check_rows(group, IMPLEMENTATION_LAYOUT, dims)


def _check_rows(group: h5py.Group, rows: Iterable[Dataset], dims: Mapping[str, int]) -> None:
    for placed in place(rows, dims, _SAMPLE):
        if "*" not in placed.path:
            _check(plain_dataset(group, placed.path), placed.shape, placed.dtype)
            continue
        folder = placed.path.rsplit("/", 1)[0]
        arrays = plain_group(group, folder)
        for name in arrays:
            dataset = plain_dataset(arrays, name)
            if dataset.shape[: len(placed.shape)] != placed.shape:
                raise RunFileError(f"{dataset.name}: shape {dataset.shape}, not {placed.shape}+")
            if dataset.dtype.kind not in _NUMERIC:
                raise RunFileError(f"{dataset.name}: type {dataset.dtype} is not numeric")


def plain_group(parent: h5py.Group, path: str) -> h5py.Group:
    found = _own(parent, path)
    if not isinstance(found, h5py.Group):
        raise RunFileError(f"{parent.name.rstrip('/')}/{path} is not a group")
    return found


def plain_dataset(parent: h5py.Group, path: str) -> h5py.Dataset:
    found = _own(parent, path)
    if not isinstance(found, h5py.Dataset):
        raise RunFileError(f"{found.name} is not a dataset")
    if found.external or found.is_virtual:
        raise RunFileError(f"{found.name} keeps its data outside the run file")
    return found


def _own(parent: h5py.Group, path: str) -> Any:
    """The object at `path` under `parent`, reached through hard links only (never another
    file's object)."""
    at = parent
    for part in path.split("/"):
        if not isinstance(at, h5py.Group):
            raise RunFileError(f"{at.name} is not a group")
        link = at.get(part, getlink=True)
        if link is None:
            raise RunFileError(f"{at.name.rstrip('/')}/{part} is missing")
        if not isinstance(link, h5py.HardLink):
            raise RunFileError(f"{at.name.rstrip('/')}/{part} is a link, not part of the file")
        at = at[part]
    return at


def _check(dataset: h5py.Dataset, shape: tuple[int, ...], dtype: np.dtype) -> None:
    if dataset.shape != shape:
        raise RunFileError(f"{dataset.name}: shape {dataset.shape}, the run's config says {shape}")
    if dataset.dtype.kind not in _NUMERIC or dataset.dtype.kind != dtype.kind:
        raise RunFileError(f"{dataset.name}: type {dataset.dtype}, not {dtype}")


def check_progress(name: str, value: np.ndarray, low: int, high: int, path: Path) -> int:
    """A `progress/*` value read from the file, an integer in low..high.

    Raises:
        RunFileError: naming the value and its range.
    """
    number = int(value)
    if not low <= number <= high:
        raise RunFileError(f"{path.name}: {name} is {number}, outside {low}..{high}")
    return number
