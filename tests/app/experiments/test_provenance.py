"""Provenance of claims and margins, read from a repository's history (issue #30)."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from app.experiments import provenance
from app.experiments.report import post_hoc
from app.experiments.results import Comparison
from app.experiments.sequential import ClaimVerdict, Interval
from app.experiments.spec_loading import shipped_names

ROOT = Path(__file__).resolve().parents[3]

SPEC = """
name = "toy"
[[comparisons]]
name = "x"
a = "A"
b = "B"
metric = "mean_reward"
condition = "c"
direction = "greater"
margin = {margin}
{extra}
"""
CLAIM_Y = """
[[comparisons]]
name = "y"
a = "A"
b = "B"
metric = "final_best_fitness"
direction = "greater"
"""
VALUES = "arm,seed,condition,metric,value\n" + "".join(
    f"{arm},0,{condition},{metric},0.5\n"
    for arm in "AB"
    for condition, metric in (("c", "mean_reward"), ("", "final_best_fitness"))
)


def _git(repo: Path, *args: str, when: int = 0) -> str:
    dates = {"GIT_COMMITTER_DATE": f"{when} +0000", "GIT_AUTHOR_DATE": f"{when} +0000"}
    done = subprocess.run(
        ["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
        cwd=repo,
        env={**os.environ, **dates},
        check=True,
        capture_output=True,
        text=True,
    )
    return done.stdout.strip()


def _commit(repo: Path, files: dict[str, str], when: int) -> str:
    for path, text in files.items():
        (repo / path).parent.mkdir(parents=True, exist_ok=True)
        (repo / path).write_text(text)
    _git(repo, "add", "-A")
    _git(repo, "commit", "-qm", "step", when=when)
    return _git(repo, "rev-parse", "HEAD")[:12]


def test_a_claim_or_margin_declared_after_its_data_is_post_hoc(tmp_path: Path) -> None:
    subprocess.run(["git", "init", "-q", str(tmp_path)], check=True)
    spec = "app/experiments/shipped/toy.toml"
    values = "docs/experiments/toy-small/values.csv"
    declared = _commit(tmp_path, {spec: SPEC.format(margin=0.02, extra="")}, 1_700_001_000)
    data = _commit(tmp_path, {values: VALUES}, 1_700_002_000)
    # After the data: x's margin changes, y is added, and an unrelated edit keeps x's claim.
    _commit(tmp_path, {spec: SPEC.format(margin=0.05, extra=CLAIM_Y)}, 1_700_003_000)
    late = _commit(
        tmp_path, {spec: "# a comment\n" + SPEC.format(margin=0.05, extra=CLAIM_Y)}, 1_700_004_000
    )
    history = provenance.read_history(tmp_path, ["toy"])["toy"]
    x, y = (provenance.Declared(**history["small"][name]) for name in ("x", "y"))
    assert (x.claim_commit, x.data_commit, y.data_commit) == (declared, data, data)
    assert x.claim_first and not x.margin_first  # margin 0.05 came at 3000 s, after the data
    assert x.margin_date == 1_700_003_000 and late not in (x.claim_commit, x.margin_commit)
    assert not y.claim_first and not y.margin_first
    unrun = provenance.Declared(**history["unrun"]["x"])
    assert unrun.data_commit is None and unrun.claim_first and unrun.margin_first


def test_a_shallow_clone_is_refused_in_one_line(tmp_path: Path) -> None:
    subprocess.run(["git", "init", "-q", str(tmp_path / "src")], check=True)
    _commit(tmp_path / "src", {"a.txt": "1"}, 1_700_001_000)
    _commit(tmp_path / "src", {"a.txt": "2"}, 1_700_002_000)
    subprocess.run(
        ["git", "clone", "-q", "--depth", "1", f"file://{tmp_path / 'src'}", str(tmp_path / "c")],
        check=True,
    )
    with pytest.raises(provenance.ProvenanceError, match="shallow"):
        provenance.read_history(tmp_path / "c", [])


def test_the_committed_provenance_is_the_history_of_this_checkout() -> None:
    committed = json.loads((ROOT / "app" / "experiments" / "provenance.json").read_text())
    assert committed == provenance.read_history(ROOT, shipped_names()), (
        "run: gnp-lab experiment provenance (after committing the spec or report), then commit"
    )


def _verdict(verdict: str, low: float, high: float) -> ClaimVerdict:
    return ClaimVerdict(verdict, Interval(0.0, low, high, 10, 10, 0.1), 0.05, 0, 0.05)  # type: ignore[arg-type]


def test_a_verdict_is_post_hoc_when_what_it_rests_on_came_after_the_data() -> None:
    claim = Comparison("c", "A", "B", "mean_reward", "x", "greater", "Fig. 1", margin=0.05)
    before, after = 1_700_000_000, 1_800_000_000
    first = provenance.Declared("c1", before, "m1", before, "d1", before + 1)
    late_claim = provenance.Declared("c1", after, "m1", before, "d1", before + 1)
    late_margin = provenance.Declared("c1", before, "m1", after, "d1", before + 1)
    held, ruled_out = _verdict("held", 0.01, 0.2), _verdict("ruled out", -0.2, 0.03)
    assert post_hoc(claim, held, first, 0.05) is False
    assert post_hoc(claim, held, late_claim, 0.05) is True
    assert post_hoc(claim, held, late_margin, 0.05) is False  # a held does not rest on it
    assert post_hoc(claim, ruled_out, late_margin, 0.05) is True
    assert post_hoc(claim, ruled_out, first, 0.05) is False  # 0.03 < the declared 0.05 too
    assert post_hoc(claim, ruled_out, first, 0.02) is True  # only today's rule rules it out
    assert post_hoc(claim, _verdict("exploratory", -1, 1), first, 0.05) is None
    assert post_hoc(claim, held, None, 0.05) is None  # a claim the history does not know
