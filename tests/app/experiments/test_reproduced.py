"""The 'thesis, reproduced' page: written from the committed reports, hand-written text kept."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from app.experiments import planning
from app.experiments.questions import load_questions
from app.experiments.reproduced import (
    SECTIONS,
    begin,
    end,
    load_reports,
    new_page,
    sections,
    spent,
    write_page,
    written,
)
from app.experiments.spec import ExperimentError
from app.experiments.spec_loading import load_shipped, shipped_names

DOCS = Path(__file__).resolve().parents[3] / "docs" / "experiments"
REPORT = DOCS / "ch3-bs-rl-small" / "report.json"


def test_the_committed_page_agrees_with_the_committed_reports() -> None:
    page = (DOCS / "README.md").read_text()
    expected = {name: "\n" + text for name, text in sections(DOCS).items()}
    assert written(page) == expected, "run: gnp-lab experiment reproduced"


def test_every_committed_report_folder_has_its_per_run_values() -> None:
    for folder in {p.parent for p in DOCS.glob("*/report.json")}:
        header = (folder / "values.csv").read_text().splitlines()[0]
        assert header == "arm,seed,condition,metric,value"


def _copy_report(folder: Path, edit: dict[str, object] | None = None) -> dict[str, object]:
    report = json.loads(REPORT.read_text())
    report.update(edit or {})
    (folder / "ch3-bs-rl-small").mkdir(parents=True)
    (folder / "ch3-bs-rl-small" / "report.json").write_text(json.dumps(report))
    shutil.copy(REPORT.parent / "values.csv", folder / "ch3-bs-rl-small")
    return report


def test_rewriting_keeps_the_hand_written_text_and_lists_each_claim(tmp_path: Path) -> None:
    report = _copy_report(tmp_path)
    marked = "".join(f"{begin(s)}\nold {s}\n{end(s)}\nwhy {s}\n" for s in SECTIONS)
    (tmp_path / "README.md").write_text(f"# Title\n\nintro\n{marked}")
    page = write_page(tmp_path).read_text()
    assert page.startswith("# Title\n\nintro\n" + begin("answers"))
    for section in SECTIONS:  # every hand-written paragraph kept, in place; the old text gone
        assert f"{end(section)}\nwhy {section}\n" in page
        assert f"old {section}" not in page
    comparisons = report["comparisons"]
    assert isinstance(comparisons, list)
    questions, sanity = written(page)["questions"], written(page)["sanity"]
    for comparison in comparisons:  # a row per claim, our means as the report has them
        claim = f"| {comparison['claim']} |"
        section = questions if comparison["kind"] == "question" else sanity
        row = next(line for line in section.splitlines() if line.startswith(claim))
        if comparison["a"]["mean"] is None:  # a claim added after the report's runs
            assert f"not run | **{comparison['verdict']}** (not run)" in row
            continue
        assert f"{comparison['a']['mean']:.3f} vs {comparison['b']['mean']:.3f}" in row
        runs = comparison["runs"]
        late = ", post hoc" if comparison["post_hoc"] else ""
        assert f"**{comparison['verdict']}**{late} ({runs[0]}" in row
    assert "Not run yet" in page  # the experiments without a report are named, not dropped


def test_an_undecided_claim_shows_the_seeds_it_would_need(tmp_path: Path) -> None:
    report = json.loads(REPORT.read_text())
    first, second = report["comparisons"][:2]
    first.update(verdict="reversed", runs=[10, 9], need=None, post_hoc=False)
    need = dict(power=0.8, seeds_per_arm_at_thesis_effect=123.0)
    margin = dict(second["margin"], basis="thesis")
    second.update(verdict="undecided", runs=[10, 10], need=need, margin=margin, post_hoc=False)
    _copy_report(tmp_path, {"comparisons": [first, second]})
    page = write_page(tmp_path).read_text()
    assert "**reversed** (10 + 9 runs) |" in page
    assert (
        "**undecided** (10 + 10 runs; 80% power at the thesis's printed effect: 123 seeds" in page
    )
    # A post hoc verdict says so, and a margin that is the smallest effect of interest is named.
    first.update(post_hoc=True)
    second.update(
        margin=dict(second["margin"], basis="declared", source="smallest effect of interest")
    )
    _copy_report(tmp_path / "again", {"comparisons": [first, second]})
    page = write_page(tmp_path / "again").read_text()
    assert "**reversed**, post hoc (10 + 9 runs) |" in page
    assert "80% power at the smallest effect of interest: 123 seeds" in page


def test_claims_are_matched_by_name_across_scales(tmp_path: Path) -> None:
    small = _copy_report(tmp_path)
    thesis = json.loads(REPORT.read_text())
    comparisons = thesis["comparisons"]
    extra = dict(comparisons[0], name="added-later", claim="A claim added after small ran")
    thesis.update(scale="thesis", comparisons=[extra, *reversed(comparisons)])
    (tmp_path / "ch3-bs-rl-thesis").mkdir()
    (tmp_path / "ch3-bs-rl-thesis" / "report.json").write_text(json.dumps(thesis))
    shutil.copy(REPORT.parent / "values.csv", tmp_path / "ch3-bs-rl-thesis")
    questions = written(write_page(tmp_path).read_text())["questions"]
    section = questions.split("### ch3-bs-rl")[1].split("###")[0]
    rows = [line.removesuffix(" |") for line in section.splitlines() if line.startswith("| ")]
    claims = [row.split(" | ")[0].removeprefix("| ") for row in rows[1:]]
    assert isinstance(small["comparisons"], list)
    asked = [c["claim"] for c in small["comparisons"] if c["kind"] == "question"]
    assert claims == [*asked, extra["claim"]]
    for row in rows[1:-1]:  # the same claim at both scales: the same numbers twice
        cells = row.split(" | ")
        assert cells[2] == cells[4] and cells[3] == cells[5]
    last, first = rows[-1].split(" | "), rows[1].split(" | ")
    assert last[2:4] == ["—", "not in the small report"] and last[4:] == first[4:]


def test_a_new_page_gets_a_title_and_the_markers(tmp_path: Path) -> None:
    _copy_report(tmp_path)
    page = write_page(tmp_path).read_text()
    assert page.startswith("# The thesis, reproduced")
    assert list(written(page)) == list(SECTIONS)
    assert written(new_page()) == dict.fromkeys(SECTIONS, "\n")


@pytest.mark.parametrize(
    "setup, message",
    [
        (lambda d: (d / "x").mkdir() or (d / "x" / "report.json").write_text("{"), "not an"),
        (lambda d: _rename(d), "rename its folder"),
        (lambda d: (d / "README.md").write_text(new_page().replace(end("spent"), "")), "'spent'"),
        (lambda d: (d / "README.md").write_text(_swapped()), "in the order"),
    ],
)
def test_bad_pages_and_reports_are_named_and_nothing_is_written(
    tmp_path: Path, setup: object, message: str
) -> None:
    assert callable(setup)
    setup(tmp_path)
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    with pytest.raises(ExperimentError, match=message):
        write_page(tmp_path)
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before


def _swapped() -> str:
    """A page whose first two sections come in the wrong order."""
    first, second = list(SECTIONS)[:2]
    block = {s: f"{begin(s)}\n{end(s)}" for s in (first, second)}
    page = new_page().replace(block[first], "FIRST").replace(block[second], block[first])
    return page.replace("FIRST", block[second])


def _rename(folder: Path) -> None:
    _copy_report(folder)
    shutil.move(folder / "ch3-bs-rl-small", folder / "ch3-bs-rl-thesis")


def test_reports_are_keyed_by_experiment_and_scale() -> None:
    assert ("ch3-bs-rl", "small") in load_reports(DOCS)


@pytest.mark.parametrize("name", shipped_names())
def test_the_stated_work_is_what_the_planned_runs_step(name: str, tmp_path: Path) -> None:
    spec = load_shipped(name)
    for scale in spec.scales:
        tasks = planning.plan(spec, scale, tmp_path)
        cost = planning.work(spec, scale)
        assert cost.runs == len(tasks)
        trained = sum(t.config.training.generations * t.generation_cost for t in tasks)
        assert cost.robot_steps == trained
        assert cost.trial_steps == sum(len(t.conditions) * t.condition_cost for t in tasks)


def test_every_question_names_claims_its_experiment_declares() -> None:
    questions = load_questions()
    assert len({q.text for q in questions}) == len(questions)
    for question in questions:
        names = [c.name for c in load_shipped(question.experiment).comparisons]
        assert question.claim in names and set(question.also) <= set(names)
        assert question.claim not in question.also


def test_a_question_takes_its_answering_claims_verdict_and_tallies_the_rest(
    tmp_path: Path,
) -> None:
    report = json.loads(REPORT.read_text())
    by_name = {c["name"]: c for c in report["comparisons"]}
    by_name["after-1-sensor"].update(verdict="reversed", post_hoc=False)
    for name, verdict in (("after-2-sensors", "held"), ("after-3-sensors", "ruled out")):
        by_name[name].update(verdict=verdict, post_hoc=False)
    by_name["after-4-sensors"].update(verdict="ruled out", post_hoc=True)
    _copy_report(tmp_path, {"comparisons": list(by_name.values())})
    page = write_page(tmp_path).read_text()
    row = next(line for line in page.splitlines() if "`after-1-sensor`" in line)
    cells = row.split(" | ")
    runs = by_name["after-1-sensor"]["runs"]
    assert cells[2] == f"**reversed** ({runs[0]} + {runs[1]} runs)"
    assert cells[3] == "—"  # no thesis-scale report in this folder
    # the decisive experiment asks it too, without a report in this folder
    assert cells[4] == "running: ch3-bs-rl-decisive, no look yet (primary)"
    assert cells[6] == "1 held, 1 ruled out, 1 undecided; post hoc: 1 ruled out |"
    fifth = next(line for line in page.splitlines() if "`training-fitness-CS-BS`" in line)
    assert fifth.split(" | ")[2:4] == ["not run", "—"]  # ch5 has no report here


def test_every_committed_reports_metric_labels_are_todays() -> None:
    """A label that changed (fault_effect's) is changed in every committed report too: the
    page's claim sentences are built from it."""
    from app.experiments.results import METRICS

    labels = {name: metric.label for name, metric in METRICS.items()}
    for (name, scale), report in load_reports(DOCS).items():
        for c in report["comparisons"]:
            assert c["metric_label"] == labels[c["metric"]], (name, scale, c["name"])


def test_the_compute_spent_counts_the_runs_and_conditions_that_have_values(tmp_path: Path) -> None:
    folder = tmp_path / "ch3-bs-rl-small"
    folder.mkdir()
    rows = [
        "arm,seed,condition,metric,value",
        "BS,0,,final_best_fitness,0.5",
        "BS,0,no-fault,mean_reward,0.4",
        "BS,0,break-1,mean_reward,0.3",
        "RL,0,,final_best_fitness,0.5",
        "RL,0,no-fault,mean_reward,nan",  # the control never ran for RL: not paid
        "RL,0,break-1,mean_reward,0.2",
        "RL,1,,final_best_fitness,nan",  # a seed that never ran
    ]
    (folder / "values.csv").write_text("\n".join(rows) + "\n")
    runs, robot, trials = spent(folder, load_shipped("ch3-bs-rl"), "small")
    # small: 100 generations x 300 individuals x 1000 steps a run; a condition is 10 start
    # poses x 30 trials x 3000 steps.
    assert (runs, robot, trials) == (2, 2 * 100 * 300 * 1000, 3 * 10 * 30 * 3000)


def test_a_report_without_its_values_is_refused(tmp_path: Path) -> None:
    _copy_report(tmp_path)
    (tmp_path / "ch3-bs-rl-small" / "values.csv").unlink()
    with pytest.raises(ExperimentError, match=r"no values\.csv"):
        load_reports(tmp_path)
