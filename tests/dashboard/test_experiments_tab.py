"""The Experiments tab without a browser: listing and status, the view of an experiment (curves,
verdicts, runs), refused actions and their messages, and run paths that stay in the runs dir.

The runs are ch3-bs-rl's at smoke scale, run in this process by the runner's own task function
(no Dask: the tab reads folders, whoever wrote them); the browser test starts one on Dask.
"""

from __future__ import annotations

import dataclasses
import re
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from page_helpers import dashboard_in_process, until_tab

from app import store
from app.dashboard import experiment_view as ev
from app.dashboard import tab_experiments
from app.dashboard.controls import DashboardInputError
from app.dashboard.experiment_job import DaskCluster, ExperimentJob, JobSnapshot
from app.dashboard.experiment_verdicts import badge, whole
from app.dashboard.plots import MAX_POINTS
from app.experiments import execution, harvest, layout, planning
from app.experiments.figures import mean_and_ci
from app.experiments.progress import Counts
from app.experiments.report import analyse
from app.experiments.report_text import format_number, interval_text
from app.experiments.results import VERDICTS
from app.experiments.spec import ExperimentSpec
from app.experiments.spec_loading import SHIPPED_PACKAGE, load_shipped
from app.experiments.summary import read_summary, write_summary

NAME, SCALE = "ch3-bs-rl", "smoke"
VERDICT = re.compile(
    r">(" + "|".join(VERDICTS) + r")</span>(<br><small><span [^>]+>need [^<]+</span></small>)? \|$",
    re.MULTILINE,
)


@pytest.fixture(scope="module")
def spec() -> ExperimentSpec:
    return load_shipped(NAME)


