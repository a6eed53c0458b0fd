"""The Runs tab: the runs dir's runs, loading one, replaying a generation's best, exporting it
(docs/export.md), and running its implementation phase (in a child process, nothing written)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import viser

import sim
from app import store
from app.brains.registry import family_of, run_kind
from app.dashboard.controls import (
    NO_RUNS,
    DashboardInputError,
    open_run,
    parse_sensors,
    whole,
)
from app.dashboard.implementation_job import (
    ImplementationJob,
    ImplementationRequest,
    JobProgress,
    trial_steps,
)
from app.dashboard.setting_controls import add_choice, add_number, check, implementation_settings
from app.dashboard.stage import Show, Stage, run_robot
from app.dashboard.status import ProgressBar, Status, set_value
from app.dashboard.tab_plots import PlotsTab
from app.export import ExportError, check_run, export_replay, export_run
from app.phases.implementation import default_name
from app.settings.config import ImplementationSettings, TrainingSettings
from app.settings.fields import read_setting
from app.tasks.common import is_task_run

FIXED_NOTE = (
    "  \n<small>This brain does not learn online: the implementation phase's ε, α and "
    "schedule do not apply to it.</small>"
)


def _most_generations() -> int:
    """A run's most generations (`TrainingSettings.generations`): a replay's generation counts
    from either end within it."""
    generations = read_setting(TrainingSettings, "generations")
    assert generations is not None and generations.high is not None
    return int(generations.high)


MOST_GENERATIONS = _most_generations()
TABLE_ROWS = 4.5
"""Rows of the runs table in view; more scroll inside it."""


@dataclass
class RunsTab:
    """The Runs tab's handles, the run loaded and the implementation phase running."""

    stage: Stage
    status: Status
    plots: PlotsTab
    runs_dir: Path
    table: viser.GuiMarkdownHandle
    run: viser.GuiDropdownHandle[str]
    summary: viser.GuiMarkdownHandle
    arena: viser.GuiDropdownHandle[str]
    generation: viser.GuiNumberHandle[int]
    sensors: viser.GuiTextHandle
    mode: viser.GuiDropdownHandle[str]
    fault_step: viser.GuiNumberHandle[int]
    steps: viser.GuiNumberHandle[int]
    repeats: viser.GuiNumberHandle[int]
    schedule: viser.GuiDropdownHandle[str]
    noise: viser.GuiNumberHandle[float]  # the trials' σ: the loaded run's implementation σ
    run_implementation: viser.GuiButtonHandle
    cancel_implementation: viser.GuiButtonHandle
    implementation_bar: ProgressBar
    implementation_text: viser.GuiMarkdownHandle
    loaded: store.RunReader | None = None
    loaded_name: str = ""  # the loaded run's name, as the runs list gives it
    load_task: Callable[[Path, str], None] | None = None  # a task run goes to the task panel
    robot_only: tuple[Any, ...] = ()  # the controls of a robot run (off for a task run)
    leave_task: Callable[[], None] | None = None  # a robot run loaded: the robot back on show
    implementation: ImplementationJob | None = None
    implementation_name: str = ""  # run/condition of the implementation job
    noise_of: store.RunReader | None = None  # the loaded run whose σ the σ field took
    last_export: Path | None = None
    exporting: Future[Path] | None = None  # a replay being exported (a second or so)
    _pool: ThreadPoolExecutor = field(
        default_factory=lambda: ThreadPoolExecutor(1, thread_name_prefix="export")
    )

    def list_runs(self, runs: Sequence[store.RunSummary]) -> None:
        """Offer `runs` to load and describe them in a table (what changed only: the list
        follows the runs dir twice a second)."""
        names = tuple(r.name for r in runs if r.error is None) or (NO_RUNS,)
        if tuple(self.run.options) != names:
            set_options(self.run, names)
        table = runs_table(runs, self.runs_dir)
        if self.table.content != table:
            self.table.content = table

    def load(self, name: str) -> None:
        """Load a run of the runs dir and put it on show: its best on the stage (a task run:
        its replay), its summary, fitness history, stored implementation, fault settings."""
        if name != NO_RUNS and self._task_run(store.resolve_run(self.runs_dir, name), name):
            if self.run.value != name and name in self.run.options:
                set_value(self.run, name)
            return
        self._load(open_run(self.runs_dir, name), name)

    def load_file(self, path: Path) -> None:
        """Load a run file another tab found inside the runs dir (an experiment's run) and put
        it on show (a task run: its replay; a fracnetics arm's file holds no individual)."""
        from app.tasks.peer import is_fracnetics_run

        name = str(path.relative_to(self.runs_dir).with_suffix(""))
        if self._task_run(path, name):
            return
        if is_fracnetics_run(path):
            raise DashboardInputError(
                f"{name} is a fracnetics arm's run: its returns and test only, no individual "
                "to replay (fracnetics' library hands back none); its arm is in the report"
            )
        self._load(store.RunReader(path), name)

    def _task_run(self, path: Path, name: str) -> bool:
        """A task run goes to the task panel (True); anything else is the robot's (False)."""
        if self.load_task is None or not is_task_run(path):
            return False
        self.load_task(path, name)
        self.summary.content = f"**{name}** is a task run: see *Task run* below."
        return True

    def _load(self, reader: store.RunReader, name: str) -> None:
        if self.leave_task is not None:
            self.leave_task()
        if self.loaded is not None:
            self.loaded.close()
        self.loaded, self.loaded_name = reader, name
        if self.run.value != name and name in self.run.options:
            set_value(self.run, name)
        history = reader.history()
        config = reader.config
        family = family_of(config)
        impls = reader.implementation_names()
        best = float(history.best_fitness.max()) if len(history.best_fitness) else 0.0
        self.summary.content = (
            f"**{name}**: {family.description}, population "
            f"{config.training.population}, {reader.generations_done}/"
            f"{config.training.generations} generations, T = {config.training.steps}, "
            f"σ = {config.training.noise_sigma:g}, seed {config.seed}  \n"
            f"{store.BEST_OF_RUN} {best:.4f}"
            f" · implementations: {', '.join(impls) or 'none'}"
            + ("" if family.learns_online else FIXED_NOTE)
        )
        implementation = config.implementation  # the run's own fault, as a starting point
        sensors = implementation.broken_sensors
        set_value(self.sensors, ",".join(map(str, sensors)) if sensors else "2,3")
        set_value(self.mode, implementation.fault_mode)
        set_value(self.fault_step, implementation.fault_step)
        set_value(self.steps, implementation.steps)
        set_value(self.repeats, implementation.repeats)
        set_value(self.schedule, implementation.schedule)
        # One stage: the run's final best goes on show at once, and every panel follows it
        # (the fitness and implementation charts through the stage's listener).
        set_value(self.generation, -1)
        if reader.generations_done == 0:
            self.status.set(f"loaded run {name}: no generation finished yet, nothing to show")
            return
        self.replay()
        self.status.set(f"loaded run {name}: its final best on show")

    def replay(self) -> None:
        """Put the loaded run's best of the chosen generation on show, from the pose on show."""
        if self.loaded is None:
            raise DashboardInputError("load a run first")
        generation = whole(self.generation.value, "generation", -MOST_GENERATIONS, MOST_GENERATIONS)
        robot = run_robot(self.loaded, generation)
        shown = generation if generation >= 0 else self.loaded.generations_done + generation
        training = self.loaded.config.training
        self.stage.present(
            Show(
                f"best of generation {shown} of run {self.loaded_name}",
                (robot,),
                self.arena.value,
                self.stage.start,
                life=training.steps,
                control_period=training.control_period,
                runs=(self.loaded_name,),
                sources=(self.loaded.path,),
            )
        )
        self.status.set(f"replaying the best of generation {shown} of {self.loaded_name}")

    def export(self, replay: bool = False) -> None:
        """Export the loaded run's best of the chosen generation into `<runs dir>/exports/
        <run>-g<G>/`, or the replay of its final elite (the recorded life) into `<run>-replay/`;
        the status line names the folder (also kept in `last_export`).

        A replay takes a second or so to draw and record: it is written in the background
        (`exporting`), so the page and its robots go on meanwhile."""
        if self.loaded is None:
            raise DashboardInputError("load a run first")
        if self.exporting is not None and not self.exporting.done():
            raise DashboardInputError("a replay is being exported: one at a time")
        run = self.loaded.path
        if replay:
            out = self.exports_dir / f"{run.stem}-replay"
            self.status.set(f"exporting the replay of {run.stem} to {out}")
            self.exporting = self._pool.submit(self._export_replay, run, out)
            return
        try:
            generation = whole(
                self.generation.value, "generation", -MOST_GENERATIONS, MOST_GENERATIONS
            )
            chosen = check_run(self.loaded, generation)
            out = export_run(run, self.exports_dir / f"{run.stem}-g{chosen}", chosen)
        except ExportError as error:
            raise DashboardInputError(str(error)) from None
        self.last_export = out
        self.status.set(f"exported {run.stem} to {out}")

    def _export_replay(self, run: Path, out: Path) -> Path:
        """Write a replay (in the export thread), then put its folder, or why not, on the
        status line: the future is done only once the page says so."""
        try:
            path = export_replay(run, out)
        except Exception as error:  # a thread's failure goes to the page, not to stderr
            failed = isinstance(error, ExportError)
            message = str(error) if failed else f"exporting the replay of {run.stem}: {error}"
            with self.status.lock:
                self.status.set(f"⚠ {message}")
            raise
        with self.status.lock:
            self.last_export = path
            self.status.set(f"exported the replay of {run.stem} to {path}")
        return path

    def wait_for_export(self, seconds: float = 60.0) -> None:
        """Let a replay being written finish (call without the lock: its last step takes it)."""
        if self.exporting is not None:
            wait([self.exporting], timeout=seconds)

    @property
    def exports_dir(self) -> Path:
        return self.runs_dir / "exports"

    def start_implementation(self) -> None:
        if self.loaded is None:
            raise DashboardInputError("load a run first")
        if self.implementation is not None and self.implementation.active:
            raise DashboardInputError("an implementation phase is already running")
        self.follow_loaded()
        request = ImplementationRequest(
            run=self.loaded.path,
            sensors=parse_sensors(self.sensors.value),
            mode=self.mode.value,
            fault_step=check(ImplementationSettings, "fault_step", self.fault_step.value, "t'"),
            steps=check(ImplementationSettings, "steps", self.steps.value, "steps T"),
            repeats=check(ImplementationSettings, "repeats", self.repeats.value, "repeats"),
            schedule=self.schedule.value,
            noise_sigma=check(ImplementationSettings, "noise_sigma", self.noise.value, "noise σ"),
        )
        # The whole request against the model here, so a bad value (sensor 9, t' ≥ T) is one
        # message now and no worker starts; the worker builds the same settings again.
        settings = request.settings(self.loaded.config.implementation)
        run = self.run_name(request.run)
        self.implementation_name = f"{run}/{default_name(settings)}"
        self.implementation = job = ImplementationJob(request, trial_steps(settings))
        self.run_implementation.disabled, self.cancel_implementation.disabled = True, False
        self._show_progress(job.progress())
        self.status.set(f"implementation phase of {run} started")

    def cancel(self) -> None:
        """Stop the implementation phase under way (nothing was written: nothing to undo)."""
        job = self.implementation
        if job is None or not job.active:
            raise DashboardInputError("no implementation phase is running")
        job.cancel()
        self.follow_implementation()

    def follow_implementation(self) -> None:
        """Show the implementation phase's progress; plot it once its child process is done
        (or say it failed or was cancelled) and offer Run again."""
        self.follow_loaded()
        job = self.implementation
        if job is None or job.reported:
            return
        progress = job.progress()
        self._show_progress(progress)
        if progress.state in ("starting", "running"):
            return
        job.reported = True
        self.run_implementation.disabled, self.cancel_implementation.disabled = False, True
        name, took = self.implementation_name, f"{progress.elapsed:.0f} s"
        of_loaded = self.of_loaded(job)
        if progress.state == "cancelled":
            if of_loaded:
                self.plots.implementation_line = f"implementation: {name} cancelled"
            self.status.set(f"implementation cancelled: {name} after {took}, nothing stored")
            return
        try:
            result = job.result()
        except Exception as error:  # the child's error, whatever it is, belongs on the page
            if of_loaded:
                self.plots.implementation_line = f"implementation: {name} failed: {error}"
            self.status.set(f"⚠ implementation failed: {error}")
            return
        if of_loaded:
            self.plots.show_implementation(name, result)
        self.status.set(
            f"implementation phase finished: {name} in {took}, mean reward/step "
            f"{result.mean_reward:.4f} (not stored: `gnp-lab implement` stores one"
            + ("" if of_loaded else "; not plotted: another run is loaded")
            + ")"
        )

    def _show_progress(self, progress: JobProgress) -> None:
        """The Runs tab's bar and line, and the readout's implementation line."""
        line = f"{self.implementation_name} {progress.describe()}"
        value = 100.0 * progress.fraction
        if self.implementation_bar.value != value:
            set_value(self.implementation_bar, value)
        job = self.implementation
        sigma = job.request.noise_sigma if job is not None else None
        text = f"**Implementation** {line}" + (f" · σ {sigma:g}" if sigma is not None else "")
        if self.implementation_text.content != text:
            self.implementation_text.content = text
        if job is not None and self.of_loaded(job) and progress.state in ("starting", "running"):
            self.plots.implementation_line = f"implementation: {line}"

    def of_loaded(self, job: ImplementationJob) -> bool:
        """Whether `job` implements the loaded run: the readout and chart are that run's,
        another run's phase is only told of in the status."""
        return self.loaded is not None and self.loaded.path.resolve() == job.request.run.resolve()

    def follow_loaded(self) -> None:
        """The σ field takes each newly loaded run's own implementation σ (the noise of its
        trials, as `gnp-lab implement` uses unless --noise is given; the Faults tab's σ is the
        robot on show's only)."""
        if self.loaded is self.noise_of:
            return
        self.noise_of = self.loaded
        if self.loaded is not None:
            set_value(self.noise, self.loaded.config.implementation.noise_sigma)

    def run_name(self, path: Path) -> str:
        """A run file's name as the Runs tab lists it (relative to the runs dir)."""
        try:
            return str(path.relative_to(self.runs_dir).with_suffix(""))
        except ValueError:
            return path.stem

    def close(self) -> None:
        self._pool.shutdown(wait=False)  # under the lock: Dashboard.stop waited for it before
        if self.implementation is not None:
            self.implementation.close()
        if self.loaded is not None:
            self.loaded.close()


