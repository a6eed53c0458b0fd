"""The GNP Lab dashboard: a viser server showing robots, their graphs and plots, live.

State lives on the server (viser's server-level scene and GUI are shared by every tab). One
background thread steps the live robots at a steady rate and redraws; GUI callbacks only change
settings under a lock, so the page answers at once even while training runs (a thread of this
process whose robots live in worker processes; `training_job.py`).

This module composes the page: the scene, the status line, a module per tab (`tab_*.py`), the
stage of robots on show (`stage.py`), and the loop.
"""

from __future__ import annotations

import signal
import threading
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np
import viser

import gnp
import neuro
from app import store
from app.dashboard.network_view import NetworkView
from app.dashboard.runs_watch import RunsWatch
from app.dashboard.stage import Show, Stage, random_show
from app.dashboard.status import Status
from app.dashboard.tab_compare import populate_compare_tab
from app.dashboard.tab_experiments import populate_experiments_tab
from app.dashboard.tab_faults import populate_faults_tab
from app.dashboard.tab_plots import populate_plots_tab
from app.dashboard.tab_runs import populate_runs_tab
from app.dashboard.tab_show import populate_show_tab
from app.dashboard.tab_task import populate_task_panel
from app.dashboard.tab_train import populate_train_tab
from app.phases.live import LiveSession
from app.system.signals import raise_interrupt
from app.views.arena_view import ArenaView
from app.views.graph_counts import SIMPLIFIED
from app.views.graph_view import GraphView
from app.views.scene import aim_camera, scene_frame

TAB_NAMES = ("Show", "Train", "Faults", "Runs", "Compare", "Experiments")
PANEL_WIDTH = 370
TIGHT_TABS = "<style>[role=tab][data-dock-tab] { padding: 0 0.55em !important; }</style>"
"""Less room around a tab's name than viser's 0.9em (its tabs set it inline)."""
FRAME_SECONDS = 1 / 10
PLOT_SECONDS = 0.5
FOLLOW_SECONDS = 0.5
# The loop leaves the lock free at least this long after each frame. Python's locks are not
# fair: on a loaded machine, where a frame outlasts FRAME_SECONDS, a loop that took the lock
# back at once kept a control's callback waiting for it for tens of seconds.
MIN_PAUSE_SECONDS = 0.01


