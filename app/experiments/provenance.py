"""When each claim and margin was declared, and whether before the data it is judged on.

Read from the repository's history (issue #30): for every shipped experiment, the commit from
which each claim (its sides, metric, conditions and direction) and its margin (the declared
margin and form, and the thesis's printed values of its two sides) have stood unchanged to this
day, and, per committed report folder, the first commit that published values of both of the
claim's sides (in `values.csv`, or in `report.json` before there was one). A claim or margin
declared after that commit is *post hoc*: its verdict is labelled so and kept out of the
tallies of pre-registered verdicts.

The history is read once and kept as data (`provenance.json`, package data), so a report made
where there is no history still knows it; `gnp-lab experiment provenance` rewrites the file and
a test checks it against the history.
"""

from __future__ import annotations

import csv
import io
import json
import subprocess
import tomllib
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from importlib import resources
from pathlib import Path
from typing import Any

SHIPPED_DIR = "app/experiments/shipped"
REPORTS_DIR = "docs/experiments"
FILE = "provenance.json"


class ProvenanceError(RuntimeError):
    """The repository's history cannot be read (not a git checkout, or a shallow one)."""


@dataclass(frozen=True)
class Declared:
    """Where a claim and its margin were declared, and when data on both sides appeared."""

    claim_commit: str
    claim_date: int  # commit time, seconds since the epoch
    margin_commit: str
    margin_date: int
    data_commit: str | None  # first commit with values of both sides at this scale
    data_date: int | None

    @property
    def claim_first(self) -> bool:
        return self.data_date is None or self.claim_date < self.data_date

    @property
    def margin_first(self) -> bool:
        return self.data_date is None or self.margin_date < self.data_date


# --- reading the history ---------------------------------------------------------------------


def _git(root: Path, *args: str) -> str:
    try:
        done = subprocess.run(
            ["git", "-C", str(root), *args], capture_output=True, text=True, check=True
        )
    except (OSError, subprocess.CalledProcessError) as error:
        raise ProvenanceError(f"cannot read the git history of {root}: {error}") from None
    return done.stdout


def _commits(root: Path, path: str) -> list[tuple[str, int]]:
    """(commit, commit time) of every commit that touched `path`, oldest first."""
    out = _git(root, "log", "--reverse", "--format=%H %ct", "--", path)
    return [(line.split()[0][:12], int(line.split()[1])) for line in out.splitlines() if line]


def _show(root: Path, commit: str, path: str) -> str | None:
    try:
        return _git(root, "show", f"{commit}:{path}")
    except ProvenanceError:
        return None  # not in that commit


