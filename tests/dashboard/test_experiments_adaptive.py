"""The Experiments tab's adaptive runs without a browser: the Start control's stage sizes
checked as `run_adaptive` checks them, an adaptive job on an in-process Dask cluster, the
stages table of its looks and the verdict tables split into questions and sanity claims.

The experiment has two arms of one config, so every seed gives both the same values and Δ = 0
between them exactly: "open" (no margin) can decide nothing and runs to the last look, "far"
(margin 1000, far beyond any tiny run's fitness) is ruled out at the first look.
"""

from __future__ import annotations

import re
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from experiment_fixtures import copies_toml, in_process_client
from page_helpers import dashboard_in_process, until_tab

from app.dashboard import experiment_view as ev
from app.dashboard.controls import DashboardInputError
from app.dashboard.experiment_job import DaskCluster, ExperimentJob
from app.dashboard.experiment_verdicts import AdaptiveRequest, badge, claim_row, seed_count, whole
from app.experiments import layout
from app.experiments.adaptive import DEFAULT_MAX_SEEDS, DEFAULT_STAGE_SEEDS
from app.experiments.report import analyse
from app.experiments.report_text import format_number
from app.experiments.results import VERDICT_COLOURS, VERDICTS
from app.experiments.sequential import Design
from app.experiments.spec import ExperimentSpec
from app.experiments.spec_loading import load_file
from app.experiments.summary import read_summary

SCALE, STAGE, MOST = "smoke", 2, 4
TWINS_TOML = copies_toml(
    "twins",
    "XY",
    """
[[comparisons]]
name = "open"
a = "X"
b = "Y"
metric = "final_best_fitness"
direction = "greater"
source = "tests"

[[comparisons]]
name = "far"
a = "X"
b = "Y"
metric = "mean_reward"
condition = "calm"
direction = "greater"
source = "tests"
margin = 0.5  # reachable: a smoke run earns about 0.1-0.2 reward per step
margin_source = "half the reward scale: far above what these twins differ by"

[[comparisons]]
name = "X-calm-above-break"
a = "X"
b = "X"
metric = "mean_reward"
condition = "calm"
condition_b = "break-1"
direction = "greater"
source = "tests"
""",
)


class InProcessCluster(DaskCluster):
    """The dashboard's cluster, but a Dask client in this process (no worker processes)."""

    def client(self) -> Any:
        with self._lock:
            if self._client is None:
                self._client = in_process_client()
            return self._client

    def close(self) -> None:
        with self._lock:
            client, self._client = self._client, None
        if client is not None:
            client.close()


@pytest.fixture(scope="module")
def spec(tmp_path_factory: pytest.TempPathFactory) -> ExperimentSpec:
    path = tmp_path_factory.mktemp("spec") / "twins.toml"
    path.write_text(TWINS_TOML, encoding="utf-8")
    return load_file(path)


@pytest.fixture(scope="module")
def watched(
    spec: ExperimentSpec, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[ExperimentJob, set[int | None]]]:
    """The twins run adaptively by the dashboard's job, in stages of 2 seeds up to 4, and the
    stages (seeds per arm) its snapshots reported while it ran."""
    runs = tmp_path_factory.mktemp("runs")
    cluster = InProcessCluster()
    started = ExperimentJob(spec, SCALE, runs, cluster, Design.staged(STAGE, MOST))
    seen: set[int | None] = set()
    while started.active:
        seen.add(started.snapshot().seeds)
        started.join(0.05)
    seen.add(started.snapshot().seeds)  # the last stage's, kept once it ended
    yield started, seen
    cluster.close()


@pytest.fixture(scope="module")
def job(watched: tuple[ExperimentJob, set[int | None]]) -> ExperimentJob:
    return watched[0]


def test_the_start_control_checks_stage_sizes_as_run_adaptive_does() -> None:
    assert AdaptiveRequest().design() is None  # not ticked: all the scale's seeds at once
    default = AdaptiveRequest(True).design()
    assert default == Design.staged(DEFAULT_STAGE_SEEDS, DEFAULT_MAX_SEEDS)
    assert AdaptiveRequest(True, 2.0, 5.0).design() == Design((2, 4, 5))  # the last is smaller
    with pytest.raises(DashboardInputError, match=r"^adaptive: stages need at least 2 seeds"):
        AdaptiveRequest(True, 1, 4).design()
    with pytest.raises(DashboardInputError, match=r"^adaptive: .*\(6 per stage, 4 at most\)"):
        AdaptiveRequest(True, 6, 4).design()
    with pytest.raises(DashboardInputError, match=r"^stage seeds: .*fractional part \(got 2\.5\)"):
        AdaptiveRequest(True, 2.5, 4).design()
    with pytest.raises(DashboardInputError, match=r"^max seeds: .*less than or equal to 10000"):
        seed_count(10_001, "max seeds")  # an experiment's seed count has the same bound
    with pytest.raises(DashboardInputError, match=r"^max seeds: .*finite number"):
        seed_count(float("nan"), "max seeds")


