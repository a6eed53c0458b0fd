"""The Show tab: arena, start pose, speed, new lives, the graph's view, and the node inspector."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import viser

import sim
from app.dashboard.controls import DashboardInputError, finite
from app.dashboard.method_show import CHOICES, show_methods
from app.dashboard.network import net_markdown
from app.dashboard.network_view import NetworkView
from app.dashboard.stage import Show, Stage
from app.dashboard.status import Status, hex_color, set_value
from app.phases.implementation import fault_text
from app.views.arena_view import ROBOT_COLORS
from app.views.genome import genome_view, node_label, node_markdown
from app.views.graph_counts import FULL, GRAPH_MODES, SIMPLIFIED, WINDOW
from app.views.graph_view import TRANSITION_STYLES, GraphView

MAX_SPEED = 200
NO_NODES = "— no GNP nodes on show"


@dataclass
class ShowTab:
    """The Show tab's handles; its methods keep them in step with the stage."""

    stage: Stage
    graph: GraphView
    network: NetworkView
    description: viser.GuiMarkdownHandle
    arena: viser.GuiDropdownHandle[str]
    start: viser.GuiDropdownHandle[str]
    speed: viser.GuiSliderHandle[int]
    playing: viser.GuiCheckboxHandle
    new_lives: viser.GuiCheckboxHandle
    graph_mode: viser.GuiDropdownHandle[str]
    graph_info: viser.GuiMarkdownHandle
    graph_of: viser.GuiDropdownHandle[str]
    node: viser.GuiDropdownHandle[str]
    inspector: viser.GuiMarkdownHandle

    def select_robot(self, label: str) -> None:
        """Draw the graph (and the charts) of the robot `label` names."""
        show = self.stage.show
        if show is None or label not in robot_labels(show):
            return
        index = robot_labels(show).index(label)
        if index != self.stage.selected:
            self.stage.select(index)

    def staged(self, show: Show) -> None:
        """A new show: the chosen robot's graph and nodes to inspect (a net: its network;
        another family: no drawing), the GNP-only controls off without a graph, the dropdowns
        and the description."""
        first = show.robots[self.stage.selected]
        cfg, net = first.family.graph_config, first.family.network_config
        self.graph.visible, self.network.visible = cfg is not None, net is not None
        self.graph_mode.disabled = self.node.disabled = cfg is None
        if cfg is not None:
            self.graph.set_genome(genome_view(cfg, first.population))
            self.node.options = tuple(
                node_label(cfg, first.population, i) for i in range(cfg.n_nodes)
            )
        else:
            self.node.options = (NO_NODES,)
        if net is not None:
            self.network.set_network(net, first.population)
        # Echo the show in the dropdowns; their callbacks then find nothing to change.
        set_value(self.arena, show.arena)
        set_value(self.start, str(show.start))
        labels = robot_labels(show)
        self.graph_of.options = labels
        set_value(self.graph_of, labels[self.stage.selected])
        self.graph_of.disabled = len(labels) == 1
        self.description.content = describe(show, self.stage.selected)
        if cfg is not None:
            self.inspect(self.graph.selected or 0)
            return
        if net is not None:
            assert self.network.layout is not None
            self.inspector.content = net_markdown(self.network.layout)
        else:
            self.inspector.content = f"A {first.family.description} brain: nothing to draw."
        self.describe_graph()

    def set_speed(self, value: float) -> None:
        self.stage.speed = finite(value, "steps per second", 1, MAX_SPEED)

    def inspect(self, node: int) -> None:
        """Ring `node` on the graph and show its sub nodes and Q values."""
        show = self.stage.show
        if show is None:
            return
        family = show.robots[self.stage.selected].family
        cfg = family.graph_config
        if cfg is None:
            raise DashboardInputError(f"a {family.description} brain has no GNP nodes to inspect")
        n_nodes = cfg.n_nodes
        if not 0 <= node < n_nodes:
            raise DashboardInputError(f"node must be in 0..{n_nodes - 1}, got {node}")
        self.graph.select(node)
        self.refresh()
        set_value(self.node, self.node.options[node])

    def inspect_label(self, label: str) -> None:
        """Inspect the node the dropdown names (`12 · J s3`); a net's placeholder: nothing."""
        if label != NO_NODES:
            self.inspect(int(label.split()[0]))

    def set_graph_mode(self, mode: str) -> None:
        """The graph in full (every connection) or simplified (what the robot runs)."""
        if mode not in GRAPH_MODES:
            raise DashboardInputError(f"graph view must be one of {', '.join(GRAPH_MODES)}")
        self.graph.set_mode(mode)
        set_value(self.graph_mode, mode)
        self.describe_graph()

    def describe_graph(self) -> None:
        """What the graph draws now, in words (also what the browser test reads)."""
        if self.network.visible:
            net = self.network.drawn()
            text = f"network: {net.layers} · {net.segments} line segments"
            if text != self.graph_info.content:
                self.graph_info.content = text
            return
        if not self.graph.visible:
            self.graph_info.content = "no graph: this brain has none to draw"
            return
        drawn = self.graph.drawn()
        genome = self.graph.genome
        total = len(genome.kinds) if genome is not None else 0
        if drawn.mode == FULL:
            text = f"graph: full · {drawn.nodes} nodes · {drawn.edges} connections"
        else:
            text = (
                f"graph: simplified · {drawn.nodes} of {total} nodes (visited this life) · "
                f"{drawn.edges} transitions taken in the last {WINDOW} visits"
            )
        text += f" · {drawn.segments} line segments"
        if text != self.graph_info.content:
            self.graph_info.content = text

    def echo_new_lives(self) -> None:
        """Show the stage's new-lives setting (breaking a sensor turns it off)."""
        set_value(self.new_lives, self.stage.new_lives)

    def refresh(self) -> None:
        """The inspected node's live Q values."""
        session, node = self.stage.session, self.graph.selected
        if session is None or node is None:
            return
        robot = session.robots[min(self.stage.selected, len(session.robots) - 1)]
        cfg = robot.family.graph_config
        if cfg is None:
            self.describe_graph()  # no nodes: its inspector stays as staged
            return
        with session.lock:
            text = node_markdown(cfg, robot.population, node)
        self.inspector.content = text + "\n\n<small>live: Q values update as it learns</small>"
        self.describe_graph()