def _claims_at(text: str) -> dict[str, tuple[tuple[Any, ...], tuple[Any, ...]]]:
    """Each claim's identity and its margin's identity in one version of a spec file."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return {}
    thesis = {
        (v.get("metric"), v.get("arm"), v.get("condition") or ""): v.get("value")
        for v in data.get("thesis", [])
    }
    out = {}
    for c in data.get("comparisons", []):
        condition = c.get("condition") or ""
        side_a = (c.get("metric"), c.get("a"), condition)
        side_b = (
            c.get("metric_b") or c.get("metric"),
            c.get("b"),
            c.get("condition_b") or condition,
        )
        claim = (*side_a, *side_b, c.get("direction"))
        margin = (
            c.get("margin"),
            c.get("margin_form", "absolute"),
            thesis.get(side_a),
            thesis.get(side_b),
        )
        out[c["name"]] = (claim, margin)
    return out


def _declared_at(root: Path, spec_path: str) -> dict[str, tuple[str, int, str, int]]:
    """Per claim of the spec today: (claim commit, date, margin commit, date), each the first
    commit from which it stood unchanged."""
    history = []
    for commit, date in _commits(root, spec_path):
        text = _show(root, commit, spec_path)
        history.append((commit, date, _claims_at(text) if text is not None else {}))
    if not history:
        return {}
    today = history[-1][2]
    out = {}
    for name, (claim, margin) in today.items():
        since = {0: history[-1][:2], 1: history[-1][:2]}
        for part, value in ((0, claim), (1, margin)):
            for commit, date, claims in reversed(history):
                if claims.get(name, (None, None))[part] != value:
                    break
                since[part] = (commit, date)
        out[name] = (*since[0], *since[1])
    return out


def _sides_in_values(text: str) -> set[tuple[str, str, str]]:
    rows = csv.DictReader(io.StringIO(text))
    return {
        (r["metric"], r["arm"], r["condition"]) for r in rows if r.get("value") not in ("", "nan")
    }


def _sides_in_report(text: str) -> set[tuple[str, str, str]]:
    """The sides a report.json showed values of (before values.csv existed)."""
    try:
        report = json.loads(text)
    except json.JSONDecodeError:
        return set()
    out = set()
    for c in report.get("comparisons", []):
        condition = c.get("condition") or ""
        out.add((c.get("metric"), c.get("a", {}).get("name"), condition))
        out.add((c.get("metric_b") or c.get("metric"), c.get("b", {}).get("name"),
                 c.get("condition_b") or condition))  # fmt: skip
    return out


def _data_seen(root: Path, folder: str) -> list[tuple[str, int, set[tuple[str, str, str]]]]:
    """(commit, time, sides with values) of every commit of a report folder, oldest first."""
    seen: list[tuple[str, int, set[tuple[str, str, str]]]] = []
    for commit, date in _commits(root, folder):
        sides: set[tuple[str, str, str]] = set()
        values = _show(root, commit, f"{folder}/values.csv")
        if values is not None:
            sides |= _sides_in_values(values)
        report = _show(root, commit, f"{folder}/report.json")
        if report is not None:
            sides |= _sides_in_report(report)
        seen.append((commit, date, sides | (seen[-1][2] if seen else set())))
    return seen


def read_history(root: str | Path, names: Iterable[str]) -> dict[str, dict[str, Any]]:
    """Every claim's provenance per experiment and scale, from the git history at `root`.

    Returns:
        {experiment: {"claims": {claim: Declared as a dict}, per scale with a report}} as
        `{"name": {"scale": {"claim": {...}}}}`.
    """
    root = Path(root)
    if _git(root, "rev-parse", "--is-shallow-repository").strip() == "true":
        raise ProvenanceError(f"{root} is a shallow clone: its history is cut")
    out: dict[str, dict[str, Any]] = {}
    for name in sorted(names):
        declared = _declared_at(root, f"{SHIPPED_DIR}/{name}.toml")
        today = _claims_at(_show(root, "HEAD", f"{SHIPPED_DIR}/{name}.toml") or "")
        scales = {"": None} | {
            p.name.removeprefix(f"{name}-"): p
            for p in sorted((root / REPORTS_DIR).glob(f"{name}-*"))
            if p.is_dir() and p.name.removeprefix(f"{name}-") in ("smoke", "small", "thesis")
        }
        per_scale: dict[str, Any] = {}
        for scale, folder in scales.items():
            seen = _data_seen(root, f"{REPORTS_DIR}/{folder.name}") if folder else []
            claims = {}
            for claim, (claim_commit, claim_date, margin_commit, margin_date) in declared.items():
                identity = today[claim][0]
                sides = {identity[:3], identity[3:6]}
                first = next(((c, d) for c, d, s in seen if sides <= s), (None, None))
                claims[claim] = asdict(
                    Declared(claim_commit, claim_date, margin_commit, margin_date, *first)
                )
            per_scale[scale or "unrun"] = claims
        out[name] = per_scale
    return out


# --- the committed file ----------------------------------------------------------------------


def write_file(root: str | Path, names: Iterable[str]) -> Path:
    """Rewrite `app/experiments/provenance.json` from the history at `root`."""
    path = Path(root) / "app" / "experiments" / FILE
    path.write_text(json.dumps(read_history(root, names), indent=1, sort_keys=True) + "\n")
    return path


def load() -> dict[str, dict[str, Any]]:
    """The committed provenance of the shipped experiments ({} when the file is absent)."""
    try:
        text = resources.files("app.experiments").joinpath(FILE).read_text()
    except (FileNotFoundError, OSError):
        return {}
    return json.loads(text)


def declared(name: str, scale: str, claim: str) -> Declared | None:
    """A shipped claim's provenance at a scale (its unrun entry where no report is
    committed at that scale), None for a claim the history does not know (a user's spec)."""
    per_scale = load().get(name, {})
    entry = (per_scale.get(scale) or per_scale.get("unrun") or {}).get(claim)
    return Declared(**entry) if entry else None
