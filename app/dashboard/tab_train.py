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

import numpy as np
import viser

from app.brains.registry import family_of, names
from app.dashboard.controls import DashboardInputError, training_config
from app.dashboard.follower import TrainingFollower
from app.dashboard.setting_controls import SettingControls, add_controls
from app.dashboard.stage import Stage
from app.dashboard.status import ProgressBar, Status, set_value
from app.dashboard.tab_plots import PlotsTab
from app.dashboard.training_job import JobState, TrainingJob
from app.settings.config import DEFAULT_BRAIN, PRESET_NAMES, RunConfig
from app.settings.loading import load_preset, train_settings

FIRST = (
    "controller.method",
    "controller.fuzzy",
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
    job: TrainingJob | None = None
    follower: TrainingFollower | None = None

    def apply_preset(self, name: str) -> None:
        """Fill the fields with a preset's values."""
        if name not in PRESET_NAMES:
            return
        self.settings.show(load_preset(name))

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
        self.plots.set_fitness(np.zeros(0), np.zeros(0))
        self.plots.training_line = f"training: started {out.name}"
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
        if best is not None:
            self.stage.swap_in(
                f"best of generation {best.generation} (training {job.out.stem})",
                best.robot,
                life=best.life,
                control_period=best.control_period,
            )
        history = progress.history
        if history is not None and len(history.best_fitness) != self.plots.fitness_points:
            self.plots.set_fitness(history.best_fitness, history.mean_fitness)
        line = progress.describe()
        self.plots.training_line = f"training: {line}"
        set_value(self.progress, 100.0 * progress.fraction)
        self.summary.content = line[:1].upper() + line[1:]
        if not progress.ended:
            return
        self.job = self.follower = None
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
    )

    tab.preset.on_update(lambda _: tab.apply_preset(tab.preset.value))
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
