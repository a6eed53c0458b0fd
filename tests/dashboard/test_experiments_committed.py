"""The committed reports as the Experiments tab reads them (`committed`) and writes them
(`committed_view`), without a server. Expected numbers are read by hand from the committed
report.json files (docs/experiments/NAME-SCALE/)."""

from __future__ import annotations

import json
import os
import shutil
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from app.dashboard import committed_view as cv
from app.dashboard.committed import (
    DOCS,
    CommittedError,
    Shelf,
    read_report,
    read_shelf,
)
from app.experiments.questions import load_questions

DECISIVE = "ch5-cs-bs-rl-decisive-thesis"


@pytest.fixture(scope="module")
def shelf() -> Shelf:
    return read_shelf()


def test_every_committed_report_is_read(shelf: Shelf) -> None:
    folders = sorted(p.parent.name for p in DOCS.glob("*/report.json"))
    assert len(folders) >= 15
    assert [r.name for r in shelf.reports] == folders
    assert shelf.problems == () and shelf.missing == ""


def test_a_decisive_claim_as_its_report_has_it(shelf: Shelf) -> None:
    report = shelf.find(DECISIVE)
    assert report is not None and report.report.scale == "thesis"
    assert report.report.looks_made == (25, 50, 75, 100)
    claim = report.claim("after-1-sensor-CS-BS")
    # By hand from report.json: reversed at look 2 on 50 + 50 runs.
    assert (claim.verdict, claim.look, claim.runs, claim.family) == (
        "reversed",
        2,
        (50, 50),
        "primary",
    )
    assert claim.post_hoc is False and claim.kind == "question"
    assert claim.difference == pytest.approx(-0.09892414853040232)
    assert (claim.interval.low, claim.interval.high) == pytest.approx(
        (-0.17901880605079204, -0.018829491010012606)
    )
    # Its runs from values.csv: the first 50 seeds of each arm, with the report's means.
    a, b = report.spread(claim)
    assert report.judged_seeds(claim) == tuple(range(2000, 2050))
    assert (a.size, b.size) == (50, 50)
    assert a.mean() == pytest.approx(0.3626762887137343)
    assert b.mean() == pytest.approx(0.46160043724413663)
    exploratory = report.claim("training-fitness-CS-BS")
    assert (exploratory.verdict, exploratory.family, exploratory.runs) == (
        "exploratory", "exploratory", (100, 75)
    )  # fmt: skip
    with pytest.raises(CommittedError, match="no claim 'nothing'"):
        report.claim("nothing")


def test_every_claims_runs_are_its_runs(shelf: Shelf) -> None:
    """Each claim's values (two arms, or one arm in two conditions) count its runs at its look
    and average to the report's means."""
    checked = 0
    for report in shelf.reports:
        for claim in report.report.comparisons:
            a, b = report.spread(claim)
            assert (a.size, b.size) == claim.runs, (report.name, claim.name)
            for values, side in zip((a, b), (claim.a, claim.b), strict=True):
                if values.size:
                    assert values.mean() == pytest.approx(side.mean), (report.name, claim.name)
            checked += 1
    assert checked > 200


def test_a_within_arm_claim_compares_two_conditions(shelf: Shelf) -> None:
    report = shelf.find("ch2-reward-source-small")
    claim = report.report.comparisons[0]
    assert claim.a.name == claim.b.name == "fuzzy-true"
    assert claim.value_keys() == (
        ("fuzzy-true", "sigma-50", "mean_reward"),
        ("fuzzy-true", "sigma-0", "mean_reward"),
    )
    assert claim.verdict == "ruled out"


def copy_report(root: Path, name: str = DECISIVE) -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    for file in ("report.json", "values.csv"):
        shutil.copy(DOCS / name / file, folder / file)
    return folder


