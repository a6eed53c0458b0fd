"""The Experiments tab: the committed reports of the checkout (`tab_committed`: the thesis's
answers, every report's verdicts and runs, with no run files), then the shipped and saved
experiments with their local runs' status, starting one at
`smoke` or `small` scale on the dashboard's Dask cluster (all its seeds, or adaptively in
stages of seeds), its progress live, the stages of an adaptive run, the verdicts of the
thesis's questions and of the sanity claims, its fitness and implementation curves per arm
with 95% bands, and any of its runs on the stage.

Callbacks only record choices and start threads: reading run files, statistics and curves are
computed in one background thread (`experiment_view`), the experiment in another
(`ExperimentJob`); `follow`, called by the page's loop, puts what they finished on the page.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import viser

from app.dashboard import experiment_view as ev
from app.dashboard import plots
from app.dashboard.controls import DashboardInputError
from app.dashboard.experiment_job import DaskCluster, ExperimentJob, JobSnapshot
from app.dashboard.experiment_verdicts import AdaptiveRequest
from app.dashboard.status import ProgressBar, Status, set_value
from app.dashboard.tab_committed import CommittedSection, populate_committed
from app.dashboard.tab_runs import set_options
from app.experiments.adaptive import DEFAULT_MAX_SEEDS, DEFAULT_STAGE_SEEDS
from app.experiments.layout import DEFINITION
from app.experiments.progress import Counts
from app.experiments.spec import SCALES, ExperimentSpec

STARTABLE_SCALES = ("smoke", "small")  # minutes at most; `thesis` is for the command line
LIVE_SECONDS = 5.0  # how often the curves are re-read from the run files while it runs
NO_CONDITIONS = "(none)"
NOT_STARTED = "experiment: none started"
READING = "Reading the experiments and counting their runs (each run file is checked)…"


@dataclass
class ExperimentsTab:
    """The Experiments tab's handles, what it shows, and the experiment it started."""

    status: Status
    runs_dir: Path
    show_run: Callable[[Path], None]  # put a run file's best on the stage (the Runs tab's way)
    table: viser.GuiMarkdownHandle
    experiment: viser.GuiDropdownHandle[str]
    scale: viser.GuiDropdownHandle[str]
    adaptive: viser.GuiCheckboxHandle
    stage_seeds: viser.GuiNumberHandle[int]
    max_seeds: viser.GuiNumberHandle[int]
    progress: ProgressBar
    progress_text: viser.GuiMarkdownHandle
    about: viser.GuiMarkdownHandle
    stages: viser.GuiMarkdownHandle
    verdicts: viser.GuiMarkdownHandle
    fitness: viser.GuiUplotHandle
    condition: viser.GuiDropdownHandle[str]
    reward_caption: viser.GuiMarkdownHandle
    reward: viser.GuiUplotHandle
    run: viser.GuiDropdownHandle[str]
    committed: CommittedSection | None = None  # the committed reports, shown beside
    cluster: DaskCluster = field(default_factory=DaskCluster)
    job: ExperimentJob | None = None
    view: ev.ExperimentView | None = None
    entries: dict[str, ev.Entry] = field(default_factory=dict)
    _pool: ThreadPoolExecutor = field(
        default_factory=lambda: ThreadPoolExecutor(1, thread_name_prefix="experiments-view")
    )
    _shipped: tuple[ExperimentSpec, ...] | None = None
    _catalogue: Future[ev.Catalogue] | None = None
    _pending: Future[ev.ExperimentView] | None = None
    _wanted: tuple[str, str] | None = None  # the (experiment, scale) the page asks for
    _again: bool = False  # the wanted view is to be read (again)
    _live_at: float = 0.0
    _closed: bool = False
    _shown: str = ""  # the progress text of this tab's job on the page
    # The chosen experiment run by `gnp-lab experiment run` in another process: looked for
    # every LIVE_SECONDS, and (name, scale, pid) of the one whose progress is on the page.
    _elsewhere: Future[tuple[tuple[str, str], tuple[int, Counts] | None]] | None = None
    _elsewhere_at: float = 0.0
    _elsewhere_shown: tuple[str, str, int] | None = None

    # -- what the callbacks do (quick: they only start background work) --

    def refresh(self) -> None:
        """Re-read the experiments and their status, and the one chosen (in the background)."""
        if not self._closed and (self._catalogue is None or self._catalogue.done()):
            self._catalogue = self._pool.submit(self._read_catalogue)
            self._catalogue.add_done_callback(self._landed)
        self.select()

    def select(self) -> None:
        """Show the chosen experiment at the chosen scale (read in the background)."""
        self._wanted = (self.experiment.value, self.scale.value)
        self._again = True
        if self.committed is not None:  # its committed report beside the local runs
            self.committed.choose(*self._wanted)
        self._submit()

    def _submit(self) -> None:
        """Read the wanted view, once the view being read (if any) is done."""
        if self._closed or not self._again or (self._pending and not self._pending.done()):
            return
        self._again = False
        name, scale = self._wanted or ("", "")
        entry = self.entries.get(name)
        if entry is not None:
            live, job = self._live(name, scale), self.job
            seeds = since = None
            if live and job is not None and job.design is not None:  # its stage's seeds so far
                seeds, since = job.snapshot().seeds, job.since
            self._pending = self._pool.submit(
                ev.build_view, entry, scale, self.runs_dir, live, seeds, since
            )
            self._pending.add_done_callback(self._landed)

    def start(self) -> None:
        """Start the chosen experiment at the chosen scale, unless one is running."""
        if self.job is not None and self.job.active:
            running = f"{self.job.spec.name} at {self.job.scale}"
            raise DashboardInputError(f"experiment {running} is running: one at a time")
        name, scale = self.experiment.value, self.scale.value
        entry = self.entries.get(name)
        if entry is None:
            raise DashboardInputError("choose an experiment first")
        if entry.spec is None:
            why = entry.problem or f"its folder keeps no {DEFINITION}"
            raise DashboardInputError(
                f"{name} cannot be started here ({why}): run it once with "
                f"`gnp-lab experiment run --file FILE --scale {scale}`, which keeps its file"
            )
        if scale not in STARTABLE_SCALES:
            raise DashboardInputError(
                f"the dashboard starts experiments at {' or '.join(STARTABLE_SCALES)} scale; "
                f"run {scale} with `gnp-lab experiment run {name} --scale {scale}`"
            )
        if scale not in entry.spec.scales:
            raise DashboardInputError(f"{name} has no {scale} scale")
        request = AdaptiveRequest(self.adaptive.value, self.stage_seeds.value, self.max_seeds.value)
        design = request.design()
        self.job = ExperimentJob(entry.spec, scale, self.runs_dir, self.cluster, design)
        self._shown = ""
        how = "" if design is None else f" adaptively (looks at {design.looks} seeds per arm)"
        self.status.set(f"experiment {name} at {scale} started{how}")

    def stop(self) -> None:
        if self.job is None or not self.job.active:
            raise DashboardInputError("no experiment is running")
        self.job.stop()
        self.status.set(f"stopping experiment {self.job.spec.name}")

    def show_condition(self) -> None:
        """Draw the chosen condition's reward curves (from results already in memory)."""
        view, condition = self.view, self.condition.value
        if view is None or not view.rewards or condition == NO_CONDITIONS:
            draw_chart(self.reward, ev.NO_CHART)
            self.reward_caption.content = "Implementation: no curves yet."
            return
        if condition not in view.rewards:
            raise DashboardInputError(f"{view.name} has no condition {condition!r}")
        chart = view.rewards[condition]
        draw_chart(self.reward, chart)
        self.reward_caption.content = chart.caption

    def load_run(self) -> None:
        """Put the chosen run's best individual on the stage."""
        path = ev.run_file(self.runs_dir, self.experiment.value, self.scale.value, self.run.value)
        self.show_run(path)

    # -- called by the page's loop, under its lock --

    def follow(self) -> None:
        """Put finished background work on the page, and the running experiment's progress."""
        if self._closed:
            return
        self._put_read()
        job = self.job
        if job is None or not job.active:
            self._look_elsewhere()
        if job is None:
            return
        snapshot = job.snapshot()
        self._show_progress(job, snapshot)
        if not snapshot.active and not job.reported:
            job.reported = True
            self.refresh()
            if snapshot.phase == "failed":
                self.status.set(f"⚠ experiment {job.spec.name} failed: {snapshot.detail}")
            else:
                self.status.set(f"experiment {job.spec.name} at {job.scale} {snapshot.phase}")
        elif (
            self._wanted is not None
            and self._live(*self._wanted)
            and time.monotonic() - self._live_at > LIVE_SECONDS
        ):
            self._live_at = time.monotonic()
            self.select()  # the curves so far, from the run files

    def _landed(self, future: Future[Any]) -> None:
        """A background read is done: on the page with it at once (not at the loop's next turn).

        `close` runs under the same lock, so `_put_read`'s check of it cannot race."""
        if not future.cancelled():
            with self.status.lock:
                self._put_read()

    def _put_read(self) -> None:
        """Put the catalogue and the view read in the background on the page, once read.

        A read that lands once the tab is closed is dropped, whether this callback or the
        page's loop sees it first: the page may be gone."""
        if self._closed:
            return
        if self._catalogue is not None and self._catalogue.done():
            catalogue, self._catalogue = self._catalogue, None
            try:
                self._apply_catalogue(catalogue.result())
            except Exception as error:  # e.g. a runs dir that went away
                self.table.content = f"⚠ could not list the experiments: {error}"
        if self._elsewhere is not None and self._elsewhere.done():
            looked, self._elsewhere = self._elsewhere, None
            if looked.exception() is None:  # else an unreadable folder: its view says why
                self._apply_elsewhere(*looked.result())
        if self._pending is not None and self._pending.done():
            pending, self._pending = self._pending, None
            try:
                view = pending.result()
            except Exception as error:  # an unreadable folder must not stop the page's loop
                self.about.content = f"⚠ could not read the experiment: {error}"
            else:
                if self._wanted == (view.name, view.scale):
                    self._apply_view(view)
        self._submit()

    def close(self) -> None:
        """Stop the experiment and close the cluster (the page is shutting down)."""
        self._closed = True
        if self.committed is not None:
            self.committed.close()
        if self.job is not None:
            self.job.stop()
        self.cluster.close()
        self._pool.shutdown(wait=False, cancel_futures=True)

    # -- helpers --

    def _live(self, name: str, scale: str) -> bool:
        job = self.job
        return job is not None and job.active and (job.spec.name, job.scale) == (name, scale)

    def _read_catalogue(self) -> ev.Catalogue:
        if self._shipped is None:
            self._shipped = ev.shipped_specs()
            # Import matplotlib and scipy now, off the page, not with the first chart.
            import app.experiments.report  # noqa: F401
        return ev.catalogue(self.runs_dir, self._shipped, self._counted)

    def _counted(self, done: int, experiments: int) -> None:
        """How far the first read of the experiments is, on the page while nothing else is
        listed (a first read validates every run file: seconds with many)."""
        with self.status.lock:
            if not self.entries and not self._closed:
                self.table.content = f"{READING} {done} of {experiments} read."

    def _apply_catalogue(self, rows: ev.Catalogue) -> None:
        self.entries = {entry.name: entry for entry, _ in rows}
        self.table.content = ev.catalogue_table(rows)
        set_options(self.experiment, list(self.entries), ev.NO_EXPERIMENTS)
        self.select()

    def _apply_view(self, view: ev.ExperimentView) -> None:
        self.view = view
        lines = [view.about]
        if view.count is not None:
            lines.append(f"{view.scale}: {view.count} runs done")
        lines += [f"⚠ {problem}" for problem in view.problems]
        self.about.content = "  \n".join(lines)
        draw_chart(self.fitness, view.fitness)
        set_options(self.condition, list(view.rewards), NO_CONDITIONS)
        self.show_condition()
        self.stages.content = view.stages
        self.verdicts.content = view.verdicts
        report = self.committed.shelf.of(view.name, view.scale) if self.committed else None
        if report is not None and view.verdicts == ev.NO_SUMMARY:
            self.verdicts.content = (
                f"No local runs' summary at this scale: the committed report {report.name} "
                "is shown above (Report)."
            )
        set_options(self.run, view.runs, ev.NO_RUNS)

    def _show_progress(self, job: ExperimentJob, snapshot: JobSnapshot) -> None:
        phase = snapshot.detail if snapshot.active else f"{snapshot.phase}: {snapshot.detail}"
        text = ev.progress_line(job.spec.name, job.scale, phase, snapshot.counts)
        text += f"  \n{snapshot.seconds:.0f} s"
        text += "".join(f"  \n{line}" for line in snapshot.outcomes)
        if text == self._shown:
            return
        self._shown = text
        self._put_progress(text, snapshot.counts)

    def _put_progress(self, text: str, counts: Counts | None) -> None:
        if self.progress_text.content != text:
            self.progress_text.content = text
        if counts is not None and counts.generations:
            done = counts.generations_done + counts.conditions_done
            set_value(self.progress, 100.0 * done / (counts.generations + counts.conditions))

    def _look_elsewhere(self) -> None:
        """Whether the chosen experiment runs in another process, and how far it is (read in
        the background every LIVE_SECONDS)."""
        wanted = self._wanted
        if wanted is None or self._elsewhere is not None or self._closed:
            return
        entry = self.entries.get(wanted[0])
        if entry is None or time.monotonic() - self._elsewhere_at < LIVE_SECONDS:
            return
        self._elsewhere_at = time.monotonic()
        self._elsewhere = self._pool.submit(
            lambda: (wanted, ev.elsewhere(entry, wanted[1], self.runs_dir))
        )
        self._elsewhere.add_done_callback(self._landed)

    def _apply_elsewhere(self, looked: tuple[str, str], found: tuple[int, Counts] | None) -> None:
        """The progress of the chosen experiment run in another process; once it ends, what
        it left (its summary, verdicts and counts), read again."""
        shown = self._elsewhere_shown
        if found is not None and looked == self._wanted:
            pid, counts = found
            self._elsewhere_shown = (*looked, pid)
            phase = f"running in another process (pid {pid})"
            self._put_progress(ev.progress_line(*looked, phase, counts), counts)
            return
        if shown is None or (found is not None and shown[:2] == looked):
            return
        self._elsewhere_shown = None
        if shown[:2] == looked:  # it ended: the page shows what it left
            name, scale, pid = shown
            self._put_progress(f"experiment: {name} at {scale} · ended in another process "
                               f"(pid {pid})", None)  # fmt: skip
            self.refresh()
        else:  # another experiment chosen: its own line (this tab's job's, or none)
            self._put_progress(self._shown or NOT_STARTED, None)
            if not self._shown:
                set_value(self.progress, 0.0)