def populate_show_tab(
    gui: viser.GuiApi,
    stage: Stage,
    status: Status,
    graph: GraphView,
    network: NetworkView,
    runs_dir: Path,
) -> ShowTab:
    """Add the Show tab's controls (inside the current tab) and attach their callbacks."""
    methods = gui.add_button_group("Method on show", CHOICES)
    gui.add_markdown(
        "<small>The bundled chapter-5 runs (same preset, seed and 1000 generations): one, or "
        "all three at once, in the arena, start pose and faults on show now.</small>"
    )
    tab = ShowTab(
        stage=stage,
        graph=graph,
        network=network,
        description=gui.add_markdown("nothing on show yet"),
        arena=gui.add_dropdown("Arena", sim.ARENA_NAMES, initial_value=stage.arena),
        start=gui.add_dropdown(
            "Start pose",
            tuple(str(i) for i in range(sim.N_START_POSES)),
            initial_value=str(stage.start),
        ),
        speed=gui.add_slider(
            "Steps per second", min=1, max=MAX_SPEED, step=1, initial_value=int(stage.speed)
        ),
        playing=gui.add_checkbox("Playing", initial_value=stage.playing),
        new_lives=gui.add_checkbox(
            "New life every T steps",
            initial_value=stage.new_lives,
            hint="As in training: after the run's life time T, start again from the next pose",
        ),
        graph_mode=gui.add_dropdown(
            "Graph",
            GRAPH_MODES,
            initial_value=graph.mode,
            hint="full: every connection of the genome; simplified: only the nodes visited in "
            "this life and the transitions taken lately, darker the more often",
        ),
        graph_info=gui.add_markdown("graph: full"),
        graph_of=gui.add_dropdown(
            "Graph of", ("robot 1",), hint="whose graph, inspector and charts are drawn"
        ),
        node=gui.add_dropdown("Inspect node", ("0 · start",)),
        inspector=gui.add_markdown("Click a node of the graph, or pick one above."),
    )
    restart = gui.add_button("Restart from the start pose", icon=viser.Icon.REFRESH)
    gui.add_markdown(legend())

    tab.arena.on_update(status.guard(lambda: stage.restage(arena=tab.arena.value)))
    tab.start.on_update(status.guard(lambda: stage.restage(start=int(tab.start.value))))
    tab.speed.on_update(status.guard(lambda: tab.set_speed(tab.speed.value)))
    restart.on_click(status.guard(stage.restage))
    methods.on_click(
        lambda event: status.guarded(
            event.client, lambda: show_chosen_methods(stage, status, runs_dir, methods.value)
        )
    )
    tab.graph_of.on_update(status.guard(lambda: tab.select_robot(tab.graph_of.value)))
    tab.node.on_update(status.guard(lambda: tab.inspect_label(tab.node.value)))
    tab.graph_mode.on_update(status.guard(lambda: tab.set_graph_mode(tab.graph_mode.value)))

    @tab.playing.on_update
    def _(_: viser.GuiEvent[viser.GuiCheckboxHandle]) -> None:
        stage.playing = bool(tab.playing.value)

    @tab.new_lives.on_update
    def _(_: viser.GuiEvent[viser.GuiCheckboxHandle]) -> None:
        stage.new_lives = bool(tab.new_lives.value)

    return tab