def test_an_adaptive_job_runs_its_stages_and_reports_them(
    watched: tuple[ExperimentJob, set[int | None]],
) -> None:
    job, seen = watched
    snapshot = job.snapshot()
    assert snapshot.phase == "finished", snapshot.detail
    assert snapshot.detail == "summary written after 2 look(s), 4 seeds per arm"
    # "open" compares identical arms without a margin: never decided, so both stages run.
    assert [(s.seeds, s.arms) for s in job.stages] == [(2, ("X", "Y")), (4, ("X", "Y"))]
    assert "open" in job.stages[-1].open_claims and "far" not in job.stages[0].open_claims
    assert {2, 4} <= seen  # each stage's seeds, in the snapshots while it ran
    assert snapshot.outcomes[-1] == "after 4 seeds per arm: 1 claim(s) decided, 2 open"
    assert job.cluster.started  # the runs needed it, so the first stage started it
    files = sorted(p.stem for p in (job.runs_dir / "experiments" / "twins" / SCALE).glob("*.h5"))
    assert files == [f"{arm}-seed{k}" for arm in "XY" for k in range(MOST)]


def test_the_stages_table_shows_each_look(job: Any, spec: ExperimentSpec) -> None:
    view = ev.build_view(ev.Entry("twins", spec), SCALE, job.runs_dir)
    lines = view.stages.splitlines()
    assert lines[0] == ("**Stages** (adaptive: 2 of 2 looks made; planned at 2, 4 seeds per arm)")
    rows = [line for line in lines if line.startswith("| ")]
    assert rows[0] == "| look | seeds | runs | decided | open |"
    first = [cell.strip() for cell in rows[1].strip("| ").split(" | ")]
    second = [cell.strip() for cell in rows[2].strip("| ").split(" | ")]
    assert first[:3] == ["1", "2", f"{whole('X 2')} · {whole('Y 2')}"]
    assert second[:3] == ["2", "4", f"{whole('X 4')} · {whole('Y 4')}"]
    assert "far (ruled out)" in first[3] and f"1 {badge('ruled out')}" in first[3]
    # "far" is decided at the first look; "open" and the sanity claim stay open to the end.
    assert first[4] == second[4] == "2" and second[3] == "–"


def test_the_verdict_tables_split_questions_and_sanity_claims(
    job: Any, spec: ExperimentSpec
) -> None:
    view = ev.build_view(ev.Entry("twins", spec), SCALE, job.runs_dir)
    report = analyse(read_summary(layout.summary_path(job.runs_dir, "twins", SCALE)))
    questions, sanity = view.verdicts.split("**Within one arm (sanity)** (1)")
    assert questions.startswith("**The thesis's questions** (2)")
    by_name = {c.comparison.name: c for c in report.comparisons}
    far, still = by_name["far"], by_name["open"]
    assert far.claim.verdict == "ruled out" and far.claim.runs == (2, 2)  # at the first look
    assert still.claim.verdict == "undecided" and still.claim.runs == (4, 4)  # the last look
    for name, table in (("far", questions), ("open", questions), ("X-calm-above-break", sanity)):
        row = "| " + " | ".join(claim_row(by_name[name])) + " |"
        assert row in table.splitlines(), name
    # The cells, by hand: the claim over Δ with its interval, the runs, the coloured verdict.
    iv = far.claim.judged.interval
    cells = claim_row(far)
    delta = f"{format_number(iv.difference)} [{format_number(iv.low)}, {format_number(iv.high)}]"
    assert cells[0].startswith('<span title="') and ">far</span><br>" in cells[0]
    assert cells[0].endswith(f"<br><small>{whole(delta)}</small>")
    assert iv.difference == 0.0 and iv.high < 0.5  # twins: Δ = 0, and the margin excluded
    assert cells[1] == whole("2, 2") and cells[2] == badge("ruled out")
    # Undecided, without a margin: no effect to power for, so the seeds needed are "–".
    assert claim_row(still)[2] == badge("undecided") + f"<br><small>{whole('need –')}</small>"
    assert still.claim.need is not None