def draw_chart(plot: viser.GuiUplotHandle, chart: ev.Chart) -> None:
    """Draw a chart's curves; without any (nothing picked, nothing run yet) hide it rather than
    show empty axes."""
    plots.set_mean_bands(plot, chart.x, chart.lines)
    plot.visible = bool(chart.lines)


def populate_experiments_tab(
    gui: viser.GuiApi, status: Status, runs_dir: Path, show_run: Callable[[Path], None]
) -> ExperimentsTab:
    """Add the Experiments tab's controls (inside the current tab) and attach their callbacks:
    the committed reports first, then the experiments run here.

    `show_run(path)` puts a run file's best individual on the stage.
    """
    committed = populate_committed(gui, status)
    with gui.add_folder("Experiments run here (local runs)"):
        tab = _populate_local(gui, status, runs_dir, show_run)
    tab.committed = committed
    tab.refresh()
    return tab


def _populate_local(
    gui: viser.GuiApi, status: Status, runs_dir: Path, show_run: Callable[[Path], None]
) -> ExperimentsTab:
    """The experiments with their local runs: start one, follow it, its verdicts and curves."""
    table = gui.add_markdown(READING)
    experiment = gui.add_dropdown("Experiment", (ev.NO_EXPERIMENTS,))
    scale = gui.add_dropdown("Scale", SCALES, initial_value=STARTABLE_SCALES[0])
    adaptive = gui.add_checkbox(
        "Adaptive",
        False,
        hint="Run in stages of seeds until every claim is decided (gnp-lab experiment run "
        "--adaptive)",
    )
    stage_seeds = gui.add_number("Stage seeds", DEFAULT_STAGE_SEEDS, step=1)
    max_seeds = gui.add_number("Max seeds", DEFAULT_MAX_SEEDS, step=1)
    buttons = gui.add_button_group("Experiment run", ("Start", "Stop", "Refresh"))
    tab = ExperimentsTab(
        status=status,
        runs_dir=runs_dir,
        show_run=show_run,
        table=table,
        experiment=experiment,
        scale=scale,
        adaptive=adaptive,
        stage_seeds=stage_seeds,
        max_seeds=max_seeds,
        progress=gui.add_progress_bar(0.0),
        progress_text=gui.add_markdown(NOT_STARTED),
        about=gui.add_markdown(""),
        stages=gui.add_markdown(""),
        verdicts=gui.add_markdown(""),
        fitness=plots.band_plot(gui, "Training: best fitness (mean, 95% band)", "generation"),
        condition=gui.add_dropdown("Condition", (NO_CONDITIONS,)),
        reward_caption=gui.add_markdown(""),
        reward=plots.band_plot(gui, "Implementation: reward per step", "step"),
        run=gui.add_dropdown("Run (arm-seed)", (ev.NO_RUNS,)),
    )
    tab.fitness.visible = tab.reward.visible = False  # until an experiment with runs is shown
    load = gui.add_button("Load run on stage")

    actions: dict[str, Callable[[], None]] = {
        "Start": tab.start,
        "Stop": tab.stop,
        "Refresh": tab.refresh,
    }
    buttons.on_click(lambda event: status.guarded(event.client, actions[buttons.value]))

    def guarded(action: Callable[[], None]) -> Callable[[Any], None]:
        return lambda event: status.guarded(event.client, action)

    experiment.on_update(guarded(tab.select))
    scale.on_update(guarded(tab.select))
    tab.condition.on_update(guarded(tab.show_condition))
    load.on_click(guarded(tab.load_run))
    return tab
