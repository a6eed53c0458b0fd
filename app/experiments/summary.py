"""The summary file of an experiment at one scale: its `ExperimentResults` as plain HDF5.

Layout (readable by h5dump and plain h5py; no pickles):

    /                       attrs: format, schema_version, package_version, name, description,
                            source, scale, units (JSON), and the experiment's definitions as
                            JSON: arms, conditions, comparisons, thesis
    /seeds                  (n,) int64: run seed of each row
    /scalars/METRIC/ARM/C   (n,) float64, one value per seed (NaN = not finished)
    /curves/METRIC/ARM/C    (n, L) float64, one curve per seed

C is the condition's name, or "-" for a training metric. Every value dataset carries attrs
`metric`, `arm`, `condition`, `label` and `description` (from `results.METRICS`).
"""

from __future__ import annotations

import contextlib
import json
import os
from dataclasses import asdict
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from app.experiments.results import (
    METRICS,
    Arm,
    Comparison,
    Condition,
    ExperimentResults,
    ThesisValue,
)
from app.experiments.spec import ExperimentError
from app.settings.user_files import loads_json
from app.store import package_version
from app.store.space import DiskFullError, require_space

FORMAT = "gnp-lab-experiment-summary"
SCHEMA_VERSION = 1
TRAINING = "-"  # the condition slot of training metrics
UNITS = {
    "final_best_fitness, best_fitness_curve": "mean reward per step (Eq. 2.8), 0..1",
    "mean_reward, mean_reward_before_fault, mean_reward_after_fault, reward_per_step": (
        "reward per step, 0..1"
    ),
    "fault_effect": "reward per step, after the fault minus the no-fault control, -1..1",
    "relative_fault_effect": "fault_effect over the no-fault control's reward per step, >= -1",
    "convergence_generation": "generation (1 = the first)",
    "best_fitness_curve axis 1": "generation",
    "reward_per_step axis 1": "implementation step",
}


class SummaryError(ExperimentError):
    """A summary file is missing, foreign or corrupt."""


def write_summary(results: ExperimentResults, path: str | Path) -> Path:
    """Write `results` to `path` (built under a temporary name, then renamed over it)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tables = (*results.scalars.values(), *results.curves.values())
    try:
        require_space(path.parent, sum(np.asarray(v).nbytes for v in tables), str(path.name))
    except DiskFullError as error:
        raise SummaryError(str(error)) from None
    try:
        with h5py.File(tmp, "w") as handle:
            attrs = handle.attrs
            attrs["format"] = FORMAT
            attrs["schema_version"] = SCHEMA_VERSION
            attrs["package_version"] = package_version()
            for key in ("name", "description", "source", "scale"):
                attrs[key] = getattr(results, key)
            attrs["control"] = results.control or ""
            attrs["looks"] = np.asarray(results.looks, dtype=np.int64)
            attrs["steps_per_run"] = float(results.steps_per_run)
            attrs["units"] = json.dumps(UNITS, ensure_ascii=False)
            for key in ("arms", "conditions", "comparisons", "thesis"):
                items = [asdict(item) for item in getattr(results, key)]
                attrs[key] = json.dumps(items, ensure_ascii=False)
            handle.create_dataset("seeds", data=np.asarray(results.seeds, dtype=np.int64))
            for kind, table in (("scalars", results.scalars), ("curves", results.curves)):
                for (metric, arm, condition), values in sorted(table.items()):
                    name = f"{kind}/{metric}/{arm}/{condition or TRAINING}"
                    dataset = handle.create_dataset(name, data=np.asarray(values, np.float64))
                    info = METRICS[metric]
                    dataset.attrs.update(
                        metric=metric,
                        arm=arm,
                        condition=condition,
                        label=info.label,
                        description=info.description,
                    )
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
    return path


def _table(handle: h5py.File, kind: str) -> dict[tuple[str, str, str], np.ndarray]:
    table: dict[tuple[str, str, str], np.ndarray] = {}
    group = handle.get(kind)
    if group is None:
        return table
    for metric, arms in group.items():
        for arm, conditions in arms.items():
            for condition, dataset in conditions.items():
                key = (metric, arm, "" if condition == TRAINING else condition)
                table[key] = np.asarray(dataset[()], dtype=np.float64)
    return table


def _items(attrs: Any, key: str, kind: type) -> tuple[Any, ...]:
    return tuple(kind(**item) for item in loads_json(attrs[key], SummaryError, f"attribute {key}"))


def read_summary(path: str | Path) -> ExperimentResults:
    """The `ExperimentResults` stored in a summary file.

    Raises:
        SummaryError: missing, foreign or corrupt file.
    """
    path = Path(path)
    if not path.is_file():
        raise SummaryError(f"summary file not found: {path}")
    try:
        with h5py.File(path, "r") as handle:
            attrs = handle.attrs
            if attrs.get("format") != FORMAT:
                raise SummaryError(f"{path} is not a gnp-lab experiment summary")
            if int(attrs["schema_version"]) != SCHEMA_VERSION:
                raise SummaryError(f"{path} has summary schema {attrs['schema_version']}")
            return ExperimentResults(
                name=str(attrs["name"]),
                description=str(attrs["description"]),
                source=str(attrs["source"]),
                scale=str(attrs["scale"]),
                arms=_items(attrs, "arms", Arm),
                seeds=tuple(int(s) for s in handle["seeds"][()]),
                conditions=_items(attrs, "conditions", Condition),
                comparisons=_items(attrs, "comparisons", Comparison),
                thesis=_items(attrs, "thesis", ThesisValue),
                control=str(attrs.get("control", "")) or None,
                looks=tuple(int(n) for n in attrs.get("looks", ())),
                steps_per_run=float(attrs.get("steps_per_run", 0.0)),
                scalars=_table(handle, "scalars"),
                curves=_table(handle, "curves"),
            )
    except (OSError, KeyError, TypeError, ValueError) as error:
        if isinstance(error, SummaryError):
            raise
        raise SummaryError(f"corrupt summary file {path}: {error}") from None
