"""The task-run panel (in the Runs tab): a Gymnasium task run's fitness plot, the live replay of
its best individual on the task (the task's frame where the arena is, the episode's return so
far in the readout) and its node-transition graph, with observation faults (issue #34, item 2).

A task run on show replaces the robot: the arena is hidden and the task's frame drawn in its
place, the graph shows the task brain's columns (its features and actions), and the robot's
controls (arena, sensor faults, implementation phase) are off until a robot is on show again.
`app.dashboard.task_replay` (and Gymnasium) is imported when the first task run is loaded.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from app import store
from app.dashboard.controls import DashboardInputError
from app.dashboard.network_view import NetworkView
from app.dashboard.status import Status
from app.dashboard.tab_plots import PlotsTab
from app.store.files import Stamp, settled, stamp
from app.tasks.common import TaskError
from app.views.arena_view import ArenaView
from app.views.genome import genome_view
from app.views.graph_view import GraphView
from app.views.scene import SceneFrame
from sim import FAULT_MODES

if TYPE_CHECKING:
    from app.dashboard.task_replay import TaskReplay
    from app.tasks.store import TaskRun

ROBOT_NOTE = (
    "<small>A task run: the arena, the sensor faults (Faults tab) and the implementation phase "
    "are the robot's and are off for it; break the task's observation features here.</small>"
)
NO_FRAME = np.full((8, 12, 3), 245, np.uint8)
"""The image before any frame (a blank)."""


@dataclass
class TaskPanel:
    """The panel's handles, the task run loaded and its replay."""

    server: viser.ViserServer
    status: Status
    plots: PlotsTab
    graph: GraphView
    network: NetworkView
    arena: ArenaView
    folder: viser.GuiFolderHandle
    summary: viser.GuiMarkdownHandle
    generation: viser.GuiNumberHandle[int]
    seed: viser.GuiNumberHandle[int]
    greedy: viser.GuiCheckboxHandle
    speed: viser.GuiSliderHandle[int]
    playing: viser.GuiCheckboxHandle
    features: viser.GuiTextHandle
    mode: viser.GuiDropdownHandle[str]
    fault_step: viser.GuiNumberHandle[int]
    image: viser.ImageHandle
    caption: viser.LabelHandle
    robot_controls: Sequence[Any] = ()  # the robot's controls, off while a task is on show
    path: Path | None = None
    name: str = ""
    replay: TaskReplay | None = None
    frame_line: str = ""  # why there is no frame, if there is none
    frames: int = 0  # frames drawn since the replay started
    _unfinished: Stamp | None = None  # an unfinished run's file stamp, as last read
    _last_frame: np.ndarray | None = field(default=None, repr=False)

    @property
    def active(self) -> bool:
        """Whether a task replay is on show (the robot's loop waits meanwhile)."""
        return self.replay is not None

    def load(self, path: Path, name: str) -> None:
        """Load a task run: its summary and fitness plot, then replay its best on the task."""
        try:
            mark = stamp(path)  # before the read: a change meanwhile is read again
            run = _read(path)
        except (KeyError, ValueError, OSError) as error:  # a damaged file: one line, no trace
            first = str(error).splitlines()[0] if str(error) else type(error).__name__
            raise DashboardInputError(f"cannot read task run {name}: {first}") from None
        if run.generation_done == 0:
            raise DashboardInputError(f"task run {name} has no generation done yet")
        self.path, self.name = path, name
        self._stage(run, mark)
        self.folder.visible = True
        self.start()

    def follow(self) -> None:
        """A task run loaded before it finished (a `gnp-lab train --task` under way, an
        experiment's run): its new generations onto the plot and the summary as the file grows,
        read only when the file changed; the replay on show carries on (*Replay on task* starts
        again on the newest generation)."""
        path = self.path
        if path is None or self.replay is None or self._unfinished is None:
            return  # nothing loaded, a robot on show, or the run finished
        mark = stamp(path)
        if mark is None or (mark == self._unfinished and settled(mark)):
            return  # gone, or unchanged since it was read
        try:
            run = _read(path)
        except (KeyError, ValueError, OSError):  # a torn read while written: the next poll
            return
        if run.generation_done:  # a run begun again under its name: nothing to plot yet
            self._stage(run, mark)

    def _stage(self, run: TaskRun, mark: Stamp | None) -> None:
        """The run's returns per generation on the plot and its summary; an unfinished run is
        followed from its file's stamp `mark` (read again until it settles)."""
        fitness, config = run.fitness, run.config
        total = config.training.generations
        unfinished = run.generation_done < total
        self._unfinished = mark if unfinished else None
        self.plots.task_staged(config.task.id, fitness.max(axis=1), fitness.mean(axis=1), self.name)
        following = " (unfinished: followed as its file grows)" if unfinished else ""
        self.summary.content = (
            f"**{self.name}**: task **{config.task.id}**, {config.description}, population "
            f"{config.training.population}, {run.generation_done}/{total} generations"
            f"{following}, ≤ {config.training.steps} steps, seed {config.seed}  \n"
            f"best return {fitness.max():.1f}  \n" + ROBOT_NOTE
        )

    def start(self) -> None:
        """(Re)start the replay with the panel's settings."""
        from app.dashboard.task_replay import TaskReplay, TaskReplayRequest

        if self.path is None:
            raise DashboardInputError("load a task run first")
        generation = int(self.generation.value)
        request = TaskReplayRequest(
            self.path,
            generation=None if generation == -1 else generation,
            seed=_whole(self.seed.value, "seed"),
            greedy=bool(self.greedy.value),
            faults=self._faults(),
        )
        try:
            replay = TaskReplay(request)
        except TaskError as error:  # a missing extra, a fault out of range: one line
            raise DashboardInputError(str(error)) from None
        replay.speed = float(self.speed.value)
        replay.playing = bool(self.playing.value)
        self.stop()
        self.replay = replay
        self.frames, self.frame_line, self._last_frame = 0, "", None
        self._show(replay)
        self.status.set(
            f"replaying the best of generation {replay.generation} of task run {self.name} "
            f"on {replay.task}"
        )

    def _faults(self) -> tuple[Any, ...]:
        from app.tasks.faults import ObservationFault

        text = self.features.value.strip()
        if not text:
            return ()
        tokens = [t.lower().removeprefix("f") for t in re.split(r"[,\s;]+", text) if t]
        if not all(t.isdigit() for t in tokens):
            raise DashboardInputError(f"features are numbers separated by commas, got {text!r}")
        step = _whole(self.fault_step.value, "fault step")
        mode = self.mode.value
        return (ObservationFault(step, tuple(sorted({int(t) for t in tokens})), mode),)  # type: ignore[arg-type]

    def _show(self, replay: TaskReplay) -> None:
        """The task on show: its frame where the arena was, its brain's graph (GNP) or network
        (a net); a family with neither shows the frame and the readout."""
        from app.dashboard.task_replay import captions, feature_captions

        adapter = replay.adapter
        with self.server.atomic():
            self.arena.set_visible(False)
            self.graph.visible = replay.cfg is not None
            self.network.visible = replay.cfg is None and replay.net is not None
            if replay.cfg is not None:  # GNP's node graph, its columns the task's
                inputs = feature_captions(replay.task, adapter.n_inputs)
                outputs = captions(replay.cfg, adapter, replay.task)
                self.graph.set_genome(genome_view(replay.cfg, replay.population, inputs, outputs))
            elif replay.net is not None:  # a net, drawn at the task's sizes
                self.network.set_network(replay.net, replay.population)
            self.image.visible = self.caption.visible = True
        _robot_controls(self.robot_controls, on=False)
        self.draw()

    def advance(self, seconds: float) -> None:
        if self.replay is not None:
            self.replay.speed = float(self.speed.value)
            self.replay.playing = bool(self.playing.value)
            self.replay.advance(seconds)

    def draw(self, with_text: bool = True) -> None:
        """One frame: the task's picture, the graph and (`with_text`, twice a second in the
        loop) the readout; under the dashboard's lock."""
        replay = self.replay
        if replay is None:
            return
        from app.dashboard.task_frame import FrameError

        try:
            frame = replay.frame()
        except FrameError as error:
            frame, self.frame_line = NO_FRAME, str(error)
        status = replay.status()
        with self.server.atomic():
            if self._last_frame is None or not np.array_equal(frame, self._last_frame):
                self.image.image = np.ascontiguousarray(frame[::-1])  # viser: row 0 at the bottom
                self._last_frame = frame
                self.frames += 1
            snapshot = replay.snapshot()
            if replay.cfg is not None:
                self.graph.update(snapshot)
            elif replay.net is not None:
                self.network.update(snapshot)
            self.caption.text = (
                f"{status.task} · episode {status.episode} (seed {status.seed}) · step {status.t}"
                f" · return {status.episode_return:g}"
            )
        if with_text:
            line = task_line(status, replay.node_words(status.current_node))
            self.plots.set_show_line(line + ("  \n⚠ " + self.frame_line if self.frame_line else ""))

    def stop(self) -> None:
        """End the replay (the task's env closed)."""
        if self.replay is not None:
            self.replay.close()
            self.replay = None

    def leave(self) -> None:
        """A robot is on show again: the arena back, the task's frame hidden, controls on."""
        if self.replay is None and not self.image.visible:
            return
        self.stop()
        with self.server.atomic():
            self.image.visible = self.caption.visible = False
            self.arena.set_visible(True)
        _robot_controls(self.robot_controls, on=True)

    def export(self) -> Path:
        """The loaded task run's controller and fitness, as `gnp-lab export` writes them, into
        `<runs dir>/exports/<run>-g<G>/`."""
        from app.tasks.cli import export

        if self.path is None or self.replay is None:
            raise DashboardInputError("load a task run first")
        g = self.replay.generation
        out = self.path.parent / "exports" / f"{self.path.stem}-g{g}"
        try:
            export(self.path, out, g)
        except store.RunFileError as error:
            raise DashboardInputError(str(error)) from None
        self.status.set(f"exported task run {self.path.stem} to {out}")
        return out

    def close(self) -> None:
        self.stop()


