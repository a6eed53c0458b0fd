"""The Train tab: a run's settings, Start / Pause / Resume / Stop, and its progress.

The settings' controls are built from the models (`app.settings.loading.train_settings`): the common
ones first, every other one in a folder, so a new field of a model shows up here by itself.
The values are checked once, by building the `RunConfig` that `TrainingJob` is given.
Training runs the CLI's loop in a thread of this process, its lives on the worker pool
(`TrainingJob`); a `TrainingFollower` reads its file as it grows, and each new generation's
best goes on show at once.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import viser

from app.brains.registry import family_of, names
from app.dashboard.controls import DashboardInputError, training_config
from app.dashboard.follower import TrainingFollower
from app.dashboard.setting_controls import SettingControls, add_controls
from app.dashboard.stage import Stage
from app.dashboard.status import ProgressBar, Status, set_value
from app.dashboard.tab_plots import PlotsTab
from app.dashboard.training_job import JobState, TrainingJob
from app.experiments.planning import training_steps
from app.experiments.results import core_steps_per_second
from app.phases.lives import shards
from app.settings.config import DEFAULT_BRAIN, PRESET_NAMES, RunConfig
from app.settings.loading import load_preset, train_settings
from app.system.workers import default_workers

FIRST = (
    "brain.controller.method",
    "brain.controller.fuzzy",
    "training.population",
    "training.generations",
    "training.steps",
    "training.noise_sigma",
    "seed",
)
"""The settings shown above the fold; the others are in the "All settings" folder."""

ACTIONS = ("Start", "Pause", "Resume", "Stop")


def enabled_actions(state: JobState | None) -> dict[str, bool]:
    """Which training buttons can act in a job `state` (None: no training started or
    followed): Start when none runs, Pause while running, Resume while paused, Stop while
    running or paused; none while a stop is under way."""
    going = state in ("running", "paused")
    return {
        "Start": not going and state != "stopping",
        "Pause": state == "running",
        "Resume": state == "paused",
        "Stop": going,
    }


@dataclass(frozen=True)
class Estimate:
    """What a training run should cost, from its size and the lab's measured rate."""

    robot_steps: int  # population × generations × steps
    steps_per_core_second: float  # `app.experiments.results.core_steps_per_second`
    workers: int  # the processes that share its lives

    @property
    def core_hours(self) -> float:
        return self.robot_steps / self.steps_per_core_second / 3600

    @property
    def seconds(self) -> float:
        """Wall time on `workers` idle cores."""
        return self.core_hours * 3600 / self.workers

    def describe(self) -> str:
        return (
            f"**Estimate** (before Start): about {duration(self.seconds)} on {self.workers} "
            f"idle core{'s' if self.workers > 1 else ''}, {self.core_hours:.2g} core-hours: "
            f"{self.robot_steps / 1e6:,.4g} M robot-steps (population × generations × steps) "
            f"at the lab's measured {self.steps_per_core_second / 1e6:.2g} M per core-second"
        )


def estimate(config: RunConfig, workers: int | None = None) -> Estimate:
    """The cost of training `config` on `workers` processes (default: one per core, as the
    tab's runs; never more than the population's shards)."""
    workers = min(workers or default_workers(), len(shards(config.training)))
    return Estimate(
        robot_steps=training_steps(config),
        steps_per_core_second=core_steps_per_second(config.training.physics),
        workers=max(1, workers),
    )


