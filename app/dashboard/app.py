"""The GNP Lab dashboard: a viser server showing robots, their graphs and plots, live.

State lives on the server (viser's server-level scene and GUI are shared by every tab). One
background thread steps the live robots at a steady rate and redraws; GUI callbacks only change
settings under a lock, so the page answers at once even while training runs (in its own process).
"""

from __future__ import annotations

import dataclasses
import signal
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import viser

import gnp
import sim
from app import store
from app.config import PRESET_NAMES, load_preset
from app.dashboard import geometry as geo
from app.dashboard import plots
from app.dashboard.controls import (
    DashboardInputError,
    TrainingRequest,
    finite,
    parse_mode,
    parse_sensors,
    training_config,
    whole,
)
from app.dashboard.genome import genome_view, node_label, node_markdown
from app.dashboard.implementation_job import ImplementationJob, ImplementationRequest
from app.dashboard.jobs import TrainingJob
from app.dashboard.scene import ROBOT_COLORS, TRANSITION_STYLES, ArenaView, GraphView
from app.live import (
    FAULT_MODES,
    LearningSettings,
    LiveError,
    LiveSession,
    RobotSnapshot,
    RobotSpec,
)

FRAME_SECONDS = 1 / 10
PLOT_SECONDS = 0.5
FOLLOW_SECONDS = 0.5


@dataclass(frozen=True)
class Show:
    """What is on show: robots, arena, start pose, and where they came from."""

    title: str
    robots: tuple[RobotSpec, ...]
    arena: str
    start: int
    fault: tuple[int, tuple[int, ...], str] | None = None  # scheduled (step, sensors, mode)
    life: int = 0  # steps per life, as in training (then the next start pose); 0: endless
    control_period: float = 0.064  # simulated seconds per step, the run's setting


def _set(handle: Any, value: object) -> None:
    """Assign a GUI input's value (viser's typing marks the setter read-only)."""
    handle.value = value