def test_a_verdict_is_marked_in_the_reports_colours() -> None:
    for verdict in VERDICTS:
        background, text = VERDICT_COLOURS[verdict]
        label = badge(verdict)
        assert f"background:{background};color:{text}" in label
        assert re.fullmatch(rf"<span style=\"[^\"]+\">{verdict}</span>", label)


def test_a_live_adaptive_view_shows_the_looks_made_so_far(job: Any, spec: ExperimentSpec) -> None:
    summary = layout.summary_path(job.runs_dir, "twins", SCALE)
    written = summary.stat().st_mtime
    live = ev.build_view(ev.Entry("twins", spec), SCALE, job.runs_dir, True, 2, written - 1)
    assert live.verdicts.startswith("Verdicts so far (the last look made):")
    assert "**Stages** (adaptive: 2 of 2 looks made" in live.stages
    assert [line.label for line in live.fitness.lines] == ["X (n = 2)", "Y (n = 2)"]  # seeds 0-1
    # A summary older than the job (an earlier run's) is not the job's: no verdicts yet.
    stale = ev.build_view(ev.Entry("twins", spec), SCALE, job.runs_dir, True, 2, written + 60)
    assert "when the experiment finishes" in stale.verdicts and stale.stages == ""


def test_a_run_that_is_not_adaptive_has_one_look(job: Any) -> None:
    results = read_summary(layout.summary_path(job.runs_dir, "twins", SCALE))
    one_look = type(results)(**{**results.__dict__, "looks": ()})
    _, stages = ev.verdicts_and_stages(one_look)
    assert stages == "**Stages**: one look at 4 seeds per arm (not adaptive)."


# --- the tab on a real (browserless) viser server --------------------------------------------


@pytest.fixture
def dashboard(job: Any, tmp_path: Path) -> Iterator[Any]:
    """The dashboard on a copy of the twins' finished runs, kept as a saved experiment (its
    folder keeps its file, so the tab can start it)."""
    runs = tmp_path / "runs"
    shutil.copytree(job.runs_dir, runs)
    layout.keep_definition(runs, "twins", TWINS_TOML)
    with dashboard_in_process(runs) as board:
        board.experiments.cluster = InProcessCluster()
        yield board


def start(board: Any, adaptive: bool, stage: float, most: float) -> None:
    tab = board.experiments
    until_tab(board, lambda: "twins" in tab.entries)
    with board.lock:
        tab.experiment.value, tab.scale.value = "twins", SCALE
        tab.adaptive.value, tab.stage_seeds.value, tab.max_seeds.value = adaptive, stage, most
    board.status.guarded(None, tab.start)


def test_the_tab_offers_the_adaptive_defaults(dashboard: Any) -> None:
    tab = dashboard.experiments
    assert tab.adaptive.value is False
    assert (tab.stage_seeds.value, tab.max_seeds.value) == (DEFAULT_STAGE_SEEDS, DEFAULT_MAX_SEEDS)


@pytest.mark.parametrize(
    ("stage", "most", "message"),
    [
        (1, 4, "⚠ adaptive: stages need at least 2 seeds each"),
        (3, 2, "⚠ adaptive: stages need at least 2 seeds each and at most"),
        (0, 4, "⚠ stage seeds: Input should be greater than or equal to 1 (got 0)"),
        (2, 20_000, "⚠ max seeds: Input should be less than or equal to 10000"),
    ],
)
def test_bad_stage_sizes_are_refused(
    dashboard: Any, stage: float, most: float, message: str
) -> None:
    start(dashboard, True, stage, most)
    assert dashboard.status.text.startswith(message)
    assert dashboard.experiments.job is None


def test_an_adaptive_rerun_from_the_tab_shows_its_stages_and_verdicts(dashboard: Any) -> None:
    tab = dashboard.experiments
    start(dashboard, True, STAGE, MOST)
    assert dashboard.status.text == (
        "experiment twins at smoke started adaptively (looks at (2, 4) seeds per arm)"
    )
    until_tab(dashboard, lambda: tab.job.reported)
    assert dashboard.status.text == "experiment twins at smoke finished"
    assert "finished: summary written after 2 look(s), 4 seeds per arm" in (
        tab.progress_text.content
    )
    assert not tab.cluster.started  # every run of every look was done: no cluster needed
    until_tab(dashboard, lambda: "**Stages** (adaptive: 2 of 2 looks made" in tab.stages.content)
    until_tab(dashboard, lambda: "**The thesis's questions** (2)" in tab.verdicts.content)
    assert f"| {whole('2, 2')} | {badge('ruled out')} |" in tab.verdicts.content  # "far", at look 1
