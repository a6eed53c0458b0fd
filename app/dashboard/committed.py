"""The committed reports of the checkout, read and checked for the Experiments tab (no viser).

A committed report is a folder `docs/experiments/NAME-SCALE/` holding `report.json` (what
`gnp-lab experiment report --out` writes: the verdicts, intervals, looks) and `values.csv`
(each run's values, `app.experiments.values`), beside its page `index.html`. `read_shelf`
reads every folder: a report whose files are missing, corrupt or foreign is one problem line
and the others are read on. An installed package has no checkout: `Shelf.missing` says so.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from app.experiments.ledger import DOCS
from app.experiments.results import VERDICTS
from app.experiments.spec import SCALES
from app.experiments.values import VALUES_COLUMNS
from app.settings.loading import describe_problems
from app.settings.user_files import loads_json, read_text

REPORT, VALUES, PAGE = "report.json", "values.csv", "index.html"
EXPLORATORY = "exploratory"  # an exploratory claim's "verdict": an interval, never a verdict


class CommittedError(ValueError):
    """A committed report that cannot be shown, in one line."""


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="ignore")


class ThesisValue(_Model):
    value: float | None = None
    source: str = ""


class Side(_Model):
    """One side of a claim: an arm (or the arm under a condition or metric), its runs' stats."""

    name: str
    label: str = ""
    n: int = Field(ge=0)
    mean: float | None = None
    sd: float | None = None
    thesis: ThesisValue | None = None


class Interval(_Model):
    low: float | None = None
    high: float | None = None
    level: float | None = Field(default=None, gt=0, lt=1)


class Need(_Model):
    seeds_per_arm_at_thesis_effect: float | None = None


class Claim(_Model):
    """One comparison of a report, as `report_json` writes it."""

    name: str = Field(min_length=1)
    claim: str = ""  # its sentence
    kind: str = Field(pattern="^(question|sanity)$")
    family: str = Field(default="primary", pattern="^(primary|exploratory)$")
    source: str = ""
    metric: str
    metric_label: str = ""
    condition: str | None = None
    condition_b: str | None = None
    metric_b: str | None = None
    sides: tuple[str, str] | None = None
    direction: str = ""
    a: Side
    b: Side
    difference: float | None = None
    verdict: str
    interval: Interval
    runs: tuple[int, int]
    look: int | None = Field(default=None, ge=1)
    need: Need | None = None
    post_hoc: bool | None = None
    paired: bool = False

    @field_validator("verdict")
    @classmethod
    def _known(cls, verdict: str) -> str:
        if verdict not in (*VERDICTS, EXPLORATORY):
            raise ValueError(f"unknown verdict {verdict!r}")
        return verdict

    def side_names(self) -> tuple[str, str]:
        return self.sides or (self.a.name, self.b.name)

    def value_keys(self) -> tuple[tuple[str, str, str], tuple[str, str, str]]:
        """The (arm, condition, metric) of each side in `values.csv`."""
        condition = self.condition or ""
        b = (self.b.name, self.condition_b or condition, self.metric_b or self.metric)
        return (self.a.name, condition, self.metric), b


class Arm(_Model):
    name: str
    label: str = ""


class Report(_Model):
    """The fields of a `report.json` the tab shows (others are ignored)."""

    experiment: str = Field(min_length=1)
    description: str = ""
    source: str = ""
    scale: str
    seeds: tuple[int, ...]
    alpha: float = Field(gt=0, lt=1)
    looks_planned: tuple[int, ...] = ()
    looks_made: tuple[int, ...] = ()
    arms: tuple[Arm, ...] = Field(min_length=1)
    comparisons: tuple[Claim, ...]

    @field_validator("scale")
    @classmethod
    def _scale(cls, scale: str) -> str:
        if scale not in SCALES:
            raise ValueError(f"scale must be one of {', '.join(SCALES)}")
        return scale


Values = dict[tuple[str, str, str], dict[int, float]]  # (arm, condition, metric) -> seed -> value


