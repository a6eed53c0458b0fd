"""An experiment's per-run values as CSV: the table every statistic of a report comes from.

`values.csv` has one row per run, metric and condition (columns `VALUES_COLUMNS`; `nan` for an
unfinished run). A committed report keeps it, so a report can be written again from it when
the rules of the verdicts change, without the run files (`read_values_csv`).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from pathlib import Path

import numpy as np

from app.experiments.results import METRICS, ExperimentResults
from app.experiments.spec import ExperimentError, ExperimentSpec
from app.settings.user_files import read_text

VALUES_COLUMNS = ("arm", "seed", "condition", "metric", "value")


def write_values_csv(results: ExperimentResults, path: Path) -> None:
    """Every per-run scalar value (NaN for unfinished runs), one row per run and metric."""
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(VALUES_COLUMNS)
        for (metric, arm, condition), values in results.scalars.items():
            for seed, value in zip(results.seeds, np.asarray(values, dtype=float), strict=True):
                writer.writerow([arm, seed, condition, metric, repr(float(value))])


def read_values_csv(
    path: str | Path, spec: ExperimentSpec, template: ExperimentResults
) -> ExperimentResults:
    """`template` (the experiment's results shape, e.g. `collect` of an empty folder) with the
    scalar values of a `values.csv` in place of its own, over the seeds the file holds.

    Metrics the file lacks (added to the experiment since) are left out (their claims read as
    not run, and the file is written back as it was); curves stay empty.

    Raises:
        ExperimentError: the file is missing, not a values table, or names an arm, metric or
            condition the experiment does not have.
    """
    path = Path(path)
    text = read_text(path, ExperimentError, "values file")
    try:
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as error:
        raise ExperimentError(f"{path} is not a values table: {error}") from None
    if not rows or tuple(rows[0]) != VALUES_COLUMNS:
        raise ExperimentError(f"{path} is not a values table (columns {', '.join(VALUES_COLUMNS)})")
    if len(rows) < 2:
        raise ExperimentError(f"{path} holds no values (only its header)")
    arms = {a.name for a in spec.arms}
    conditions = {c.name for c in spec.conditions} | {""}
    parsed: list[tuple[str, int, str, str, float]] = []
    for number, row in enumerate(rows[1:], start=2):
        try:
            arm, seed, condition, metric, cell = row
            if int(seed) < 0:
                raise ValueError("a negative seed")
            parsed.append((arm, int(seed), condition, metric, float(cell)))
        except ValueError:
            raise ExperimentError(f"{path}, line {number}: not a row of values: {row}") from None
        if arm not in arms or condition not in conditions or metric not in METRICS:
            raise ExperimentError(
                f"{path}, line {number}: arm {arm!r}, condition {condition!r} or metric "
                f"{metric!r} is not the experiment's"
            )
    seeds = tuple(sorted({run for _, run, _, _, _ in parsed}))
    row_of = {run: i for i, run in enumerate(seeds)}
    # The template's keys of the metrics the file holds: a metric added to the experiment since
    # (none of its values in the file) is left out, not written back as a column of NaN.
    held = {metric for _, _, _, metric, _ in parsed}
    scalars = {key: np.full(len(seeds), np.nan) for key in template.scalars if key[0] in held}
    for arm, run, condition, metric, value in parsed:
        key = (metric, arm, condition)
        scalars.setdefault(key, np.full(len(seeds), np.nan))[row_of[run]] = (
            value if math.isfinite(value) else np.nan
        )
    return dataclasses.replace(template, seeds=seeds, scalars=scalars, curves={})