def task_line(status: Any, node: str) -> str:
    """The readout's lines about a task replay (what the browser test reads)."""
    returns = status.returns[-5:]
    last = " · last returns " + ", ".join(f"{r:g}" for r in returns) if returns else ""
    broken = ", ".join(f"f{j}" for j in status.broken) or "none"
    return (
        f"on show: task {status.task} · generation {status.generation} · episode "
        f"{status.episode} · step {status.t} · return {status.episode_return:g}{last}  \n"
        f"{node} · action {status.action} · broken features: {broken}"
    )


def _read(path: Path) -> TaskRun:
    """`read_task_run`, imported on first use: `app.tasks.store` brings Gymnasium in, which the
    page leaves out until a task run is loaded."""
    from app.tasks.store import read_task_run

    return read_task_run(path)


def _robot_controls(handles: Sequence[Any], on: bool) -> None:
    """The robot's controls on or off (a button group cannot be disabled in viser: hidden)."""
    for handle in handles:
        if isinstance(handle, viser.GuiButtonGroupHandle):
            handle.visible = on
        else:
            handle.disabled = not on


def _whole(value: float, what: str) -> int:
    if not float(value).is_integer() or value < 0:
        raise DashboardInputError(f"{what} must be a whole number ≥ 0, got {value}")
    return int(value)