@dataclass(frozen=True)
class CommittedReport:
    """One committed report: its folder, its checked report.json (and the raw dict, for
    `app.experiments.questions`) and its runs' values."""

    folder: Path
    report: Report
    raw: dict[str, Any] = field(repr=False)
    values: Values = field(repr=False)

    @property
    def name(self) -> str:
        """The folder's name, NAME-SCALE."""
        return self.folder.name

    @property
    def page(self) -> Path:
        return self.folder / PAGE

    def claim(self, name: str) -> Claim:
        found = next((c for c in self.report.comparisons if c.name == name), None)
        if found is None:
            raise CommittedError(f"{self.name} has no claim {name!r}")
        return found

    def judged_seeds(self, claim: Claim) -> tuple[int, ...]:
        """The seeds a claim was judged on: the first seeds per arm of its look (all without
        one)."""
        seeds = tuple(sorted(self.report.seeds))
        looks = self.report.looks_made
        if claim.look is not None and claim.look <= len(looks):
            return seeds[: looks[claim.look - 1]]
        return seeds

    def spread(self, claim: Claim) -> tuple[np.ndarray, np.ndarray]:
        """Each side's run values for the claim (the judged seeds' finite values, by seed)."""
        seeds = self.judged_seeds(claim)
        out = []
        for key in claim.value_keys():
            by_seed = self.values.get(key, {})
            found = [by_seed[s] for s in seeds if s in by_seed and math.isfinite(by_seed[s])]
            out.append(np.array(found, dtype=np.float64))
        return out[0], out[1]


@dataclass(frozen=True)
class Shelf:
    """Every committed report found, the folders that could not be read, and why none were
    (no checkout)."""

    reports: tuple[CommittedReport, ...] = ()
    problems: tuple[tuple[str, str], ...] = ()  # (folder, what is wrong)
    missing: str = ""

    def by_key(self) -> dict[tuple[str, str], dict[str, Any]]:
        """(experiment, scale) -> report.json, as `app.experiments.questions` takes them."""
        return {(r.report.experiment, r.report.scale): r.raw for r in self.reports}

    def find(self, name: str) -> CommittedReport | None:
        return next((r for r in self.reports if r.name == name), None)

    def of(self, experiment: str, scale: str) -> CommittedReport | None:
        return self.find(f"{experiment}-{scale}")


def read_report(folder: Path) -> CommittedReport:
    """One report folder, checked: its report.json names its folder, values.csv is its runs'.

    Raises:
        CommittedError: a file is missing, unreadable, not a report, or not this folder's.
    """
    path = folder / REPORT
    try:
        raw = loads_json(read_text(path, CommittedError, REPORT), CommittedError, REPORT)
        report = Report.model_validate(raw)
    except CommittedError as error:
        raise CommittedError(f"{REPORT}: cannot be read ({error})") from None
    except ValidationError as error:
        raise CommittedError(f"{REPORT} is not a report: {describe_problems(error, 3)}") from None
    if folder.name != f"{report.experiment}-{report.scale}":
        raise CommittedError(f"{REPORT} holds {report.experiment} at {report.scale} scale")
    arms = {arm.name for arm in report.arms}
    return CommittedReport(folder, report, raw, read_values(folder / VALUES, arms))


def read_values(path: Path, arms: set[str]) -> Values:
    """A values.csv of the report's arms: (arm, condition, metric) -> seed -> value.

    Raises:
        CommittedError: missing, unreadable, not a values table, or of another experiment.
    """
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise CommittedError(f"{VALUES}: cannot be read ({error})") from None
    if not rows or tuple(rows[0]) != VALUES_COLUMNS:
        raise CommittedError(f"{VALUES} is not a values table ({', '.join(VALUES_COLUMNS)})")
    values: Values = {}
    for number, row in enumerate(rows[1:], start=2):
        try:
            arm, seed, condition, metric, text = row
            value = float(text)
            values.setdefault((arm, condition, metric), {})[int(seed)] = value
        except ValueError:
            raise CommittedError(f"{VALUES}, line {number}: not a row of values") from None
        if arm not in arms:
            raise CommittedError(f"{VALUES}, line {number}: arm {arm!r} is not the report's")
    return values


def shelf_signature(root: Path = DOCS) -> tuple[tuple[str, int, int], ...]:
    """What `read_shelf` would read, as (file, mtime, size): equal signatures, equal shelves."""
    if not root.is_dir():
        return ()
    files = sorted([*root.glob(f"*/{REPORT}"), *root.glob(f"*/{VALUES}")])
    return tuple((str(f), f.stat().st_mtime_ns, f.stat().st_size) for f in files)


def read_shelf(root: Path = DOCS) -> Shelf:
    """Every report folder under `root` (sorted by name); a folder that cannot be read is a
    problem, the rest are read on."""
    if not root.is_dir():
        return Shelf(
            missing=f"No committed reports: {root} is not here (the lab runs from an installed "
            "package, not a checkout of the repository)."
        )
    reports, problems = [], []
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        if not (folder / REPORT).exists() and not (folder / VALUES).exists():
            continue  # not a report folder
        try:
            reports.append(read_report(folder))
        except CommittedError as error:
            problems.append((folder.name, str(error)))
    return Shelf(tuple(reports), tuple(problems))