@pytest.mark.parametrize(
    ("damage", "problem"),
    [
        (lambda f: (f / "report.json").write_text("{not json"), "report.json: cannot be read"),
        (lambda f: (f / "report.json").write_text("[" * 100_000), "nested 100000 deep"),
        (lambda f: (f / "report.json").unlink() or os.mkfifo(f / "report.json"), "regular file"),
        (lambda f: (f / "report.json").write_text('{"experiment": "x"}'), "is not a report"),
        (lambda f: (f / "values.csv").unlink(), "values.csv: cannot be read"),
        (lambda f: (f / "values.csv").write_text("a,b\n1,2\n"), "is not a values table"),
        (
            lambda f: (f / "values.csv").write_text(
                "arm,seed,condition,metric,value\nCS,x,,final_best_fitness,1\n"
            ),
            "line 2: not a row of values",
        ),
        (
            lambda f: (f / "values.csv").write_text(
                "arm,seed,condition,metric,value\nPPO,1,,final_best_fitness,1\n"
            ),
            "arm 'PPO' is not the report's",
        ),
        (
            lambda f: (f / "report.json").write_text(
                json.dumps({**json.loads((f / "report.json").read_text()), "scale": "huge"})
            ),
            "scale must be one of",
        ),
    ],
)
def test_a_damaged_report_is_a_problem_and_the_rest_go_on(
    tmp_path: Path, damage: object, problem: str
) -> None:
    copy_report(tmp_path, "ch2-reward-source-small")
    broken = copy_report(tmp_path)
    damage(broken)  # type: ignore[operator]
    shelf = read_shelf(tmp_path)
    assert [r.name for r in shelf.reports] == ["ch2-reward-source-small"]
    assert len(shelf.problems) == 1 and shelf.problems[0][0] == DECISIVE
    assert problem in shelf.problems[0][1]
    table = cv.reports_table(shelf)
    assert f"| ⚠ {DECISIVE} |" in table and "ch2-reward-source · small" in table


def test_a_report_in_another_folder_is_foreign(tmp_path: Path) -> None:
    folder = copy_report(tmp_path)
    moved = folder.rename(tmp_path / "ch5-cs-bs-rl-small")
    with pytest.raises(CommittedError, match="holds ch5-cs-bs-rl-decisive at thesis scale"):
        read_report(moved)


def test_no_checkout_says_so(tmp_path: Path) -> None:
    shelf = read_shelf(tmp_path / "absent")
    assert shelf.reports == () and "installed package" in shelf.missing
    assert cv.reports_table(shelf) == shelf.missing and cv.answers_table(shelf) == ""


def test_the_tables_and_the_picture(shelf: Shelf) -> None:
    reports = cv.reports_table(shelf, "http://127.0.0.1:1/")
    assert reports.count("\n") == 1 + len(shelf.reports)
    assert "| 2 held, 1 reversed, 1 undecided; 16 exploratory |" in reports
    assert f'href="http://127.0.0.1:1/{DECISIVE}/index.html"' in reports
    answers = cv.answers_table(shelf)
    assert answers.count("\n") == 1 + len(load_questions())
    row = next(line for line in answers.splitlines() if "CS earn more reward than BS" in line)
    assert row.endswith("| <small>—</small> | <small>**reversed** (50 + 50 runs)</small> |")
    report = shelf.find(DECISIVE)
    claims = cv.claims_tables(report)
    assert "**The thesis's questions** (4)" in claims and "(16)" in claims
    assert "-0.09892 [-0.179, -0.01883]" in claims and "thesis: CS &gt; BS" in claims
    assert "need 416" in claims  # after-1-sensor-CS-RL, undecided
    assert "docs/experiments/ch5-cs-bs-rl-decisive-thesis/index.html" in cv.header(report, "")
    claim = report.claim("after-1-sensor-CS-BS")
    image = cv.spread_image(report, claim)
    assert image.ndim == 3 and image.shape[2] == 4 and image.dtype == np.uint8
    assert "CS n = 50, BS n = 50" in cv.spread_caption(report, claim)


def test_thesis_values_are_shown_where_printed(shelf: Shelf) -> None:
    printed = [c for r in shelf.reports for c in r.report.comparisons if c.a.thesis and c.b.thesis]
    assert printed
    claim = printed[0]
    assert cv.thesis_cell(claim).startswith(f"thesis: {claim.side_names()[0]} ")


def test_the_pages_are_served(tmp_path: Path) -> None:
    (tmp_path / "x-small").mkdir()
    (tmp_path / "x-small" / "index.html").write_text("<p>the page</p>")
    server = cv.PageServer(tmp_path)
    try:
        assert server.url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(server.url + "x-small/index.html", timeout=10) as answer:
            assert answer.read() == b"<p>the page</p>"
    finally:
        server.close()


def test_the_reports_are_read_again_only_when_a_file_changed(tmp_path: Path) -> None:
    from app.dashboard.committed import shelf_signature
    from app.dashboard.tab_committed import read_once

    folder = copy_report(tmp_path, "ch2-reward-source-small")
    first = read_once(tmp_path)
    assert read_once(tmp_path) is first and len(first[0].reports) == 1
    before = shelf_signature(tmp_path)
    (folder / "values.csv").write_text("arm,seed,condition,metric,value\n")
    assert shelf_signature(tmp_path) != before
    shelf, _ = read_once(tmp_path)
    assert shelf.problems == () and shelf.reports[0].values == {}