def populate_task_panel(
    gui: viser.GuiApi,
    server: viser.ViserServer,
    status: Status,
    plots: PlotsTab,
    views: tuple[GraphView, NetworkView, ArenaView],
    frame: SceneFrame,
) -> TaskPanel:
    """Add the panel (a folder, hidden until a task run is loaded) and the scene's image, which
    takes the arena's place (scaled to its width, centred on it)."""
    graph, network, arena = views
    folder = gui.add_folder("Task run", visible=False)
    with folder:
        summary = gui.add_markdown("")
        generation = gui.add_number("Generation (−1 = last)", -1, step=1)
        seed = gui.add_number("Episode seed", 0, min=0, step=1)
        greedy = gui.add_checkbox("Greedy (ε = 0)", initial_value=True)
        speed = gui.add_slider("Task steps / s", min=1, max=200, step=1, initial_value=30)
        playing = gui.add_checkbox("Task playing", initial_value=True)
        features = gui.add_text("Break features", "")
        mode = gui.add_dropdown("Feature fault", tuple[str, ...](FAULT_MODES), initial_value="dead")
        fault_step = gui.add_number("Feature fault step", 50, min=0, step=1)
        buttons = gui.add_button_group("Task", ("Replay on task", "Export task run"))
    arena_bottom = frame.graph_origin[1] + frame.graph_height + 0.12 * frame.width
    height = frame.ymax - arena_bottom
    width = min(frame.width, 1.5 * height)
    center = ((frame.xmin + frame.xmax) / 2, (arena_bottom + frame.ymax) / 2, 0.002)
    image = server.scene.add_image(
        "/task/frame", NO_FRAME, width, width * 2 / 3, position=center, visible=False,
        format="jpeg", jpeg_quality=80, cast_shadow=False, receive_shadow=False,
    )  # fmt: skip
    caption = server.scene.add_label(
        "/task/caption",
        "",
        position=(center[0] - width / 2, center[1] + width / 3 + 0.01, 0.0),
        anchor="bottom-left",
        visible=False,
    )
    panel = TaskPanel(
        server, status, plots, graph, network, arena, folder, summary, generation, seed,
        greedy, speed, playing, features, mode, fault_step, image, caption,
    )  # fmt: skip

    def export() -> None:
        panel.export()

    actions = {"Replay on task": panel.start, "Export task run": export}
    buttons.on_click(lambda event: status.guarded(event.client, actions[buttons.value]))
    return panel