def populate_runs_tab(
    gui: viser.GuiApi,
    stage: Stage,
    status: Status,
    plots: PlotsTab,
    runs_dir: Path,
    refresh: Callable[[], None],
) -> RunsTab:
    """Add the Runs tab's controls (inside the current tab) and attach their callbacks.

    `refresh` re-reads the runs dir for every list of runs on the page.
    """
    table = gui.add_markdown("")
    run = gui.add_dropdown("Run", (NO_RUNS,))
    buttons = gui.add_button_group("Run file", ("Refresh list", "Load"))
    summary = gui.add_markdown("No run loaded.")
    # The implementation phase first: Load already puts the run's final best on show, so the
    # phase's Run button is what must fit a 720-pixel-high window; replays and exports follow.
    gui.add_markdown("**Implementation phase** (implementation arena, online Sarsa)")
    fields = implementation_settings()
    tab = RunsTab(
        stage=stage,
        status=status,
        plots=plots,
        runs_dir=runs_dir,
        table=table,
        run=run,
        summary=summary,
        sensors=gui.add_text("Break sensors", "2,3"),
        mode=add_choice(gui, fields["fault_mode"], fields["fault_mode"].default, "Mode"),
        # Bounds and hints from the model; the values are short for a look in the page.
        fault_step=add_number(gui, fields["fault_step"], 500, "Fault step t'"),
        steps=add_number(gui, fields["steps"], 1500, "Steps T"),
        repeats=add_number(gui, fields["repeats"], 3, "Repeats per start pose"),
        schedule=add_choice(gui, fields["schedule"], fields["schedule"].default, "ε, α "),
        # The trials' own σ, from the loaded run (`follow_loaded`), not the Faults tab's.
        noise=add_number(gui, fields["noise_sigma"], 0.0, "Noise σ (trials)"),
        run_implementation=gui.add_button("Run implementation", icon=viser.Icon.PLAYER_PLAY),
        cancel_implementation=gui.add_button(
            "Cancel implementation", icon=viser.Icon.PLAYER_STOP, disabled=True
        ),
        implementation_bar=gui.add_progress_bar(0.0),
        implementation_text=gui.add_markdown(
            "Implementation: not run. σ starts at the loaded run's implementation σ."
        ),
        arena=gui.add_dropdown("Replay in", sim.ARENA_NAMES, initial_value="training"),
        generation=gui.add_number("Generation (−1 = last)", -1, step=1),
    )
    replay = gui.add_button("Replay best individual", icon=viser.Icon.PLAYER_PLAY)
    exports = gui.add_button_group("Export", ("Export", "Export replay"))
    arena, generation = tab.arena, tab.generation
    tab.robot_only = (
        arena, generation, replay, exports, tab.sensors, tab.mode, tab.fault_step, tab.steps,
        tab.repeats, tab.schedule, tab.noise, tab.run_implementation,
    )  # fmt: skip

    actions = {"Refresh list": refresh, "Load": lambda: tab.load(tab.run.value)}
    buttons.on_click(lambda event: status.guarded(event.client, actions[buttons.value]))
    replay.on_click(status.guard(tab.replay))
    exports.on_click(
        lambda event: status.guarded(
            event.client, lambda: tab.export(replay=exports.value == "Export replay")
        )
    )
    tab.run_implementation.on_click(status.guard(tab.start_implementation))
    tab.cancel_implementation.on_click(status.guard(tab.cancel))
    return tab