def _hex(color: tuple[int, int, int]) -> str:
    return "#{:02x}{:02x}{:02x}".format(*color)


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
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._arenas = {name: sim.load_arena(name) for name in sim.ARENA_NAMES}
        self.session: LiveSession | None = None
        self.show: Show | None = None
        self.speed = 30.0
        self.playing = True
        self.noise_sigma = 0.0
        self.learning = LearningSettings()
        self.job: TrainingJob | None = None
        self.job_reader: store.RunReader | None = None
        self.job_shown_generation = -1
        self._job_history: store.History | None = None
        self._job_retries = 0
        self.implementation: ImplementationJob | None = None
        self.loaded: store.RunReader | None = None
        self._status = "starting"
        self._show_line = "on show: nothing"
        self._training_line = "training: idle"
        self._implementation_line = "implementation: none run"
        self._fitness_points = 0

        server.gui.configure_theme(control_width="large", show_share_button=False)
        server.gui.set_panel_label("GNP Lab")
        server.gui.main_panel.dock_right()
        server.gui.main_panel.set_width(370)
        self._build_scene()
        self._build_controls()
        self._build_plots()
        self._refresh_run_lists()
        self._show_initial(run)
        self._thread = threading.Thread(target=self._loop, name="dashboard-loop", daemon=True)
        self._thread.start()

    # --- layout -------------------------------------------------------------------------

    def _build_scene(self) -> None:
        """Arena on top, graph below it (they share the width), camera looking straight down."""
        bounds = np.array([a.bounds for a in self._arenas.values()]) * geo.MM
        xmin, ymin = bounds[:, :2].min(axis=0)
        xmax, ymax = bounds[:, 2:].max(axis=0)
        width = xmax - xmin
        self.arena_view = ArenaView(self.server, self._arenas["training"])
        graph_height = 0.62 * width
        graph_origin = (xmin, ymin - 0.12 * width - graph_height)
        self.graph_view = GraphView(self.server, graph_origin, width, graph_height)
        bottom, top = graph_origin[1] - 0.05 * width, ymax + 0.03 * width
        center = ((xmin + xmax) / 2, (bottom + top) / 2)
        fov = np.radians(50.0)
        distance = 1.08 * (top - bottom) / 2 / np.tan(fov / 2)
        self.server.scene.set_up_direction("+y")
        camera = self.server.initial_camera
        camera.up = (0.0, 1.0, 0.0)
        camera.look_at = (center[0], center[1], 0.0)
        camera.position = (center[0], center[1], distance)
        camera.fov = fov
        camera.far = 100.0

        @self.graph_view.nodes_handle.on_click
        def _(event: viser.SceneNodePointerEvent[Any]) -> None:
            origin, direction = np.array(event.ray_origin), np.array(event.ray_direction)
            if abs(direction[2]) < 1e-9:
                return
            hit = origin - direction * (origin[2] / direction[2])
            node = self.graph_view.node_at(hit[:2])
            if node is not None:
                self._inspect(node)

    def _build_controls(self) -> None:
        gui = self.server.gui
        self.status_md = gui.add_markdown("**Status:** starting")
        tabs = gui.add_tab_group()
        with tabs.add_tab("Show", viser.Icon.EYE):
            self._build_show_tab()
        with tabs.add_tab("Train", viser.Icon.SCHOOL):
            self._build_train_tab()
        with tabs.add_tab("Faults", viser.Icon.BOLT):
            self._build_faults_tab()
        with tabs.add_tab("Runs", viser.Icon.DATABASE):
            self._build_runs_tab()
        with tabs.add_tab("Compare", viser.Icon.ARROWS_LEFT_RIGHT):
            self._build_compare_tab()

    def _build_show_tab(self) -> None:
        gui = self.server.gui
        self.show_md = gui.add_markdown("nothing on show yet")
        self.arena_dropdown = gui.add_dropdown("Arena", sim.ARENA_NAMES, initial_value="training")
        self.start_dropdown = gui.add_dropdown(
            "Start pose", tuple(str(i) for i in range(10)), initial_value="0"
        )
        self.speed_slider = gui.add_slider(
            "Steps per second", min=1, max=200, step=1, initial_value=int(self.speed)
        )
        self.play_checkbox = gui.add_checkbox("Playing", initial_value=True)
        self.lives_checkbox = gui.add_checkbox(
            "New life every T steps",
            initial_value=True,
            hint="As in training: after the run's life time T, start again from the next pose",
        )
        restart = gui.add_button("Restart from the start pose", icon=viser.Icon.REFRESH)
        self.node_dropdown = gui.add_dropdown("Inspect node", ("0 · start",))
        self.inspector_md = gui.add_markdown("Click a node of the graph, or pick one above.")
        legend = " · ".join(
            f"<span style='color:{_hex(s.color)}'>■</span> {s.name}" for s in TRANSITION_STYLES
        )
        gui.add_markdown(
            f"<small>Graph: {legend} · <span style='color:#f01e1e'>○</span> current node · "
            "<span style='color:#8228c8'>○</span> inspected node. Arena: rays grey→orange with "
            "the reading, <span style='color:#e61414'>red ✕</span> a broken sensor; trail "
            "red→green with reward.</small>"
        )

        @self.arena_dropdown.on_update
        def _(event: viser.GuiEvent) -> None:
            self._guarded(event, lambda: self._restage(arena=self.arena_dropdown.value))

        @self.start_dropdown.on_update
        def _(event: viser.GuiEvent) -> None:
            self._guarded(event, lambda: self._restage(start=int(self.start_dropdown.value)))

        @self.speed_slider.on_update
        def _(event: viser.GuiEvent) -> None:
            def apply() -> None:
                self.speed = finite(self.speed_slider.value, "steps per second", 1, 200)

            self._guarded(event, apply)

        @self.play_checkbox.on_update
        def _(_: viser.GuiEvent) -> None:
            self.playing = bool(self.play_checkbox.value)

        @restart.on_click
        def _(event: viser.GuiEvent) -> None:
            self._guarded(event, lambda: self._restage())

        @self.node_dropdown.on_update
        def _(event: viser.GuiEvent) -> None:
            self._guarded(event, lambda: self._inspect(int(self.node_dropdown.value.split()[0])))

    def _build_train_tab(self) -> None:
        gui = self.server.gui
        quick = load_preset("quick")  # the fields start at the quick preset's values
        training = quick.training
        self.train_method = gui.add_dropdown(
            "Method", ("RL", "BS", "CS"), initial_value=quick.controller.method
        )
        self.train_judgment = gui.add_dropdown(
            "Judgment",
            ("fuzzy", "crisp"),
            initial_value="fuzzy" if quick.controller.fuzzy else "crisp",
        )
        self.train_preset = gui.add_dropdown("Preset", PRESET_NAMES, initial_value="quick")
        self.train_population = gui.add_number(
            "Population", training.population, min=2, max=100_000, step=1
        )
        self.train_generations = gui.add_number(
            "Generations", training.generations, min=1, max=1_000_000, step=1
        )
        self.train_steps = gui.add_number(
            "Life T (steps)", training.steps, min=1, max=1_000_000, step=1
        )
        self.train_noise = gui.add_number(
            "Noise σ", training.noise_sigma, min=0.0, max=1023.0, step=1.0
        )
        self.train_seed = gui.add_number("Seed", quick.seed, min=0, max=2**31 - 1, step=1)
        buttons = gui.add_button_group("Training", ("Start", "Pause", "Resume", "Stop"))
        self.train_progress = gui.add_progress_bar(0.0)
        self.train_md = gui.add_markdown("Not training.")

        @self.train_preset.on_update
        def _(_: viser.GuiEvent) -> None:
            self._apply_preset(self.train_preset.value)

        @buttons.on_click
        def _(event: viser.GuiEvent) -> None:
            actions: dict[str, Callable[[], None]] = {
                "Start": self._start_training,
                "Pause": lambda: self._job_action("pause"),
                "Resume": lambda: self._job_action("resume"),
                "Stop": lambda: self._job_action("stop"),
            }
            self._guarded(event, actions[buttons.value])

    def _build_faults_tab(self) -> None:
        gui = self.server.gui
        self.noise_slider = gui.add_slider(
            "Noise σ (live)", min=0, max=300, step=1, initial_value=0
        )
        self.fault_sensors = gui.add_text("Sensors to break", "2,3")
        self.fault_mode = gui.add_dropdown("Fault mode", FAULT_MODES)
        buttons = gui.add_button_group("Faults", ("Break now", "Repair all"))
        gui.add_markdown("**Online learning** (Sarsa while on show)")
        self.learn_checkbox = gui.add_checkbox("Learn online", initial_value=True)
        self.schedule_dropdown = gui.add_dropdown(
            "ε, α", ("fixed", "scheduled from the fault (Eq. 4.3–4.4)")
        )
        self.eps_max = gui.add_number("ε (max)", 0.1, min=0.0, max=1.0, step=0.005)
        self.eps_min = gui.add_number("ε min (scheduled)", 0.01, min=0.0, max=1.0, step=0.005)
        self.alpha_max = gui.add_number("α (max)", 0.1, min=0.0, max=1.0, step=0.005)
        self.alpha_min = gui.add_number("α min (scheduled)", 0.01, min=0.0, max=1.0, step=0.005)
        self.schedule_n = gui.add_number("n (exponent)", 1.0, min=0.01, max=100.0, step=0.1)
        self.schedule_horizon = gui.add_number("T − t' (steps)", 2500, min=1, max=10**6, step=1)
        apply = gui.add_button("Apply learning settings")

        @self.noise_slider.on_update
        def _(event: viser.GuiEvent) -> None:
            def set_noise() -> None:
                sigma = finite(self.noise_slider.value, "noise σ", 0.0, 1023.0)
                self.noise_sigma = sigma
                if self.session is not None:
                    self.session.set_noise(sigma)
                self._set_status(f"noise σ = {sigma:g} applied")

            self._guarded(event, set_noise)

        @buttons.on_click
        def _(event: viser.GuiEvent) -> None:
            if buttons.value == "Break now":
                self._guarded(event, self._break_now)
            else:
                self._guarded(event, self._repair)

        @self.learn_checkbox.on_update
        def _(event: viser.GuiEvent) -> None:
            self._guarded(event, self._apply_learning)

        @apply.on_click
        def _(event: viser.GuiEvent) -> None:
            self._guarded(event, self._apply_learning)

    def _build_runs_tab(self) -> None:
        gui = self.server.gui
        self.runs_md = gui.add_markdown("")
        self.runs_dropdown = gui.add_dropdown("Run", ("(none)",))
        buttons = gui.add_button_group("Run file", ("Refresh list", "Load"))
        self.run_md = gui.add_markdown("No run loaded.")
        self.replay_arena = gui.add_dropdown("Replay in", sim.ARENA_NAMES, initial_value="training")
        self.replay_generation = gui.add_number("Generation (−1 = last)", -1, step=1)
        replay = gui.add_button("Replay best individual", icon=viser.Icon.PLAYER_PLAY)
        gui.add_markdown("**Implementation phase** (implementation arena, online Sarsa)")
        self.impl_sensors = gui.add_text("Break sensors", "2,3")
        self.impl_mode = gui.add_dropdown("Mode", FAULT_MODES)
        self.impl_fault_step = gui.add_number("Fault step t'", 500, min=0, max=10**6, step=1)
        self.impl_steps = gui.add_number("Steps T", 1500, min=1, max=10**6, step=1)
        self.impl_repeats = gui.add_number("Repeats per start pose", 3, min=1, max=1000, step=1)
        self.impl_schedule = gui.add_dropdown("ε, α ", ("fixed", "changing"))
        run_impl = gui.add_button("Run implementation", icon=viser.Icon.PLAYER_PLAY)

        @buttons.on_click
        def _(event: viser.GuiEvent) -> None:
            if buttons.value == "Refresh list":
                self._guarded(event, self._refresh_run_lists)
            else:
                self._guarded(event, lambda: self._load_run(self.runs_dropdown.value))

        @replay.on_click
        def _(event: viser.GuiEvent) -> None:
            self._guarded(event, self._replay_loaded)

        @run_impl.on_click
        def _(event: viser.GuiEvent) -> None:
            self._guarded(event, self._start_implementation)

    def _build_compare_tab(self) -> None:
        gui = self.server.gui
        gui.add_markdown("Two runs' best individuals, same arena, start pose and fault.")
        self.compare_a = gui.add_dropdown("Run A (blue)", ("(none)",))
        self.compare_b = gui.add_dropdown("Run B (orange)", ("(none)",))
        self.compare_arena = gui.add_dropdown(
            "Arena ", sim.ARENA_NAMES, initial_value="implementation"
        )
        self.compare_start = gui.add_dropdown("Start pose ", tuple(str(i) for i in range(10)))
        self.compare_sensors = gui.add_text("Break sensors ", "2,3")
        self.compare_mode = gui.add_dropdown("Mode ", FAULT_MODES)
        self.compare_step = gui.add_number("At step", 300, min=0, max=10**6, step=1)
        go = gui.add_button("Compare", icon=viser.Icon.ARROWS_LEFT_RIGHT)

        @go.on_click
        def _(event: viser.GuiEvent) -> None:
            self._guarded(event, self._compare)

    def _build_plots(self) -> None:
        gui = self.server.gui
        panel = gui.add_panel()
        with panel.add_tab("Plots", viser.Icon.CHART_LINE):
            self.readout_md = gui.add_markdown("")
            self.reward_plot = plots.reward_plot(gui)
            self.fitness_plot = plots.fitness_plot(gui)
            self.implementation_plot = plots.implementation_plot(gui)
        panel.dock_left()
        panel.set_width(360)

    # --- helpers ------------------------------------------------------------------------

    def _guarded(self, event: viser.GuiEvent | None, action: Callable[[], None]) -> None:
        """Run a control's action; a bad value is reported on the page and changes nothing."""
        try:
            with self._lock:
                action()
        except (DashboardInputError, LiveError, store.RunFileError, gnp.GnpError) as error:
            self._set_status(f"⚠ {error}")
            if event is not None and event.client is not None:
                event.client.add_notification(
                    "Not applied", str(error), color="red", auto_close_seconds=6.0
                )

    def _set_status(self, text: str) -> None:
        self._status = text
        self.status_md.content = f"**Status:** {text}"

    def _readout(self) -> str:
        lines = [self._show_line, self._training_line]
        lines.append(f"fitness plot: {self._fitness_points} generations")
        lines.append(self._implementation_line)
        return "  \n".join(lines)

    # --- what is on show ----------------------------------------------------------------

    def _show_initial(self, run: str | None) -> None:
        names = [s.name for s in store.list_runs(self.runs_dir) if s.error is None]
        choice = run if run is not None else ("demo" if "demo" in names else None)
        if choice is None and names:
            choice = names[-1]
        if choice is not None:
            try:
                self._load_run(choice)
                self._replay_loaded()
                return
            except (store.RunFileError, gnp.GnpError) as error:
                if run is not None:
                    raise
                self._set_status(f"⚠ could not load {choice}: {error}")
        cfg = gnp.GnpConfig(method="CS")
        population = gnp.init_population(cfg, 1, np.random.default_rng(0))
        self._stage(
            Show(
                "an untrained random CS individual",
                (RobotSpec("random", cfg, population),),
                "training",
                0,
                life=1000,
            )
        )
        self._set_status(
            f"no runs in {self.runs_dir} — showing an untrained random individual; "
            "train one in the Train tab"
        )

    def _stage(self, show: Show) -> None:
        """Put `show` on the arena: a fresh live session, graph and plots."""
        arena = self._arenas[show.arena]
        session = LiveSession(
            arena,
            show.robots,
            start=show.start,
            seed=0,
            noise_sigma=self.noise_sigma,
            learning=self.learning,
            control_period=show.control_period,
        )
        if show.fault is not None:
            session.schedule_fault(*show.fault)
        with self._lock:
            self.session, self.show = session, show
        self.arena_view.set_arena(arena)
        first = show.robots[0]
        self.graph_view.set_genome(genome_view(first.cfg, first.population))
        self.node_dropdown.options = tuple(
            node_label(first.cfg, first.population, i) for i in range(first.cfg.n_nodes)
        )
        if self.arena_dropdown.value != show.arena:
            _set(self.arena_dropdown, show.arena)
        if self.start_dropdown.value != str(show.start):
            _set(self.start_dropdown, str(show.start))
        plots.set_reward_series(self.reward_plot, [r.label for r in show.robots])
        robots = ", ".join(
            f"<span style='color:{_hex(ROBOT_COLORS[i])}'>●</span> {r.label} "
            f"({r.cfg.method}, {'fuzzy' if r.cfg.fuzzy else 'crisp'})"
            for i, r in enumerate(show.robots)
        )
        fault = (
            f" · breaks s{', s'.join(map(str, show.fault[1]))} ({show.fault[2]}) at step "
            f"{show.fault[0]}"
            if show.fault
            else ""
        )
        self.show_md.content = (
            f"**On show:** {show.title}  \n{robots}  \n{show.arena} arena, start pose "
            f"{show.start}{fault}"
        )
        self._inspect(self.graph_view.selected or 0)

    def _restage(self, arena: str | None = None, start: int | None = None) -> None:
        if self.show is None:
            return
        show = self.show
        new = dataclasses.replace(
            show,
            arena=arena if arena is not None else show.arena,
            start=start if start is not None else show.start,
        )
        if arena is not None and arena not in self._arenas:
            raise DashboardInputError(f"unknown arena {arena!r}")
        if new != show or (arena is None and start is None):
            self._stage(new)

    def _inspect(self, node: int) -> None:
        if self.show is None:
            return
        cfg = self.show.robots[0].cfg
        if not 0 <= node < cfg.n_nodes:
            raise DashboardInputError(f"node must be in 0..{cfg.n_nodes - 1}, got {node}")
        self.graph_view.select(node)
        self._refresh_inspector()
        label = self.node_dropdown.options[node]
        if self.node_dropdown.value != label:
            _set(self.node_dropdown, label)

    def _refresh_inspector(self) -> None:
        session, node = self.session, self.graph_view.selected
        if session is None or node is None:
            return
        robot = session.robots[0]
        with session.lock:
            text = node_markdown(robot.cfg, robot.population, node)
        self.inspector_md.content = text + "\n\n<small>live: Q values update as it learns</small>"

    # --- faults and learning ------------------------------------------------------------

    def _break_now(self) -> None:
        sensors = parse_sensors(self.fault_sensors.value)
        mode = parse_mode(self.fault_mode.value)
        if self.session is None:
            raise DashboardInputError("nothing on show to break")
        self.session.break_sensors(sensors, mode)
        _set(self.lives_checkbox, False)  # watch the recovery: no new life wipes the fault
        self._set_status(f"broke s{', s'.join(map(str, sensors))} ({mode})")

    def _repair(self) -> None:
        if self.session is not None:
            self.session.repair()
        self._set_status("all sensors repaired")

    def _apply_learning(self) -> None:
        scheduled = self.schedule_dropdown.value != "fixed"
        eps_max = finite(self.eps_max.value, "ε", 0.0, 1.0)
        alpha_max = finite(self.alpha_max.value, "α", 0.0, 1.0)
        eps_min = finite(self.eps_min.value, "ε min", 0.0, 1.0) if scheduled else eps_max
        alpha_min = finite(self.alpha_min.value, "α min", 0.0, 1.0) if scheduled else alpha_max
        if eps_min > eps_max or alpha_min > alpha_max:
            raise DashboardInputError("a schedule's min must not exceed its max")
        n = finite(self.schedule_n.value, "n", 0.01, 100.0)
        horizon = whole(self.schedule_horizon.value, "T − t'", 1, 10**6)
        learning = LearningSettings(
            online=bool(self.learn_checkbox.value),
            epsilon=eps_max,
            alpha=alpha_max,
            after_fault=(
                gnp.Schedule(max=eps_max, min=eps_min, n=n),
                gnp.Schedule(max=alpha_max, min=alpha_min, n=n),
            )
            if scheduled
            else None,
            horizon=horizon,
        )
        self.learning = learning
        if self.session is not None:
            self.session.set_learning(learning)
        mode = (
            f"scheduled {eps_max}→{eps_min}, α {alpha_max}→{alpha_min}"
            if scheduled
            else (f"fixed ε {eps_max}, α {alpha_max}")
        )
        self._set_status(f"online learning {'on' if learning.online else 'off'}, {mode}")

    # --- runs ---------------------------------------------------------------------------

    def _refresh_run_lists(self) -> None:
        runs = store.list_runs(self.runs_dir)
        good = tuple(r.name for r in runs if r.error is None) or ("(none)",)
        for dropdown in (self.runs_dropdown, self.compare_a, self.compare_b):
            current = dropdown.value
            dropdown.options = good
            if current in good:
                _set(dropdown, current)
        if len(good) > 1 and self.compare_b.value == self.compare_a.value:
            _set(self.compare_b, good[1])
        if not runs:
            self.runs_md.content = f"No runs in `{self.runs_dir}` yet: train one in the Train tab."
            return
        rows = ["| run | method | generations | best fitness |", "|---|---|---|---|"]
        for r in runs:
            if r.error is not None:
                rows.append(f"| {r.name} | ⚠ unreadable | | |")
                continue
            done = f"{r.generations_done}/{r.generations}" + ("" if r.finished else " …")
            judgment = "fuzzy" if r.fuzzy else "crisp"
            rows.append(f"| {r.name} | {r.method} {judgment} | {done} | {r.best_fitness:.4f} |")
        self.runs_md.content = "\n".join(rows)

    def _reader(self, name: str) -> store.RunReader:
        if name == "(none)":
            raise DashboardInputError(f"no runs in {self.runs_dir}")
        return store.RunReader(store.resolve_run(self.runs_dir, name))

    def _load_run(self, name: str) -> None:
        reader = self._reader(name)
        if self.loaded is not None:
            self.loaded.close()
        self.loaded = reader
        if self.runs_dropdown.value != name and name in self.runs_dropdown.options:
            _set(self.runs_dropdown, name)
        history = reader.history()
        plots.set_fitness(self.fitness_plot, history.best_fitness, history.mean_fitness)
        self._fitness_points = len(history.best_fitness)
        config = reader.config
        impls = reader.implementation_names()
        best = float(history.best_fitness.max()) if len(history.best_fitness) else 0.0
        self.run_md.content = (
            f"**{name}**: {config.controller.method} "
            f"{'fuzzy' if config.controller.fuzzy else 'crisp'}, population "
            f"{config.training.population}, {reader.generations_done}/"
            f"{config.training.generations} generations, T = {config.training.steps}, "
            f"σ = {config.training.noise_sigma:g}, seed {config.seed}  \n"
            f"best fitness {best:.4f}"
            f" · implementations: {', '.join(impls) or 'none'}"
        )
        implementation = config.implementation  # the run's own fault, as a starting point
        sensors = implementation.broken_sensors
        _set(self.impl_sensors, ",".join(map(str, sensors)) if sensors else "2,3")
        _set(self.impl_mode, implementation.fault_mode)
        _set(self.impl_fault_step, implementation.fault_step)
        _set(self.impl_steps, implementation.steps)
        _set(self.impl_repeats, implementation.repeats)
        _set(self.impl_schedule, implementation.schedule)
        if impls:
            results = {impl: reader.implementation(impl) for impl in impls}
            # Prefer a stored phase with a fault: that is what the plot's marker is for.
            faulted = [i for i, r in results.items() if r.settings.broken_sensors]
            shown = (faulted or impls)[-1]
            self._show_implementation(f"{name}/{shown}", results[shown])
        self._set_status(f"loaded run {name}")

    def _replay_loaded(self) -> None:
        if self.loaded is None:
            raise DashboardInputError("load a run first")
        generation = whole(self.replay_generation.value, "generation", -(10**6), 10**6)
        cfg, population = self.loaded.best_genome(generation)
        name = self.loaded.path.stem
        done = self.loaded.generations_done
        shown = generation if generation >= 0 else done + generation
        self._stage(
            Show(
                f"best of generation {shown} of run {name}",
                (RobotSpec(name, cfg, population),),
                self.replay_arena.value,
                int(self.start_dropdown.value),
                life=self.loaded.config.training.steps,
                control_period=self.loaded.config.training.control_period,
            )
        )
        self._set_status(f"replaying the best of generation {shown} of {name}")

    def _compare(self) -> None:
        names = (self.compare_a.value, self.compare_b.value)
        specs = []
        for name in names:
            with self._reader(name) as reader:
                cfg, population = reader.best_genome()
            specs.append(RobotSpec(name, cfg, population))
        sensors = parse_sensors(self.compare_sensors.value)
        mode = parse_mode(self.compare_mode.value)
        step = whole(self.compare_step.value, "fault step", 0, 10**6)
        self._stage(
            Show(
                f"{names[0]} vs {names[1]}",
                tuple(specs),
                self.compare_arena.value,
                int(self.compare_start.value),
                fault=(step, sensors, mode),
            )
        )
        self._set_status(f"comparing {names[0]} and {names[1]}")

    # --- implementation phase -----------------------------------------------------------

    def _start_implementation(self) -> None:
        if self.loaded is None:
            raise DashboardInputError("load a run first")
        if self.implementation is not None and self.implementation.active:
            raise DashboardInputError("an implementation phase is already running")
        request = ImplementationRequest(
            run=self.loaded.path,
            sensors=parse_sensors(self.impl_sensors.value),
            mode=parse_mode(self.impl_mode.value),
            fault_step=whole(self.impl_fault_step.value, "fault step t'", 0, 10**6),
            steps=whole(self.impl_steps.value, "steps T", 1, 10**6),
            repeats=whole(self.impl_repeats.value, "repeats", 1, 1000),
            schedule=self.impl_schedule.value,
        )
        if request.fault_step >= request.steps:
            raise DashboardInputError("the fault step t' must come before the end T")
        self.implementation = ImplementationJob(request)
        self._implementation_line = "implementation: running"
        self._set_status(f"implementation phase of {self.loaded.path.stem} started")

    def _follow_implementation(self) -> None:
        job = self.implementation
        if job is None or job.active or job.reported:
            return
        job.reported = True
        try:
            result = job.result()
        except Exception as error:  # the child's error, whatever it is, belongs on the page
            self._implementation_line = f"implementation: failed: {error}"
            self._set_status(f"⚠ implementation failed: {error}")
            return
        self._show_implementation(job.request.run.stem, result)
        self._set_status("implementation phase finished")

    def _show_implementation(self, name: str, result: store.Implementation) -> None:
        settings = result.settings
        plots.set_implementation(
            self.implementation_plot, result.reward_per_step, settings.fault_step
        )
        sensors = ", ".join(f"s{s}" for s in settings.broken_sensors) or "none"
        self._implementation_line = (
            f"implementation: {name} · {len(result.trial_mean_reward)} trials · breaks {sensors} "
            f"({settings.fault_mode}) at {settings.fault_step} · mean reward/step "
            f"{result.mean_reward:.4f}, after the fault {result.mean_after_fault:.4f}"
        )

    # --- training -----------------------------------------------------------------------

    def _apply_preset(self, name: str) -> None:
        """Fill the Train tab's fields with a preset's values."""
        if name not in PRESET_NAMES:
            return
        preset = load_preset(name)
        _set(self.train_method, preset.controller.method)
        _set(self.train_judgment, "fuzzy" if preset.controller.fuzzy else "crisp")
        _set(self.train_population, preset.training.population)
        _set(self.train_generations, preset.training.generations)
        _set(self.train_steps, preset.training.steps)
        _set(self.train_noise, preset.training.noise_sigma)

    def _start_training(self) -> None:
        if self.job is not None and self.job.active:
            raise DashboardInputError("a training run is already going: stop it first")
        config = training_config(
            TrainingRequest(
                preset=self.train_preset.value,
                method=self.train_method.value,
                judgment=self.train_judgment.value,
                population=self.train_population.value,
                generations=self.train_generations.value,
                steps=self.train_steps.value,
                noise_sigma=self.train_noise.value,
                seed=self.train_seed.value,
            )
        )
        self.runs_dir.mkdir(parents=True, exist_ok=True)
        out = store.new_run_path(self.runs_dir, config, datetime.now(UTC))
        if self.job_reader is not None:
            self.job_reader.close()
            self.job_reader = None
        self.job = TrainingJob(config, out)
        self.job_shown_generation = -1
        self._job_history = None
        self._job_retries = 0
        plots.set_fitness(self.fitness_plot, np.zeros(0), np.zeros(0))
        self._fitness_points = 0
        self._training_line = f"training: started {out.name}"
        self._set_status(f"training {out.stem} started")

    def _job_action(self, action: str) -> None:
        job = self.job
        if job is None or not job.active:
            raise DashboardInputError("no training is running")
        getattr(job, action)()
        self._set_status(f"training {action}d" if action != "stop" else "training stopped")

    def _read_training(self, job: TrainingJob) -> store.History | None:
        """The run file's history so far, or None if it cannot be read right now.

        A SWMR reader can catch the writer mid-flush (h5py then raises); the reader is dropped
        and the file reopened at the next poll, which sees a consistent state again.
        """
        if not job.out.exists():
            return None
        try:
            if self.job_reader is None:
                self.job_reader = store.RunReader(job.out)
            else:
                self.job_reader.refresh()
            history = self.job_reader.history()
            done = len(history.best_fitness)
            if done > 0 and done - 1 != self.job_shown_generation:
                cfg, population = self.job_reader.best_genome(done - 1)
                self.job_shown_generation = done - 1
                current = self.show
                self._stage(
                    Show(
                        f"best of generation {done - 1} (training {job.out.stem})",
                        (RobotSpec(job.out.stem, cfg, population),),
                        current.arena if current else "training",
                        current.start if current else 0,
                        life=job.config.training.steps,
                        control_period=job.config.training.control_period,
                    )
                )
            return history
        except Exception:  # a torn SWMR read, or a file not yet complete: retry next poll
            if self.job_reader is not None:
                self.job_reader.close()
            self.job_reader = None
            return None

    def _follow_training(self) -> None:
        """Poll the training process and its run file: plot, replay each new best, progress."""
        job = self.job
        if job is None:
            return
        active = job.active  # once, up front: the line and the clean-up must agree on it
        state = job.state  # before reading: a finished job's file is complete
        history = self._read_training(job)
        if history is not None:
            self._job_history = history
            if len(history.best_fitness) != self._fitness_points:
                plots.set_fitness(self.fitness_plot, history.best_fitness, history.mean_fitness)
                self._fitness_points = len(history.best_fitness)
        total = job.config.training.generations
        done = self._fitness_points
        elapsed = job.elapsed()
        if state == "failed":
            line = f"training: failed: {job.error()}"
        else:
            line = f"training: {state} · generation {done}/{total}"
            last = self._job_history
            if last is not None and len(last.best_fitness):
                line += f" · best {last.best_fitness[-1]:.4f} · mean {last.mean_fitness[-1]:.4f}"
            line += f" · {elapsed:.0f} s"
            if state == "running" and done:
                line += f" · ETA {elapsed / done * (total - done):.0f} s"
        self._training_line = line
        _set(self.train_progress, 100.0 * done / total)
        detail = line.removeprefix("training: ")
        self.train_md.content = detail[:1].upper() + detail[1:]
        if active or (history is None and state == "finished" and self._job_retries < 5):
            self._job_retries += state == "finished"
            return
        self.job = None
        if self.job_reader is not None:
            self.job_reader.close()
            self.job_reader = None
        self._refresh_run_lists()
        if state == "failed":
            self._set_status(f"⚠ training failed: {job.error()}")
        else:
            self._set_status(f"training {state}: {job.out.stem}")
        job.close()

    # --- the loop -----------------------------------------------------------------------

    def _loop(self) -> None:
        last = time.monotonic()
        owed = 0.0
        next_plot = next_follow = 0.0
        while not self._stop.is_set():
            frame_start = time.monotonic()
            try:
                with self._lock:
                    session = self.session
                    if session is not None and self.playing:
                        owed += (frame_start - last) * self.speed
                        steps = min(int(owed), 50)
                        owed -= steps
                        owed = min(owed, 1.0)
                        if steps:
                            session.step(steps)
                            self._maybe_new_life(session)
                    last = frame_start
                    if session is not None:
                        self._draw(session, frame_start >= next_plot)
                    if frame_start >= next_plot:
                        next_plot = frame_start + PLOT_SECONDS
                    if frame_start >= next_follow:
                        next_follow = frame_start + FOLLOW_SECONDS
                        self._follow_training()
                        self._follow_implementation()
                        self._refresh_inspector()
            except Exception:  # keep the page alive; say what went wrong
                self._set_status(
                    "⚠ internal error: " + traceback.format_exc(limit=1).splitlines()[-1]
                )
                traceback.print_exc()
                time.sleep(0.5)
            self._stop.wait(max(0.0, FRAME_SECONDS - (time.monotonic() - frame_start)))

    def _maybe_new_life(self, session: LiveSession) -> None:
        """After a life of T steps, start the same individual again from the next start pose."""
        show = self.show
        if show is None or not show.life or not self.lives_checkbox.value:
            return
        if session.robots[0].t >= show.life:
            self._stage(dataclasses.replace(show, start=(show.start + 1) % 10))

    def _draw(self, session: LiveSession, with_plots: bool) -> None:
        robots = session.snapshot()
        with self.server.atomic():
            self.arena_view.update(robots)
            self.graph_view.update(robots[0])
            if with_plots:
                plots.set_rewards(self.reward_plot, robots)
                self._show_line = show_line(robots, self.noise_sigma)
                self.readout_md.content = self._readout()

    def stop(self) -> None:
        """Stop the loop, any training or implementation job, and close files."""
        self._stop.set()
        self._thread.join(timeout=5)
        with self._lock:
            if self.job is not None:
                self.job.close()
            if self.implementation is not None:
                self.implementation.close()
            for reader in (self.loaded, self.job_reader):
                if reader is not None:
                    reader.close()


def show_line(robots: tuple[RobotSnapshot, ...], noise_sigma: float) -> str:
    """The readout's lines about the robots on show (also what the browser tests read)."""
    first = robots[0]
    rewards = " · ".join(f"{r.label}: reward/step {r.mean_reward:.3f}" for r in robots)
    sub = f" sub {first.visits[-1, 1]}" if len(first.visits) else ""
    lines = [
        f"on show: step {first.t} · {rewards} · node {first.current_node}{sub} · "
        f"ε {first.epsilon:.3f} α {first.alpha:.3f} · noise σ {noise_sigma:g}"
    ]
    broken = ", ".join(f"s{i}" for i in np.flatnonzero(first.broken))
    if broken:
        since = f" since step {first.fault_steps[-1]}" if first.fault_steps else ""
        lines.append(f"broken: {broken} ({first.fault_mode}){since}")
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


def _raise_interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


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
    signal.signal(signal.SIGTERM, _raise_interrupt)
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