@pytest.fixture(scope="module")
def finished(spec: ExperimentSpec, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A runs dir holding ch3-bs-rl at smoke scale, every run done, and its summary."""
    runs = tmp_path_factory.mktemp("experiment-runs")
    for task in planning.plan(spec, SCALE, runs):
        execution.run_task(task)
    write_summary(harvest.collect(spec, SCALE, runs), layout.summary_path(runs, NAME, SCALE))
    return runs


@pytest.fixture
def runs(finished: Path, tmp_path: Path) -> Path:
    """A copy of the finished runs dir, to change."""
    shutil.copytree(finished, tmp_path / "runs")
    return tmp_path / "runs"


def save_other(runs: Path, name: str = "mine") -> None:
    """A saved experiment the dashboard has no file of: ch3's summary under another name,
    with BS seed 1's runs unfinished."""
    results = read_summary(layout.summary_path(runs, NAME, SCALE))
    scalars = dict(results.scalars)
    scalars[("final_best_fitness", "BS", "")] = np.array([0.5, np.nan])
    other = dataclasses.replace(results, name=name, scalars=scalars)
    write_summary(other, layout.summary_path(runs, name, SCALE))


def test_the_catalogue_lists_shipped_and_saved_experiments_with_runs_done(runs: Path) -> None:
    save_other(runs)
    (runs / "experiments" / ".hidden").mkdir()  # not an experiment name: not offered
    (runs / "experiments" / "notes.txt").write_text("not a folder")
    rows = ev.catalogue(runs, ev.shipped_specs())
    names = [entry.name for entry, _ in rows]
    assert names[-1] == "mine" and NAME in names and ".hidden" not in names
    table = ev.catalogue_table(rows)
    assert "| ch3-bs-rl | 4/4 | 0/20 | 0/20 |" in table
    assert "| ch2-fuzzy-crisp | 0/4 | 0/20 | 0/20 |" in table
    assert "| mine (saved) | 3/4 | – | – |" in table
    mine = dict((e.name, e) for e, _ in rows)["mine"]
    assert mine.spec is None and mine.scales(runs) == (SCALE,)


def test_a_saved_experiment_that_keeps_its_file_is_offered_with_it(
    runs: Path, spec: ExperimentSpec
) -> None:
    text = resources.files(SHIPPED_PACKAGE).joinpath(f"{NAME}.toml").read_text()
    layout.keep_definition(runs, "kept", text.replace(f'name = "{NAME}"', 'name = "kept"', 1))
    (runs / "experiments" / "broken").mkdir()
    (runs / "experiments" / "broken" / layout.DEFINITION).write_text("name = ")
    rows = ev.catalogue(runs, ev.shipped_specs())
    entries = {e.name: e for e, _ in rows}
    kept, broken = entries["kept"], entries["broken"]
    assert kept.spec is not None and not kept.shipped and not kept.problem
    assert kept.spec.comparisons == spec.comparisons and kept.scales(runs) == tuple(spec.scales)
    assert "| kept (saved) | 0/4 | 0/20 | 0/20 |" in ev.catalogue_table(rows)
    assert "**kept** (" in ev.about(kept, None) and "saved)" in ev.about(kept, None)
    assert broken.spec is None and "not valid TOML" in broken.problem


def test_a_foreign_run_file_is_reported_not_raised(runs: Path, spec: ExperimentSpec) -> None:
    folder = runs / "experiments" / NAME / SCALE
    shutil.copyfile(folder / "RL-seed0.h5", folder / "BS-seed0.h5")  # another arm's config
    entry = ev.Entry(NAME, spec)
    count = ev.scale_count(entry, SCALE, runs)
    assert count is not None and (count.done, count.problems) == (3, 1) and str(count) == "3/4 ⚠"
    view = ev.build_view(entry, SCALE, runs, live=True)
    assert any("BS-seed0.h5 holds a run with another config" in p for p in view.problems)
    job = ExperimentJob(spec, SCALE, runs, DaskCluster())
    job.join(120)
    snapshot = job.snapshot()
    assert snapshot.phase == "failed" and "another config" in snapshot.detail
    assert not job.cluster.started  # refused before any cluster was started


def test_the_view_of_a_finished_experiment(finished: Path, spec: ExperimentSpec) -> None:
    view = ev.build_view(ev.Entry(NAME, spec), SCALE, finished)
    results = read_summary(layout.summary_path(finished, NAME, SCALE))
    assert view.count == ev.ScaleCount(4, 4) and not view.problems
    assert view.runs == ("BS-seed0", "BS-seed1", "RL-seed0", "RL-seed1")
    # The verdict tables hold the report's own numbers and verdicts: questions, then sanity.
    report = analyse(results)
    rows = [line for line in view.verdicts.splitlines() if line.startswith("| <span")]
    ordered = [*report.of_kind("question"), *report.of_kind("sanity")]
    assert len(rows) == len(spec.comparisons) == len(ordered)
    assert view.verdicts.index("**The thesis's questions**") < view.verdicts.index(
        "**Within one arm (sanity)**"
    )
    for row, comparison in zip(rows, ordered, strict=True):
        cells = [cell.strip() for cell in row.strip("|").split(" | ")]
        # The claim's name over its Δ and interval, each kept on one line.
        assert f">{comparison.comparison.name}</span><br><small>" in cells[0]
        c = comparison.comparison
        side = f"{c.a} ({c.side_names()[0]})" if c.paired else c.a  # one arm, two sides
        mean_a = f"{side} {format_number(comparison.stats.a.mean)} ± "
        assert mean_a + format_number(comparison.stats.a.sd) in cells[0]  # in its tooltip
        difference = format_number(comparison.stats.difference)
        delta = whole(f"{difference} {interval_text(comparison.claim)}")
        assert cells[0].endswith(f"<br><small>{delta}</small>")
        assert cells[1] == whole(", ".join(map(str, comparison.claim.runs)))
        assert cells[2].startswith(badge(comparison.claim.verdict))
        assert comparison.claim.verdict in VERDICTS
    assert view.stages == "**Stages**: one look at 2 seeds per arm (not adaptive)."
    # Fitness: per arm the mean over seeds per generation and its 95% half-width.
    assert view.fitness.x.tolist() == [1.0, 2.0]
    assert [line.label for line in view.fitness.lines] == ["BS (n = 2)", "RL (n = 2)"]
    mean, half_width, _ = mean_and_ci(results.curve("best_fitness_curve", "RL"))
    assert np.allclose(view.fitness.lines[1].mean, mean)
    assert np.allclose(view.fitness.lines[1].half_width, half_width, equal_nan=True)
    # Implementation: one chart per condition, centred moving averages of the 120 steps.
    assert list(view.rewards) == [c.name for c in spec.conditions]
    chart = view.rewards["break-2"]
    assert "2 sensors break" in chart.caption and "t' = 40" in chart.caption
    assert 0 < len(chart.x) <= MAX_POINTS and len(chart.lines) == 2
    assert all(np.isfinite(line.mean).all() for line in chart.lines)


def test_a_live_view_reads_the_run_files_and_waits_for_the_verdicts(
    runs: Path, spec: ExperimentSpec
) -> None:
    (runs / "experiments" / NAME / SCALE / "RL-seed1.h5").unlink()  # one run not started
    view = ev.build_view(ev.Entry(NAME, spec), SCALE, runs, live=True)
    assert view.count is None  # while it runs, the job's progress counts the runs
    assert view.runs == ("BS-seed0", "BS-seed1", "RL-seed0")
    assert "when the experiment finishes" in view.verdicts
    rl = view.fitness.lines[1]
    assert rl.label == "RL (n = 1)" and np.isnan(rl.half_width).all()  # one run: no band


def test_a_saved_experiment_is_shown_from_its_summary(runs: Path) -> None:
    save_other(runs)
    view = ev.build_view(ev.Entry("mine", None), SCALE, runs)
    assert view.count == ev.ScaleCount(3, 4)
    assert "saved" in view.about and VERDICT.search(view.verdicts)
    assert view.runs == ()  # its summary only: no run files
    empty = ev.build_view(ev.Entry("mine", None), "small", runs)
    assert empty.count is None and empty.fitness.lines == () and "No summary" in empty.verdicts


def test_progress_lines_count_runs_generations_and_conditions() -> None:
    counts = Counts(1, 4, 5, 8, 10, 20, (("BS-seed1", 1, 2), ("RL-seed0", 2, 2)))
    line = ev.progress_line(NAME, SCALE, "running on the Dask cluster", counts)
    assert line.startswith(
        "experiment: ch3-bs-rl at smoke · running on the Dask cluster · 1/4 runs done · "
        "generations 5/8 · conditions 10/20"
    )
    assert line.endswith("under way: BS-seed1 1/2, RL-seed0 2/2")
    assert ev.progress_line(NAME, SCALE, "starting", None) == (
        "experiment: ch3-bs-rl at smoke · starting"
    )


def test_an_experiments_run_resolves_inside_the_runs_dir(runs: Path, spec: ExperimentSpec) -> None:
    path = ev.run_file(runs, NAME, SCALE, "BS-seed1")
    assert path == Path(planning.plan(spec, SCALE, runs)[1].path)
    assert path.resolve().is_relative_to(runs.resolve())


@pytest.mark.parametrize(
    ("name", "scale", "run", "error", "message"),
    [
        (NAME, SCALE, "../../../demo", store.RunFileError, "plain file name"),
        (NAME, SCALE, "/etc/passwd", store.RunFileError, "plain file name"),
        (NAME, SCALE, "..", store.RunFileError, "plain file name"),
        (NAME, SCALE, "sub\\dir", store.RunFileError, "plain file name"),
        (NAME, SCALE, "RL-seed7", store.RunFileError, "no run named"),
        ("..", SCALE, "BS-seed0", DashboardInputError, "experiment name"),
        ("../ch3-bs-rl", SCALE, "BS-seed0", DashboardInputError, "experiment name"),
        ("/tmp", SCALE, "BS-seed0", DashboardInputError, "experiment name"),
        (NAME, "../smoke", "BS-seed0", DashboardInputError, "scale must be one of"),
        (NAME, SCALE, ev.NO_RUNS, DashboardInputError, "choose an experiment"),
    ],
)
def test_run_paths_cannot_escape_the_runs_dir(
    finished: Path, name: str, scale: str, run: str, error: type[Exception], message: str
) -> None:
    with pytest.raises(error, match=re.escape(message)):
        ev.run_file(finished, name, scale, run)


# --- the tab on a real (browserless) viser server --------------------------------------------


@pytest.fixture
def dashboard(runs: Path) -> Iterator[Any]:
    save_other(runs)
    (runs / "experiments" / "broken").mkdir()  # keeps a file that is not an experiment
    (runs / "experiments" / "broken" / layout.DEFINITION).write_text("name = ")
    with dashboard_in_process(runs) as board:
        yield board


def choose(board: Any, experiment: str, scale: str) -> None:
    tab = board.experiments
    with board.lock:
        tab.experiment.value, tab.scale.value = experiment, scale
        tab.select()


def test_the_tab_shows_an_experiment_and_loads_its_run_on_the_stage(dashboard: Any) -> None:
    tab = dashboard.experiments
    until_tab(dashboard, lambda: "| ch3-bs-rl | 4/4 |" in tab.table.content)
    choose(dashboard, NAME, SCALE)
    until_tab(dashboard, lambda: VERDICT.search(tab.verdicts.content) is not None)
    assert tab.run.options == ("BS-seed0", "BS-seed1", "RL-seed0", "RL-seed1")
    assert tab.condition.options == tuple(c.name for c in load_shipped(NAME).conditions)
    assert [s["label"] for s in tab.fitness.series][1::3] == ["BS (n = 2)", "RL (n = 2)"]
    assert len(tab.fitness.bands) == 2
    with dashboard.lock:
        tab.condition.value = "break-3"
        tab.show_condition()
    assert tab.reward_caption.content.startswith("3 sensors break")
    with dashboard.lock:
        tab.run.value = "RL-seed1"
    dashboard.status.guarded(None, tab.load_run)
    assert "RL-seed1" in dashboard.status.text and "⚠" not in dashboard.status.text
    assert dashboard.stage.show.robots[0].label == "RL-seed1"
    assert dashboard.runs.loaded.path == Path(ev.run_file(tab.runs_dir, NAME, SCALE, "RL-seed1"))
    # The saved one: shown from its summary, with no runs to load.
    choose(dashboard, "mine", SCALE)
    until_tab(dashboard, lambda: "**mine** (" in tab.about.content)
    assert tab.run.options == (ev.NO_RUNS,)
    dashboard.status.guarded(None, tab.load_run)
    assert dashboard.status.text == "⚠ choose an experiment and one of its runs first"


@pytest.mark.parametrize(
    ("experiment", "scale", "message"),
    [
        (NAME, "thesis", "the dashboard starts experiments at smoke or small scale"),
        ("mine", SCALE, "mine cannot be started here (its folder keeps no experiment.toml)"),
        ("broken", SCALE, "broken cannot be started here (experiment file "),
        (ev.NO_EXPERIMENTS, SCALE, "choose an experiment first"),
    ],
)
def test_refused_starts_say_why(dashboard: Any, experiment: str, scale: str, message: str) -> None:
    tab = dashboard.experiments
    until_tab(dashboard, lambda: "mine" in tab.entries)
    choose(dashboard, experiment, scale)
    dashboard.status.guarded(None, tab.start)
    assert dashboard.status.text.startswith(f"⚠ {message}")
    assert tab.job is None


def test_one_experiment_at_a_time(dashboard: Any) -> None:
    tab = dashboard.experiments
    until_tab(dashboard, lambda: NAME in tab.entries)
    running = SimpleNamespace(active=True, spec=SimpleNamespace(name="ch5-cs-bs-rl"), scale="small")
    tab.job = running
    choose(dashboard, NAME, SCALE)
    dashboard.status.guarded(None, tab.start)
    assert dashboard.status.text == "⚠ experiment ch5-cs-bs-rl at small is running: one at a time"
    assert tab.job is running
    tab.job = None


class EndsAfterItsSnapshot:
    """A job that ends between its snapshot and any later look: the race the tab must not
    report as "running" (the snapshot said running, `active` then says ended)."""

    spec = SimpleNamespace(name=NAME)
    scale = SCALE
    reported = False
    design = None

    def __init__(self) -> None:
        self.phase = "running"

    @property
    def active(self) -> bool:
        return self.phase == "running"

    def snapshot(self) -> JobSnapshot:
        taken = JobSnapshot(phase=self.phase, detail="", counts=None, outcomes=(), seconds=1.0)  # type: ignore[arg-type]
        self.phase = "finished"  # it ends right after
        return taken


def test_a_job_ending_while_read_is_reported_in_the_phase_it_ended_in(dashboard: Any) -> None:
    tab = dashboard.experiments
    try:
        with dashboard.lock:  # the page's loop follows too, under this lock
            tab.job = EndsAfterItsSnapshot()
            tab.follow()  # its snapshot says running: nothing reported yet
            assert not tab.job.reported
            tab.follow()
        assert tab.job.reported
        assert dashboard.status.text == f"experiment {NAME} at {SCALE} finished"
    finally:
        tab.job = None


def test_starting_a_finished_experiment_writes_its_summary_without_a_cluster(
    dashboard: Any,
) -> None:
    tab = dashboard.experiments
    summary = layout.summary_path(tab.runs_dir, NAME, SCALE)
    summary.unlink()
    until_tab(dashboard, lambda: NAME in tab.entries)
    choose(dashboard, NAME, SCALE)
    dashboard.status.guarded(None, tab.start)
    until_tab(dashboard, lambda: tab.job.reported)
    assert dashboard.status.text == "experiment ch3-bs-rl at smoke finished"
    assert re.search(r"finished: summary written · 4/4 runs done", tab.progress_text.content)
    assert summary.exists() and not tab.cluster.started
    until_tab(dashboard, lambda: VERDICT.search(tab.verdicts.content) is not None)  # new summary


def test_a_read_that_lands_after_the_tab_closed_stays_off_the_page(
    dashboard: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The page may be gone once the tab is closed: a background read still under way then
    puts nothing on it (viser would warn of a message on a closed connection)."""
    tab = dashboard.experiments
    reading, release = threading.Event(), threading.Event()
    build_view = ev.build_view

    def slow_build_view(entry: ev.Entry, scale: str, *args: Any) -> ev.ExperimentView:
        if (entry.name, scale) == (NAME, SCALE):  # the read the page asks for, held back
            reading.set()
            assert release.wait(60)
        return build_view(entry, scale, *args)

    monkeypatch.setattr(ev, "build_view", slow_build_view)
    until_tab(dashboard, lambda: NAME in tab.entries)
    choose(dashboard, NAME, SCALE)
    until_tab(dashboard, reading.is_set)
    with dashboard.lock:
        tab.close()
        shown, about = tab.view, tab.about.content
    release.set()
    tab._pool.shutdown(wait=True)  # the read has landed, its callback run
    assert tab.view is shown and tab.about.content == about
    with dashboard.lock:  # nor does the page's loop, should it turn once more
        tab.follow()
    assert tab.view is shown and tab.about.content == about


def hold_the_lock(runs: Path, scale: str) -> subprocess.Popen[str]:
    """Another process holding the experiment's lock, as `gnp-lab experiment run` does while it
    runs `scale`; started once it holds it."""
    folder = layout.experiment_dir(runs, NAME)
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from app.experiments.lock import experiment_lock\n"
         f"with experiment_lock({str(folder)!r}, {scale!r}):\n"
         "    print('held', flush=True); time.sleep(120)"],
        stdout=subprocess.PIPE, text=True, cwd=Path(__file__).resolve().parents[2],
    )  # fmt: skip
    assert holder.stdout is not None and holder.stdout.readline() == "held\n"
    return holder


def test_an_experiment_run_in_another_process_is_followed_until_it_ends(
    dashboard: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`gnp-lab experiment run` in another terminal: while it holds the experiment's lock at the
    chosen scale, the tab's progress line says so and counts its runs from the files as they
    change; once it ends, the line says that it ended and the tab reads what it left. A run at
    another scale is not this scale's."""
    monkeypatch.setattr(tab_experiments, "LIVE_SECONDS", 0.2)
    tab = dashboard.experiments
    until_tab(dashboard, lambda: NAME in tab.entries)
    choose(dashboard, NAME, SCALE)
    other = hold_the_lock(tab.runs_dir, "small")
    try:
        time.sleep(1.0)  # several looks
        until_tab(dashboard, lambda: tab._elsewhere is None)
        assert tab.progress_text.content == tab_experiments.NOT_STARTED
    finally:
        other.kill()
        other.wait()
    holder = hold_the_lock(tab.runs_dir, SCALE)
    try:
        running = f"experiment: {NAME} at {SCALE} · running in another process (pid {holder.pid})"
        until_tab(dashboard, lambda: f"{running} · 4/4 runs done" in tab.progress_text.content)
        Path(ev.run_file(tab.runs_dir, NAME, SCALE, "BS-seed1")).unlink()  # as if re-run
        until_tab(dashboard, lambda: f"{running} · 3/4 runs done" in tab.progress_text.content)
        assert tab.progress.value > 0
        choose(dashboard, NAME, "small")  # not the scale it runs: this one's line, none
        until_tab(dashboard, lambda: tab.progress_text.content == tab_experiments.NOT_STARTED)
        assert tab.progress.value == 0
        choose(dashboard, NAME, SCALE)
        until_tab(dashboard, lambda: f"{running} · 3/4 runs done" in tab.progress_text.content)
    finally:
        holder.kill()  # killed: its lock file stays, with a pid that runs nowhere
        holder.wait()
    ended = f"experiment: {NAME} at {SCALE} · ended in another process (pid {holder.pid})"
    until_tab(dashboard, lambda: tab.progress_text.content == ended)
    until_tab(dashboard, lambda: f"{SCALE}: 3/4 runs done" in tab.about.content)  # read again


def test_the_first_read_of_the_experiments_says_how_far_it_is(
    runs: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Counting the runs checks every run file (seconds with many): until the table is read,
    it says how many experiments are read so far."""
    scale_count, held, release = ev.scale_count, threading.Event(), threading.Event()
    counted: list[str] = []

    def slow_scale_count(entry: ev.Entry, scale: str, runs_dir: Path) -> Any:
        if entry.name not in counted:
            counted.append(entry.name)
        if len(counted) == 3:  # the third experiment's read, held back
            held.set()
            assert release.wait(60)
        return scale_count(entry, scale, runs_dir)

    monkeypatch.setattr(ev, "scale_count", slow_scale_count)
    with dashboard_in_process(runs) as board:
        tab = board.experiments
        try:
            assert held.wait(60)
            total = len(ev.find_experiments(runs, ev.shipped_specs()))
            until_tab(board, lambda: tab.table.content.endswith(f" 2 of {total} read."))
            assert tab.table.content.startswith(tab_experiments.READING)
        finally:
            release.set()
        until_tab(board, lambda: f"| {NAME} | 4/4 |" in tab.table.content)
