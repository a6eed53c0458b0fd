"""The left panel's Plots tab: a plain-text readout of the state, and the three charts.

The readout is what the browser tests read: each part of the dashboard sets its own line.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import viser

from app import store
from app.dashboard import plots
from app.dashboard.stage import Show
from app.phases.implementation import fault_text
from app.phases.live import RobotSnapshot


@dataclass
class PlotsTab:
    """The readout, its lines, and the reward, fitness and implementation charts."""

    readout: viser.GuiMarkdownHandle
    reward: viser.GuiUplotHandle
    fitness: viser.GuiUplotHandle
    implementation: viser.GuiUplotHandle
    show_line: str = "on show: nothing"
    training_line: str = "training: idle"
    implementation_line: str = "implementation: none run"
    fitness_points: int = 0  # generations on the fitness chart
    fitness_run: str = ""  # the run they are of
    training_ended: bool = False  # the training line tells of a run that has ended
    source: Path | None = None  # the run file the fitness and implementation charts are of
    staged_once: bool = False

    def staged(self, show: Show, selected: int = 0) -> None:
        """A new show: one reward curve per robot; a show of another run (of the `selected`
        robot, the one whose graph is drawn) switches the fitness and implementation charts
        to that run's (or empties them), so no chart names another run than the one on show."""
        labels = [r.label for r in show.robots]
        plots.set_reward_series(self.reward, labels)
        names = [show.origin(i)[0] or label for i, label in enumerate(labels)]
        title = f"Reward per step · {', '.join(names)}"
        if self.reward.title != title:
            self.reward.title = title
        run, source = show.origin(selected)
        if self.staged_once and source == self.source:
            return  # the same run: a new life, another generation, the same charts
        self.staged_once, self.source = True, source
        if self.training_ended:
            self.training_line, self.training_ended = "training: idle", False
        name = run or labels[selected]
        if source is None:
            self.set_fitness(np.zeros(0), np.zeros(0), name)
            self.clear_implementation(f"implementation: {name} has none")
            return
        try:
            with store.RunReader(source) as reader:
                history = reader.history()
                stored = stored_implementation(reader)
        except store.RunFileError as error:  # e.g. a file cut mid-write: the charts say so
            self.set_fitness(np.zeros(0), np.zeros(0), f"{name} (unreadable: {error})")
            self.clear_implementation(f"implementation: {name} unreadable")
            return
        self.set_fitness(history.best_fitness, history.mean_fitness, name)
        if stored is None:
            self.clear_implementation(f"implementation: none stored in {name}")
        else:
            self.show_implementation(f"{name}/{stored[0]}", stored[1])

    def clear_implementation(self, line: str) -> None:
        """An empty implementation chart, and why."""
        plots.set_implementation(self.implementation, np.zeros(0), 0)
        self.implementation.title = plots.IMPLEMENTATION_TITLE
        self.implementation_line = line

    def draw(self, robots: tuple[RobotSnapshot, ...], noise_sigma: float) -> None:
        """The robots' reward curves and the readout."""
        plots.set_rewards(self.reward, robots)
        self.set_show_line(show_line(robots, noise_sigma))

    def set_show_line(self, line: str) -> None:
        """The readout with another line about what is on show (a task replay's)."""
        self.show_line = line
        self.readout.content = "  \n".join(
            [
                line,
                self.training_line,
                f"fitness plot: {self.fitness_points} generations of {self.fitness_run or '—'}",
                self.implementation_line,
            ]
        )

    def set_fitness(self, best: np.ndarray, mean: np.ndarray, run: str = "") -> None:
        """Best and mean fitness per generation of `run`."""
        plots.set_fitness(self.fitness, best, mean, run=run)
        self.fitness_points = len(best)
        self.fitness_run = run

    def task_staged(self, task: str, best: np.ndarray, mean: np.ndarray, run: str = "") -> None:
        """A task run on show: its returns per generation; the robot's charts emptied."""
        plots.set_fitness(self.fitness, best, mean, returns=True, run=run or task)
        self.fitness_points, self.fitness_run = len(best), run or task
        self.staged_once = False  # the robot's next show sets its charts again
        plots.set_reward_series(self.reward, [])
        self.reward.title = plots.REWARD_TITLE  # no robot on show: no run named
        self.clear_implementation(f"implementation: the robot's (none for {task})")

    def show_implementation(self, name: str, result: store.Implementation) -> None:
        settings = result.settings
        broken = len(settings.broken_sensors) or settings.break_count
        plots.set_implementation(
            self.implementation, result.reward_per_step, settings.fault_step, broken
        )
        title = f"{plots.IMPLEMENTATION_TITLE} · {name}"
        if self.implementation.title != title:
            self.implementation.title = title
        sensors = ", ".join(f"s{s}" for s in settings.broken_sensors) or "none"
        self.implementation_line = (
            f"implementation: {name} · {len(result.trial_mean_reward)} trials · breaks {sensors} "
            f"({settings.fault_mode}) at {settings.fault_step} · mean reward/step "
            f"{result.mean_reward:.4f}, after the fault {result.mean_after_fault:.4f}"
        )


def stored_implementation(
    reader: store.RunReader,
) -> tuple[str, store.Implementation] | None:
    """The implementation phase a run file stores that its chart shows first: the last with a
    fault (what the chart's fault marker is for), else the last; None if it stores none."""
    names = reader.implementation_names()
    if not names:
        return None
    results = {name: reader.implementation(name) for name in names}
    faulted = [n for n, r in results.items() if r.settings.broken_sensors]
    shown = (faulted or names)[-1]
    return shown, results[shown]


def populate_plots_tab(gui: viser.GuiApi) -> PlotsTab:
    """Add the Plots tab in a panel docked on the left."""
    panel = gui.add_panel()
    with panel.add_tab("Plots", viser.Icon.CHART_LINE):
        tab = PlotsTab(
            readout=gui.add_markdown(""),
            reward=plots.reward_plot(gui),
            fitness=plots.fitness_plot(gui),
            implementation=plots.implementation_plot(gui),
        )
    panel.dock_left()
    panel.set_width(360)
    return tab


def show_line(robots: Sequence[RobotSnapshot], noise_sigma: float) -> str:
    """The readout's lines about the robots on show (also what the browser tests read)."""
    first = robots[0]
    rewards = " · ".join(f"{r.label}: reward/step {r.mean_reward:.3f}" for r in robots)
    sub = f" sub {first.visits[-1, 1]}" if len(first.visits) else ""
    if not first.learns_online:  # a net, or another family: no node, nothing learnt online
        left, right = first.commands
        brain = f"wheels {left:+.1f} {right:+.1f} · no online learning"
    else:
        brain = f"node {first.current_node}{sub} · ε {first.epsilon:.3f} α {first.alpha:.3f}"
    lines = [f"on show: step {first.t} · {rewards} · {brain} · noise σ {noise_sigma:g}"]
    broken = [int(i) for i in np.flatnonzero(first.broken)]
    if broken:
        since = first.fault_steps[-1] if first.fault_steps else None
        lines.append(fault_text(broken, str(first.fault_mode), since))
    else:
        lines.append("broken: none")
    plot = f"reward plot: {len(first.rewards)} steps"
    if first.fault_steps:
        fault = first.fault_steps[-1]
        before = first.rewards[first.reward_steps < fault]
        after = first.rewards[first.reward_steps >= fault]
        plot += f" · fault marked at step {fault}"
        if len(before) and len(after):
            plot += f" · reward/step before {before.mean():.3f}, after {after.mean():.3f}"
    lines.append(plot)
    return "  \n".join(lines)
