"""The node-transition graph of the robot on show, seen from above beside the arena.

Everything is drawn with line segments (screen-thick, cheap) and a batched mesh of node discs;
per-frame updates assign new arrays of a fixed shape to existing handles, so a long session never
adds nodes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import viser

from app.phases.live import RobotSnapshot
from app.views import geometry as geo
from app.views.genome import GenomeView
from app.views.graph_counts import (
    FULL,
    GRAPH_MODES,
    SIMPLIFIED,
    WINDOW,
    edge_shades,
    graph_counts,
)
from app.views.graph_layout import GraphLayout, graph_layout
from app.views.scene import add_node_discs
from gnp.config import BRANCH_NAMES, JUDGMENT, START


@dataclass(frozen=True)
class EdgeStyle:
    """Colour and meaning of one kind of transition drawn on the graph."""

    name: str
    color: tuple[int, int, int]


TRANSITION_STYLES = (
    EdgeStyle("normal transition", (30, 110, 220)),
    EdgeStyle("BS: alternative branch connection (u > 0)", (235, 140, 0)),
    EdgeStyle("CS: credit branch (node skipped)", (200, 30, 200)),
)
NORMAL, BRANCH_SWITCH, CREDIT_SKIP = 0, 1, 2


@dataclass(frozen=True)
class GraphDrawn:
    """What the graph draws now (read from its handles): node discs, edges (genome connections
    in the full view, transitions taken in the simplified one), and all its line segments."""

    mode: str
    nodes: int
    edges: int
    segments: int


TAKEN_COLOR = (20, 60, 150)
"""Transitions taken in the simplified view, darker the more often."""
NODE_COLORS = np.array([[50, 50, 50], [40, 100, 170], [30, 140, 60]], np.uint8)


class GraphView:
    """The node-transition graph of the robot on show, beside the arena.

    Full view (static): nodes (colour by kind), every connection of the genome (faint), column
    captions. Simplified view: only the nodes visited in the current life, and the transitions
    taken over the last `WINDOW` visits as arrows shaded by how often each was taken. Both,
    live: the last transitions as arrows coloured by kind (fading with age), the current node
    ringed, the inspected node ringed.
    """

    RECENT = 12

    def __init__(
        self, server: viser.ViserServer, origin: tuple[float, float], width: float, height: float
    ):
        self._server = server
        self._origin = np.array(origin)
        self._width, self._height = width, height
        self._size = size = min(width, height)
        root = "/graph"
        # Everything of the graph hangs under one frame: hidden at once when a net is on show.
        self._root = server.scene.add_frame(root, show_axes=False)
        blank = np.zeros((1, 2, 3))
        black = np.zeros((1, 2, 3), np.uint8)
        self._edges = server.scene.add_line_segments(
            f"{root}/edges", blank, black, thickness=1.0, thickness_units="screen"
        )
        self._node_radius = 0.02 * size
        self._nodes = add_node_discs(server, f"{root}/nodes", self._node_radius)
        self._recent = server.scene.add_line_segments(
            f"{root}/recent", blank, black, thickness=3.0, thickness_units="screen"
        )
        self._current = server.scene.add_line_segments(
            f"{root}/current", blank, (240, 30, 30), thickness=3.5, thickness_units="screen"
        )
        # What the current node did, in words, at a fixed place above the graph.
        self._current_label = server.scene.add_label(
            f"{root}/current_label",
            "",
            position=(*(self._origin + np.array([0.45 * width, 1.06 * height])), 0.0),
            anchor="bottom-left",
            font_screen_scale=0.85,
        )
        self._selected = server.scene.add_line_segments(
            f"{root}/selected", blank, (130, 40, 200), thickness=2.5, thickness_units="screen"
        )
        self._taken = server.scene.add_line_segments(
            f"{root}/taken", blank, black, thickness=3.0, thickness_units="screen", visible=False
        )
        self._captions: list[viser.LabelHandle] = []
        self._title = server.scene.add_label(
            f"{root}/title",
            "node-transition graph",
            position=(*(self._origin + np.array([0.0, 1.06 * height])), 0.0),
            anchor="bottom-left",
        )
        self.layout: GraphLayout | None = None
        self.genome: GenomeView | None = None
        self.selected: int | None = None
        self.mode = FULL
        self._shown_nodes = np.zeros(0, np.int64)  # the nodes whose discs are drawn
        self._colors = np.zeros((0, 3), np.uint8)  # and their colours
        self._n_taken = 0
        self._last: RobotSnapshot | None = None

    @property
    def visible(self) -> bool:
        """Whether the graph is drawn (a net on show draws its network instead)."""
        return self._root.visible

    @visible.setter
    def visible(self, visible: bool) -> None:
        self._root.visible = visible

    @property
    def nodes_handle(self) -> viser.BatchedMeshHandle:
        """The node discs (clickable)."""
        return self._nodes

    def node_at(self, point: np.ndarray) -> int | None:
        """The drawn node nearest to a scene point (x, y), if within reach of its disc."""
        if self.layout is None or not len(self._shown_nodes):
            return None
        positions = self._origin + self.layout.positions[self._shown_nodes]
        distances = np.linalg.norm(positions - np.asarray(point)[:2], axis=1)
        nearest = int(np.argmin(distances))
        return int(self._shown_nodes[nearest]) if distances[nearest] < 0.04 * self._size else None

    def set_mode(self, mode: str) -> None:
        """Full or simplified view; redraws at once with the latest snapshot."""
        if mode not in GRAPH_MODES:
            raise ValueError(f"graph view must be one of {', '.join(GRAPH_MODES)}, got {mode!r}")
        if mode == self.mode:
            return
        self.mode = mode
        with self._server.atomic():
            self._edges.visible = mode == FULL
            self._taken.visible = mode == SIMPLIFIED
            if mode == FULL and self.layout is not None:
                self._show_nodes(np.arange(len(self.layout.positions)))
            if self._last is not None:
                self.update(self._last)

    def drawn(self) -> GraphDrawn:
        """Counts of what is drawn now, from the handles (the benchmark's and tests' view)."""
        if self.mode == FULL:
            edges = len(self.genome.edges) if self.genome is not None else 0
        else:
            edges = self._n_taken
        handles = [self._recent, self._current, self._edges if self.mode == FULL else self._taken]
        if self._selected.visible:
            handles.append(self._selected)
        segments = sum(len(h.points) for h in handles)
        return GraphDrawn(self.mode, len(self._shown_nodes), edges, segments)

    def _show_nodes(self, nodes: np.ndarray, lately: np.ndarray | None = None) -> None:
        """Draw the discs of `nodes` only (every node in the full view); with `lately`, a
        (V,) mask, the nodes outside it pale."""
        assert self.layout is not None and self.genome is not None
        nodes = np.asarray(nodes, np.int64)
        if not len(nodes):  # a batched mesh needs an instance: one at the start node
            nodes = np.zeros(1, np.int64)
        colors = NODE_COLORS[self.genome.kinds[nodes]]
        if lately is not None:
            pale = ~lately[nodes]
            colors[pale] = np.round(0.35 * colors[pale] + 0.65 * 255).astype(np.uint8)
        if np.array_equal(nodes, self._shown_nodes) and np.array_equal(colors, self._colors):
            return
        if not np.array_equal(nodes, self._shown_nodes):
            positions = self._origin + self.layout.positions[nodes]
            self._nodes.batched_positions = geo.flat_to_3d(positions[None])[0].astype(np.float32)
            self._nodes.batched_wxyzs = np.tile(
                np.array([1.0, 0, 0, 0], np.float32), (len(nodes), 1)
            )
        self._nodes.batched_colors = colors
        self._shown_nodes, self._colors = nodes, colors

    def set_genome(self, genome: GenomeView) -> None:
        """Lay out and draw the static graph of an individual."""
        self.genome = genome
        layout = graph_layout(
            genome.kinds,
            genome.column_function,
            self._width,
            self._height,
            genome.inputs,
            genome.outputs,
        )
        self.layout = layout
        positions = self._origin + layout.positions
        edges = genome.edges
        if len(edges):
            points = geo.flat_to_3d(np.stack([positions[edges[:, 0]], positions[edges[:, 1]]], 1))
        else:
            points = np.zeros((1, 2, 3))
        self._edges.points = points.astype(np.float32)
        self._edges.colors = np.broadcast_to(
            np.array([215, 215, 222], np.uint8), points.shape
        ).copy()
        self._last = None
        self._shown_nodes = np.zeros(0, np.int64)
        with self._server.atomic():
            # A new individual (or life): the simplified view starts from its start node.
            self._show_nodes(np.arange(len(positions)) if self.mode == FULL else np.zeros(1))
            if self.mode == SIMPLIFIED:
                self._draw_taken(np.zeros((0, 2), np.int64), np.zeros(0, np.int64))
        # One caption per column; a task's brain has its own number of columns (the spare
        # captions of a wider graph are hidden, not removed).
        for i in range(len(self._captions), len(layout.column_names)):
            self._captions.append(
                self._server.scene.add_label(
                    f"/graph/caption_{i}",
                    "",
                    position=(0.0, 0.0, 0.0),
                    anchor="top-center",
                    font_screen_scale=0.8,
                )
            )
        for i, caption in enumerate(self._captions):
            used = i < len(layout.column_names)
            if used:
                if caption.text != layout.column_names[i]:
                    caption.text = layout.column_names[i]
                x = float(self._origin[0] + layout.column_x[i])
                caption.position = (x, float(self._origin[1] - 0.02), 0.0)
            if caption.visible != used:
                caption.visible = used
        self.select(self.selected)

    def select(self, node: int | None) -> None:
        """Ring the inspected node (None: no ring)."""
        self.selected = node
        if self.layout is None or node is None or not 0 <= node < len(self.layout.positions):
            self._selected.visible = False
            return
        center = self._origin + self.layout.positions[node]
        self._selected.points = geo.circle_segments(center[None], 0.03 * self._size).astype(
            np.float32
        )
        self._selected.visible = True

    def update(self, robot: RobotSnapshot) -> None:
        """Draw the robot's latest transitions and ring its current node (and, simplified, the
        nodes it visited this life and the transitions it took lately)."""
        if self.layout is None:
            return
        self._last = robot
        positions = self._origin + self.layout.positions
        if self.mode == SIMPLIFIED:
            self._update_simplified(robot)
        visits = robot.visits[-(self.RECENT + 1) :]
        n_arrows = max(0, len(visits) - 1)
        arrows = np.zeros((3 * self.RECENT, 2, 3))
        colors = np.full((3 * self.RECENT, 2, 3), 255, np.uint8)
        if n_arrows:
            source, target = visits[:-1], visits[1:]
            kinds = transition_kinds(source, target)
            drawn = geo.arrow_segments(
                positions[source[:, 0]],
                positions[target[:, 0]],
                head=0.035 * self._size,
                shorten=0.02 * self._size,
            )
            age = np.linspace(0.75, 0.0, n_arrows)[:, None]  # oldest faintest
            style = np.array([s.color for s in TRANSITION_STYLES], np.float64)[kinds]
            shade = np.round(style * (1 - age) + 255 * age).astype(np.uint8)
            arrows[-3 * n_arrows :] = drawn
            colors[-3 * n_arrows :] = np.repeat(shade, 3, axis=0)[:, None, :]
        # Unused slots collapse onto the current node (invisible, same shape every frame).
        arrows[: 3 * (self.RECENT - n_arrows)] = geo.flat_to_3d(
            positions[robot.current_node][None, None]
        )
        self._recent.points = arrows.astype(np.float32)
        self._recent.colors = colors
        current = positions[robot.current_node]
        ring = geo.circle_segments(current[None], 0.022 * self._size)
        self._current.points = ring.astype(np.float32)
        text = ""
        if len(robot.visits) and self.genome is not None:
            last = robot.visits[-1]
            text = describe_visit(last, int(self.genome.kinds[last[0]]))
        if text != self._current_label.text:
            self._current_label.text = text

    def _update_simplified(self, robot: RobotSnapshot) -> None:
        assert self.layout is not None
        n_nodes = len(self.layout.positions)
        counts = graph_counts(robot.visits, n_nodes, WINDOW)
        if len(robot.node_visits) == n_nodes:
            visited = robot.node_visits > 0
        else:  # a snapshot without the life's counts: the window's
            visited = counts.node_visits > 0
        visited[robot.current_node] = True
        # Visited this life but not lately: drawn pale.
        self._show_nodes(np.flatnonzero(visited), lately=counts.node_visits > 0)
        self._draw_taken(counts.edges, counts.edge_counts)

    def _draw_taken(self, edges: np.ndarray, counts: np.ndarray) -> None:
        """Transitions taken, as arrows shaded by how often (the simplified view's edges)."""
        assert self.layout is not None
        positions = self._origin + self.layout.positions
        self._n_taken = len(edges)
        if len(edges):
            points = geo.arrow_segments(
                positions[edges[:, 0]],
                positions[edges[:, 1]],
                head=0.022 * self._size,
                shorten=0.02 * self._size,
            )
            shades = np.repeat(edge_shades(counts, TAKEN_COLOR), 3, axis=0)
            colors = np.repeat(shades[:, None, :], 2, axis=1)
        else:  # nothing taken yet: one invisible segment at the start node
            points = geo.flat_to_3d(positions[[0]][None].repeat(2, axis=1))
            colors = np.full((1, 2, 3), 255, np.uint8)
        self._taken.points = points.astype(np.float32)
        self._taken.colors = colors


def describe_visit(visit: np.ndarray, kind: int) -> str:
    """A visit (node, sub, branch, u, skipped) of a node of `kind` in words."""
    node, sub, branch, u, skipped = (int(v) for v in visit)
    if kind == START:
        return "start node"
    if skipped:
        return f"node {node}: skipped by its credit branch"
    text = f"node {node}: sub node {sub}"
    if kind == JUDGMENT:
        text += ", branch " + BRANCH_NAMES[branch]
    if u > 0:
        text += f", branch connection u = {u}"
    return text


def transition_kinds(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Kind of each transition between consecutive visits (rows of node, sub, branch, u, credit).

    A transition into a credit-skipped node is a CS credit skip; one taken through a BS branch
    connection other than the first (u > 0) is a branch switch; anything else is normal.
    """
    kinds = np.full(len(source), NORMAL, np.int64)
    kinds[source[:, 3] > 0] = BRANCH_SWITCH
    kinds[(target[:, 4] > 0) | (source[:, 4] > 0)] = CREDIT_SKIP
    return kinds
