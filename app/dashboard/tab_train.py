"""The Train tab: a run's settings, Start / Pause / Resume / Stop, and its progress.

Training runs as `gnp-lab train` in its own process (`TrainingJob`); a `TrainingFollower`
reads its file as it grows, and each new generation's best goes on show at once.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import viser
from viser._gui_handles import GuiProgressBarHandle  # not exported by viser 1.1.1

import gnp
import sim
from app.config import PRESET_NAMES, RunConfig, load_preset
from app.dashboard.controls import DashboardInputError, TrainingRequest, training_config
from app.dashboard.follower import TrainingFollower
from app.dashboard.stage import Stage
from app.dashboard.status import Status, set_value
from app.dashboard.tab_plots import PlotsTab
from app.dashboard.training_job import TrainingJob

JUDGMENTS = ("fuzzy", "crisp")


@dataclass
class TrainTab:
    """The Train tab's handles, and the training it started (if any)."""

    stage: Stage
    status: Status
    plots: PlotsTab
    runs_dir: Path
    on_run_ended: Callable[[], None]  # a run file is complete: list it
    method: viser.GuiDropdownHandle[gnp.Method]
    judgment: viser.GuiDropdownHandle[str]
    preset: viser.GuiDropdownHandle[str]
    population: viser.GuiNumberHandle[int]
    generations: viser.GuiNumberHandle[int]
    steps: viser.GuiNumberHandle[int]
    noise: viser.GuiNumberHandle[float]
    seed: viser.GuiNumberHandle[int]
    progress: GuiProgressBarHandle
    summary: viser.GuiMarkdownHandle
    job: TrainingJob | None = None
    follower: TrainingFollower | None = None

    def apply_preset(self, name: str) -> None:
        """Fill the fields with a preset's values."""
        if name not in PRESET_NAMES:
            return
        preset = load_preset(name)
        set_value(self.method, preset.controller.method)
        set_value(self.judgment, judgment_of(preset))
        set_value(self.population, preset.training.population)
        set_value(self.generations, preset.training.generations)
        set_value(self.steps, preset.training.steps)
        set_value(self.noise, preset.training.noise_sigma)

    def start(self) -> None:
        if self.job is not None and self.job.active:
            raise DashboardInputError("a training run is already going: stop it first")
        config = training_config(
            TrainingRequest(
                preset=self.preset.value,
                method=self.method.value,
                judgment=self.judgment.value,
                population=self.population.value,
                generations=self.generations.value,
                steps=self.steps.value,
                noise_sigma=self.noise.value,
                seed=self.seed.value,
            )
        )
        out = new_run_path(self.runs_dir, config)
        self.close()  # a run that ended but was not yet followed to its end
        self.job = TrainingJob(config, out)
        self.follower = TrainingFollower(out, config)
        self.plots.set_fitness(np.zeros(0), np.zeros(0))
        self.plots.training_line = f"training: started {out.name}"
        self.status.set(f"training {out.stem} started")

    def act(self, action: str) -> None:
        """Pause, resume or stop the training."""
        job = self.job
        if job is None or not job.active:
            raise DashboardInputError("no training is running")
        {"pause": job.pause, "resume": job.resume, "stop": job.stop}[action]()
        self.status.set(f"training {action}d" if action != "stop" else "training stopped")

    def follow(self) -> None:
        """Poll the training: plot, put each new best on show, progress; clean up at its end."""
        job, follower = self.job, self.follower
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
    training = quick.training
    method = gui.add_dropdown("Method", gnp.METHODS, initial_value=quick.controller.method)
    judgment = gui.add_dropdown("Judgment", JUDGMENTS, initial_value=judgment_of(quick))
    preset = gui.add_dropdown("Preset", PRESET_NAMES, initial_value="quick")
    population = gui.add_number("Population", training.population, min=2, max=100_000, step=1)
    generations = gui.add_number("Generations", training.generations, min=1, max=1_000_000, step=1)
    steps = gui.add_number("Life T (steps)", training.steps, min=1, max=1_000_000, step=1)
    noise = gui.add_number("Noise σ", training.noise_sigma, min=0.0, max=sim.IR_MAX, step=1.0)
    seed = gui.add_number("Seed", quick.seed, min=0, max=2**31 - 1, step=1)
    buttons = gui.add_button_group("Training", ("Start", "Pause", "Resume", "Stop"))
    tab = TrainTab(
        stage=stage,
        status=status,
        plots=plots,
        runs_dir=runs_dir,
        on_run_ended=on_run_ended,
        method=method,
        judgment=judgment,
        preset=preset,
        population=population,
        generations=generations,
        steps=steps,
        noise=noise,
        seed=seed,
        progress=gui.add_progress_bar(0.0),
        summary=gui.add_markdown("Not training."),
    )

    tab.preset.on_update(lambda _: tab.apply_preset(tab.preset.value))
    actions: dict[str, Callable[[], None]] = {
        "Start": tab.start,
        "Pause": lambda: tab.act("pause"),
        "Resume": lambda: tab.act("resume"),
        "Stop": lambda: tab.act("stop"),
    }
    buttons.on_click(lambda event: status.guarded(event.client, actions[buttons.value]))
    return tab


def judgment_of(config: RunConfig) -> str:
    return "fuzzy" if config.controller.fuzzy else "crisp"


def new_run_path(runs_dir: Path, config: RunConfig) -> Path:
    """`<method>-<judgment>-<time>.h5` in `runs_dir`, numbered if that name is taken."""
    runs_dir.mkdir(parents=True, exist_ok=True)
    stem = f"{config.controller.method}-{judgment_of(config)}-{time.strftime('%Y%m%d-%H%M%S')}"
    out = runs_dir / f"{stem}.h5"
    suffix = 1
    while out.exists():
        suffix += 1
        out = runs_dir / f"{stem}-{suffix}.h5"
    return out