def set_options(
    dropdown: viser.GuiDropdownHandle[str], names: Sequence[str], empty: str = NO_RUNS
) -> None:
    """Offer `names` (or the `empty` placeholder), keeping the choice if it is still there."""
    current = dropdown.value
    options = tuple(names) or (empty,)
    dropdown.options = options
    if current in options:
        set_value(dropdown, current)


def runs_table(runs: Sequence[store.RunSummary], runs_dir: Path) -> str:
    """A markdown table of the runs: method (or neural optimiser), generations done, best
    fitness."""
    if not runs:
        return f"No runs in `{runs_dir}` yet: train one in the Train tab."
    rows = [f"| run | method | generations | {store.BEST_OF_RUN} |", "|---|---|---|---|"]
    for r in runs:
        if r.error is not None:
            rows.append(f"| {r.name} | ⚠ unreadable | | |")
            continue
        done = f"{r.generations_done}/{r.generations}" + ("" if r.finished else " …")
        rows.append(f"| {r.name} | {run_kind(r)} | {done} | {r.best_fitness:.4f} |")
    # A long list scrolls in its own box, so the controls below keep their place on the page.
    return f"<div style='max-height: {TABLE_ROWS * 1.6}em; overflow-y: auto'>\n\n" + (
        "\n".join(rows) + "\n\n</div>"
    )