def duration(seconds: float) -> str:
    """`40 s`, `12 min`, `3.4 h`."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


@dataclass
class TrainTab:
    """The Train tab's handles, and the training it started (if any)."""

    stage: Stage
    status: Status
    plots: PlotsTab
    runs_dir: Path
    on_run_ended: Callable[[], None]  # a run file is complete: list it
    preset: viser.GuiDropdownHandle[str]
    brain: viser.GuiDropdownHandle[str]
    settings: SettingControls
    buttons: dict[str, viser.GuiButtonHandle]
    progress: ProgressBar
    summary: viser.GuiMarkdownHandle
    cost: viser.GuiMarkdownHandle  # the estimate beside Start
    job: TrainingJob | None = None
    follower: TrainingFollower | None = None
    stage_run: Path | None = None  # the run on show that the training's bests may replace

    def apply_preset(self, name: str) -> None:
        """Fill the fields with a preset's values."""
        if name not in PRESET_NAMES:
            return
        self.settings.show(load_preset(name))

    def show_estimate(self) -> None:
        """The estimate of the run the controls describe (or why there is none)."""
        try:
            config = training_config(self.preset.value, self.settings.values(), self.brain.value)
        except DashboardInputError as error:
            text = f"**Estimate**: none until the settings are valid ({error})"
        else:
            text = estimate(config).describe()
        if self.cost.content != text:
            self.cost.content = text

    def sync_buttons(self) -> None:
        """Enable the buttons that can act on the training as it is now."""
        state = self.job.state if self.job is not None else None
        for name, enabled in enabled_actions(state).items():
            button = self.buttons[name]
            if button.disabled == enabled:  # viser sends every assignment: only changes
                button.disabled = not enabled

    def start(self) -> None:
        if self.job is not None and self.job.active:
            raise DashboardInputError("a training run is already going: stop it first")
        config = training_config(self.preset.value, self.settings.values(), self.brain.value)
        out = new_run_path(self.runs_dir, config)
        self.close()  # a run that ended but was not yet followed to its end
        self.job = TrainingJob(config, out)
        self.follower = TrainingFollower(out, config)
        # The stage follows this run from its first best on, unless another is put on show.
        self.stage_run = self.stage.source
        self.plots.training_line = f"training: started {out.stem}"
        self.status.set(f"training {out.stem} started")
        self.sync_buttons()

    def act(self, action: str) -> None:
        """Pause, resume or stop the training."""
        job = self.job
        if job is None or not job.active:
            raise DashboardInputError("no training is running")
        {"pause": job.pause, "resume": job.resume, "stop": job.stop}[action]()
        self.status.set(f"training {action}d" if action != "stop" else "training stopped")
        self.sync_buttons()

    def follow(self) -> None:
        """Poll the training: plot, put each new best on show, progress; clean up at its end."""
        job, follower = self.job, self.follower
        self.sync_buttons()
        if job is None or follower is None:
            return
        state = job.state  # before reading: a finished job's file is complete
        progress = follower.poll(state, job.elapsed(), job.error() if state == "failed" else "")
        best = progress.best
        on_show = self.stage.source
        if best is not None and on_show in (self.stage_run, job.out):
            self.stage.swap_in(
                f"best of generation {best.generation} (training {job.out.stem})",
                best.robot,
                life=best.life,
                control_period=best.control_period,
                run=job.out.stem,
                source=job.out,
            )
            self.stage_run = on_show = job.out
        history = progress.history
        drawn = self.plots.fitness_points
        if on_show == job.out and history is not None and len(history.best_fitness) != drawn:
            self.plots.set_fitness(history.best_fitness, history.mean_fitness, job.out.stem)
        line = progress.describe()
        if job.phase and (job.compiling or not progress.generations):
            line = f"{job.phase} · {job.elapsed():.0f} s"  # numba's first compile, then done
        self.plots.training_line = f"training: {line} · run {job.out.stem}"
        set_value(self.progress, 100.0 * progress.fraction)
        self.summary.content = line[:1].upper() + line[1:]
        if not progress.ended:
            return
        self.job = self.follower = None
        self.plots.training_ended = True  # its line goes once another run is on show
        self.sync_buttons()
        self.on_run_ended()
        if state == "failed":
            self.status.set(f"⚠ training failed: {progress.error}")
        else:
            self.status.set(f"training {state}: {job.out.stem}")
        job.close()

    def close(self) -> None:
        if self.job is not None:
            self.job.close()
        if self.follower is not None:
            self.follower.close()


def populate_train_tab(
    gui: viser.GuiApi,
    stage: Stage,
    status: Status,
    plots: PlotsTab,
    runs_dir: Path,
    on_run_ended: Callable[[], None],
) -> TrainTab:
    """Add the Train tab's controls (inside the current tab) and attach their callbacks."""
    quick = load_preset("quick")  # the fields start at the quick preset's values
    preset = gui.add_dropdown("Preset", PRESET_NAMES, initial_value="quick")
    brain = gui.add_dropdown(
        "Brain",
        names(),
        initial_value=DEFAULT_BRAIN,
        hint="the brain family to train: GNP (method and judgment below), a neural net "
        "(CMA-ES on an Elman net, NEAT), or one registered from outside (docs/brains.md)",
    )
    everything = train_settings()
    first = [s for key in FIRST for s in everything if s.key == key]
    settings = add_controls(gui, first, quick)
    with gui.add_folder("All settings", expand_by_default=False):
        rest = [s for s in everything if s.key not in FIRST]
        settings.controls.update(add_controls(gui, rest, quick).controls)
    cost = gui.add_markdown("")
    buttons = {name: gui.add_button(name, disabled=name != "Start") for name in ACTIONS}
    tab = TrainTab(
        stage=stage,
        status=status,
        plots=plots,
        runs_dir=runs_dir,
        on_run_ended=on_run_ended,
        preset=preset,
        brain=brain,
        settings=settings,
        buttons=buttons,
        progress=gui.add_progress_bar(0.0),
        summary=gui.add_markdown("Not training."),
        cost=cost,
    )

    def preset_changed(_: object) -> None:
        tab.apply_preset(tab.preset.value)
        tab.show_estimate()

    tab.preset.on_update(preset_changed)
    tab.brain.on_update(lambda _: tab.show_estimate())
    for control in settings.controls.values():
        control.on_update(lambda _: tab.show_estimate())
    tab.show_estimate()
    buttons["Start"].on_click(status.guard(tab.start))
    for name in ACTIONS[1:]:
        buttons[name].on_click(status.guard(partial(tab.act, name.lower())))
    return tab


def new_run_path(runs_dir: Path, config: RunConfig) -> Path:
    """`<brain's stem>-<time>.h5` in `runs_dir` (`CS-fuzzy-…`), numbered if that name is
    taken."""
    runs_dir.mkdir(parents=True, exist_ok=True)
    stem = f"{family_of(config).file_stem}-{time.strftime('%Y%m%d-%H%M%S')}"
    out = runs_dir / f"{stem}.h5"
    suffix = 1
    while out.exists():
        suffix += 1
        out = runs_dir / f"{stem}-{suffix}.h5"
    return out