def show_chosen_methods(stage: Stage, status: Status, runs_dir: Path, choice: str) -> None:
    show_methods(stage, runs_dir, choice)
    faults = stage.faults
    kept = f", {fault_text(*faults, None)} still" if faults else ""
    status.set(f"on show: {choice} (bundled chapter-5 runs){kept}")


def robot_labels(show: Show) -> tuple[str, ...]:
    """One label per robot on show, `1 · demo-rl` (unique even for twice the same run)."""
    return tuple(
        f"{i + 1} · {show.origin(i)[0] or robot.label}" for i, robot in enumerate(show.robots)
    )


def describe(show: Show, selected: int = 0) -> str:
    """The Show tab's description of a show: title, robots (in their colours, the one whose
    graph is drawn marked), arena, fault."""
    robots = ", ".join(
        f"<span style='color:{hex_color(ROBOT_COLORS[i])}'>●</span> "
        f"{show.origin(i)[0] or r.label} ({r.family.description})"
        + (" ← graph" if i == selected and len(show.robots) > 1 else "")
        for i, r in enumerate(show.robots)
    )
    fault = ""
    if show.fault is not None:
        step, sensors, mode = show.fault
        fault = f" · breaks s{', s'.join(map(str, sensors))} ({mode}) at step {step}"
    return (
        f"**On show:** {show.title}  \n{robots}  \n{show.arena} arena, start pose "
        f"{show.start}{fault}"
    )


def legend() -> str:
    """What the colours of the graph and the arena mean."""
    transitions = " · ".join(
        f"<span style='color:{hex_color(s.color)}'>■</span> {s.name}" for s in TRANSITION_STYLES
    )
    return (
        f"<small>Graph: {transitions} · <span style='color:#f01e1e'>○</span> current node · "
        "<span style='color:#8228c8'>○</span> inspected node; simplified: "
        f"<span style='color:#143c96'>→</span> transitions taken, darker the more often"
        f" ({SIMPLIFIED} shows only nodes visited this life). Arena: rays grey→orange with "
        "the reading, <span style='color:#e61414'>red ✕</span> a broken sensor; trail "
        "red→green with reward. A neural net's network: weights "
        "<span style='color:#d75014'>orange</span> positive, <span style='color:#1e64d7'>blue"
        "</span> negative, darker the larger; nodes coloured by their live value.</small>"
    )
