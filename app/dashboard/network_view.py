"""The graph panel of a neural controller: its network, drawn where GNP's graph is.

Weights are line segments (screen-thick; never `add_arrows`) shaded by sign and magnitude, set
once per individual; each frame only recolours the node discs by the units' live activations
(an array of a fixed shape on an existing handle), inside the caller's `server.atomic()`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import viser

import neuro
from app.dashboard.network import (
    CONTEXT,
    HIDDEN,
    INPUT,
    OUTPUT,
    NetworkLayout,
    activation_colors,
    describe_layers,
    io_captions,
    network_layout,
    node_values,
    weight_colors,
)
from app.phases.live import RobotSnapshot
from app.views import geometry as geo
from app.views.scene import add_node_discs

RIM_COLOR = (90, 90, 100)


@dataclass(frozen=True)
class NetworkDrawn:
    """What the network panel draws now (read from its handles)."""

    nodes: int
    weights: int
    segments: int
    layers: str  # `describe_layers` of the net


class NetworkView:
    """The network of the net on show, in the graph panel's box (hidden until a net is shown).

    Args:
        server: the viser server.
        origin: bottom-left corner of the box in the scene (x, y).
        width: the box's width.
        height: the box's height.
    """

    def __init__(
        self, server: viser.ViserServer, origin: tuple[float, float], width: float, height: float
    ) -> None:
        self._server = server
        self._origin = np.array(origin)
        self._width, self._height = width, height
        self._size = min(width, height)
        root = "/network"
        self._root = server.scene.add_frame(root, show_axes=False, visible=False)
        blank, black = np.zeros((1, 2, 3)), np.zeros((1, 2, 3), np.uint8)
        self._edges = server.scene.add_line_segments(
            f"{root}/edges", blank, black, thickness=1.5, thickness_units="screen"
        )
        self._rims = server.scene.add_line_segments(
            f"{root}/rims", blank, RIM_COLOR, thickness=1.0, thickness_units="screen"
        )
        self._nodes = add_node_discs(server, f"{root}/nodes", 0.025 * self._size)
        self._title = server.scene.add_label(
            f"{root}/title",
            "network",
            position=(*(self._origin + np.array([0.0, 1.06 * height])), 0.0),
            anchor="bottom-left",
        )
        # Left of the inputs and of the context, below the hidden and wheel columns.
        self._captions = [
            server.scene.add_label(
                f"{root}/caption_{i}",
                "",
                position=(0.0, 0.0, 0.0),
                anchor="center-right" if i < 2 else "top-center",
                font_screen_scale=0.8,
            )
            for i in range(4)
        ]
        self.layout: NetworkLayout | None = None
        self._colors = np.zeros((0, 3), np.uint8)

    @property
    def visible(self) -> bool:
        return self._root.visible

    @visible.setter
    def visible(self, visible: bool) -> None:
        self._root.visible = visible

    def set_network(self, cfg: neuro.NetConfig, arrays: dict[str, np.ndarray]) -> None:
        """Lay out and draw the net of individual 0 of `arrays`, every node at activation 0."""
        layout = network_layout(cfg, arrays, self._width, self._height)
        self.layout = layout
        positions = self._origin + layout.positions
        edges = layout.edges
        with self._server.atomic():
            if len(edges):
                shorten = 0.025 * self._size  # from rim to rim
                start, end = positions[edges[:, 0]], positions[edges[:, 1]]
                unit = (end - start) / np.linalg.norm(end - start, axis=1, keepdims=True)
                segments = np.stack([start + shorten * unit, end - shorten * unit], 1)
                points = geo.flat_to_3d(segments)
                colors = np.repeat(weight_colors(layout.weights)[:, None, :], 2, axis=1)
            else:  # no weight at all: one invisible segment
                points = geo.flat_to_3d(positions[[0]][None].repeat(2, axis=1))
                colors = np.full((1, 2, 3), 255, np.uint8)
            self._edges.points = points.astype(np.float32)
            self._edges.colors = colors
            rims = geo.circle_segments(positions, 0.025 * self._size, n_sides=16)
            self._rims.points = rims.astype(np.float32)
            self._nodes.batched_positions = geo.flat_to_3d(positions[None])[0].astype(np.float32)
            self._nodes.batched_wxyzs = np.tile(
                np.array([1.0, 0, 0, 0], np.float32), (len(positions), 1)
            )
            self._colors = activation_colors(np.zeros(len(positions)))
            self._nodes.batched_colors = self._colors
            self._title.text = f"network: {describe_layers(layout)}"
            self._place_captions(layout, io_captions(cfg))

    def _place_captions(self, layout: NetworkLayout, io: tuple[str, str]) -> None:
        """The inputs (`IR in`, a task's `inputs f0–f3`) and `context t−1` left of their
        groups, `hidden` and the outputs (`wheels`, a task's `outputs y0–y1`) below."""
        gap = 0.04 * self._size
        inputs, outputs = io
        texts = ((INPUT, inputs), (CONTEXT, "context t−1"), (HIDDEN, "hidden"), (OUTPUT, outputs))
        for caption, (kind, text) in zip(self._captions, texts, strict=True):
            members = layout.positions[layout.kinds == kind]
            caption.visible = len(members) > 0
            if not len(members):
                continue
            if kind in (INPUT, CONTEXT):
                x, y = members[0, 0] - gap, members[:, 1].mean()
            else:
                x, y = members[0, 0], members[:, 1].min() - gap
            caption.text = text
            caption.position = (float(self._origin[0] + x), float(self._origin[1] + y), 0.0)

    def update(self, robot: RobotSnapshot) -> None:
        """Colour each node by what it holds after the robot's last step."""
        if self.layout is None or len(robot.activation) == 0:
            return
        values = node_values(
            self.layout, robot.activation, robot.context, robot.seen_readings, robot.commands
        )
        colors = activation_colors(values)
        if not np.array_equal(colors, self._colors):
            self._nodes.batched_colors = colors
            self._colors = colors

    @property
    def node_colors(self) -> np.ndarray:
        """(V,) colours of the node discs as last sent."""
        return self._colors

    def drawn(self) -> NetworkDrawn:
        """Counts of what is drawn now, from the handles (the tests' view)."""
        if self.layout is None:
            return NetworkDrawn(0, 0, 0, "")
        segments = len(self._edges.points) if len(self.layout.weights) else 0
        return NetworkDrawn(
            len(self._nodes.batched_positions),
            len(self.layout.weights),
            segments,
            describe_layers(self.layout),
        )