class Dashboard:
    """Builds the page on `server` and runs its live loop until `stop()`.

    Args:
        server: the viser server to draw on.
        runs_dir: directory of run files (listed, loaded, and where new runs are written).
        run: name of the run to show first (default: `demo` if present, else the newest).
    """

    def __init__(self, server: viser.ViserServer, runs_dir: Path, run: str | None = None) -> None:
        self.server = server
        self.runs_dir = Path(runs_dir)
        self.runs_watch = RunsWatch(self.runs_dir)
        self._robot_runs: list[str] | None = None  # the robot runs the Compare tab offers
        self.lock = threading.RLock()
        self._stop = threading.Event()
        self.stage = Stage()
        self._build_scene()

        gui = server.gui
        gui.configure_theme(control_width="large", show_share_button=False)
        gui.set_panel_label("GNP Lab")
        gui.main_panel.dock_right()
        gui.main_panel.set_width(PANEL_WIDTH)
        self.status = Status(gui, self.lock)
        gui.add_html(TIGHT_TABS)
        tabs = gui.add_tab_group()
        # Names without icons, closer together: else the six tabs take two rows of the panel.
        show, train, faults, runs, compare, experiments = (tabs.add_tab(name) for name in TAB_NAMES)
        self.plots = populate_plots_tab(gui)  # in its own panel, docked left
        with show:
            self.show = populate_show_tab(
                gui, self.stage, self.status, self.graph_view, self.network_view, self.runs_dir
            )
        with train:
            self.train = populate_train_tab(
                gui, self.stage, self.status, self.plots, self.runs_dir, self.refresh_runs
            )
        with faults:
            self.faults = populate_faults_tab(
                gui, self.stage, self.status, self.show.echo_new_lives
            )
        with runs:
            self.runs = populate_runs_tab(
                gui, self.stage, self.status, self.plots, self.runs_dir, self.refresh_runs
            )
            views = (self.graph_view, self.network_view, self.arena_view)
            self.task = populate_task_panel(
                gui, server, self.status, self.plots, views, self.scene_frame
            )
        self.runs.load_task = self.task.load
        self.runs.leave_task = self._leave_task
        faults_buttons = (self.faults.buttons,) if self.faults.buttons is not None else ()
        self.task.robot_controls = (
            *self.runs.robot_only,
            self.faults.sensors,
            self.faults.mode,
            *faults_buttons,
        )
        with compare:
            self.compare = populate_compare_tab(gui, self.stage, self.status, self.runs_dir)
        with experiments:
            self.experiments = populate_experiments_tab(
                gui, self.status, self.runs_dir, self._show_run_file
            )

        self.stage.on_staged(self._staged)
        self._show_first(run, self.runs_watch.look(again=True))
        self._thread = threading.Thread(target=self._loop, name="dashboard-loop", daemon=True)
        self._thread.start()

    def _build_scene(self) -> None:
        """Arena on top, graph below it (they share the width), camera looking straight down."""
        frame = self.scene_frame = scene_frame(list(self.stage.arenas.values()))
        self.arena_view = ArenaView(self.server, self.stage.arenas["training"])
        graph_box = (frame.graph_origin, frame.width, frame.graph_height)
        self.graph_view = GraphView(self.server, *graph_box)
        self.graph_view.set_mode(SIMPLIFIED)  # the program the robot runs; full is a click away
        # A neural net on show draws its network in the same place (one of the two is hidden).
        self.network_view = NetworkView(self.server, *graph_box)
        aim_camera(self.server, frame, headroom=0.03)

        @self.graph_view.nodes_handle.on_click
        def _(event: viser.SceneNodePointerEvent[Any]) -> None:
            origin, direction = np.array(event.ray_origin), np.array(event.ray_direction)
            if abs(direction[2]) < 1e-9:
                return
            hit = origin - direction * (origin[2] / direction[2])
            node = self.graph_view.node_at(hit[:2])
            if node is not None:
                self.status.guarded(event.client, lambda: self._inspect(node))

    def _inspect(self, node: int) -> None:
        """A node clicked: the robot's in the inspector, a task brain's in the status line."""
        replay = self.task.replay
        if replay is None:
            self.show.inspect(node)
            return
        self.graph_view.select(node)
        self.status.set(f"{replay.task} brain: {replay.node_words(node)}")

    def _staged(self, show: Show, session: LiveSession) -> None:
        """A new show on the stage: its arena, graph, Show tab and reward chart (a task replay
        on show gives way to it)."""
        self.task.leave()
        self.arena_view.set_arena(session.arena)
        self.show.staged(show)
        self.plots.staged(show, self.stage.selected)

    def _leave_task(self) -> None:
        """A robot run loaded while a task replay is on show: the robot's show again."""
        if self.task.active:
            self.stage.restage()  # its `_staged` puts the arena and the robot's graph back

    def _show_run_file(self, path: Path) -> None:
        """Load a run file inside the runs dir (an experiment's run): its best on show."""
        self.runs.load_file(path)

    def refresh_runs(self) -> None:
        """Re-read the runs dir into every list of runs on the page (*Refresh list*)."""
        self._list_runs(self.runs_watch.look(again=True))

    def follow_runs(self) -> None:
        """The lists of runs follow the runs dir: runs added, removed or being written."""
        self._list_runs(self.runs_watch.look())

    def _list_runs(self, runs: list[store.RunSummary] | None) -> None:
        if runs is None:
            return
        self.runs.list_runs(runs)
        robots = [r.name for r in runs if r.error is None and not r.task]
        if robots != self._robot_runs:  # the Compare tab's choices change only with the list
            self._robot_runs = robots
            self.compare.list_runs(robots)

    def _show_first(self, run: str | None, runs: list[store.RunSummary] | None) -> None:
        """List `runs` (the runs dir's, read once) and show `run`, else `demo`, else the newest
        run, else an untrained random individual."""
        runs = runs or []
        self._list_runs(runs)
        names = [s.name for s in runs if s.error is None and not s.task]
        if run is not None and run in {s.name for s in runs if s.task}:
            self.stage.present(random_show())  # what a robot show starts from later
            self.runs.load(run)  # a task run: its replay on show
            return
        choice = run if run is not None else ("demo" if "demo" in names else None)
        if choice is None and names:
            choice = names[-1]
        if choice is not None:
            try:
                self.runs.load(choice)  # its final best on show
                return
            except (store.RunFileError, gnp.GnpError, neuro.NeuroError) as error:
                if run is not None:
                    raise
                self.status.set(f"⚠ could not load {choice}: {error}")
        self.stage.present(random_show())
        tasks = any(s.task for s in runs)
        none = "no robot runs (task runs: load one in the Runs tab)" if tasks else "no runs"
        self.status.set(
            f"{none} in {self.runs_dir} — showing an untrained random individual; "
            "train one in the Train tab"
        )

    def _loop(self) -> None:
        last = time.monotonic()
        next_plot = next_follow = 0.0
        while not self._stop.is_set():
            frame_start = time.monotonic()
            try:
                with self.lock:
                    with_plots = frame_start >= next_plot
                    if with_plots:
                        next_plot = frame_start + PLOT_SECONDS
                    if self.task.active:  # a task run on show: its replay, the robot waits
                        self.task.advance(frame_start - last)
                        self.task.draw(with_plots)
                    else:
                        self.stage.advance(frame_start - last)
                        if self.stage.session is not None:
                            self._draw(self.stage.session, with_plots)
                    last = frame_start
                    if frame_start >= next_follow:
                        next_follow = frame_start + FOLLOW_SECONDS
                        self.train.follow()
                        self.runs.follow_implementation()
                        self.experiments.follow()
                        self.task.follow()
                        self.show.refresh()
                        self.follow_runs()
            except Exception:  # keep the page alive; say what went wrong
                self.status.set(
                    "⚠ internal error: " + traceback.format_exc(limit=1).splitlines()[-1]
                )
                traceback.print_exc()
                time.sleep(0.5)
            pause = FRAME_SECONDS - (time.monotonic() - frame_start)
            self._stop.wait(max(MIN_PAUSE_SECONDS, pause))

    def _draw(self, session: LiveSession, with_plots: bool) -> None:
        robots = session.snapshot()
        with self.server.atomic():
            self.arena_view.update(robots)
            chosen = robots[min(self.stage.selected, len(robots) - 1)]
            if self.network_view.visible:
                self.network_view.update(chosen)
            else:
                self.graph_view.update(chosen)
            if with_plots:
                self.plots.draw(robots, self.stage.noise_sigma)

    def stop(self) -> None:
        """Stop the loop, any training, implementation or experiment, and close files."""
        self._stop.set()
        self._thread.join(timeout=5)
        self.runs.wait_for_export()  # a replay being written is finished, not cut
        with self.lock:
            self.train.close()
            self.runs.close()
            self.task.close()
            self.experiments.close()


def serve(host: str, port: int, runs_dir: Path, run: str | None) -> None:
    """Serve the dashboard until interrupted (Ctrl-C); blocking.

    Args:
        host: interface to bind (127.0.0.1 by default in the CLI: only this machine).
        port: TCP port.
        runs_dir: directory of run files.
        run: run to show first (default `demo` if present).
    """
    server = viser.ViserServer(host=host, port=port, verbose=False)
    dashboard = Dashboard(server, Path(runs_dir), run)
    # SIGTERM ends the server like Ctrl-C, so a training run it started is stopped, not orphaned.
    signal.signal(signal.SIGTERM, raise_interrupt)
    bound = server.get_port()  # viser moves on to the next free port if `port` is taken
    if bound != port:
        print(f"port {port} is in use; serving on {bound} instead", flush=True)
    print(f"GNP Lab dashboard on http://{host}:{bound}  (Ctrl-C to stop)", flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        dashboard.stop()
        server.stop()
