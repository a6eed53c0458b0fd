"""How the scene is framed: the arena on top, the graph below it (they share the width), and the
camera looking straight down on both. The dashboard and the replay export frame it the same way."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import viser

import sim
from app.views import geometry as geo

GRAPH_HEIGHT = 0.62
"""The graph's height, as a fraction of the scene's width."""
GRAPH_GAP = 0.12
"""Space between the arena and the graph, as a fraction of the width."""
MARGIN = 0.05
"""Space below the graph, as a fraction of the width."""
FOV_DEGREES = 50.0


@dataclass(frozen=True)
class SceneFrame:
    """Where the views go, in scene units (metres).

    Attributes:
        xmin: left edge of every arena (and of the graph).
        xmax: right edge of every arena.
        ymax: top edge of every arena.
        width: width of the widest arena span (the graph's width too).
        graph_origin: lower-left corner of the graph.
        graph_height: height of the graph.
    """

    xmin: float
    xmax: float
    ymax: float
    width: float
    graph_origin: tuple[float, float]
    graph_height: float


def scene_frame(arenas: Sequence[sim.Arena]) -> SceneFrame:
    """The frame holding all `arenas` (drawn one at a time in the same place) and the graph."""
    bounds = np.array([a.bounds for a in arenas]) * geo.MM
    xmin, ymin = bounds[:, :2].min(axis=0)
    xmax, ymax = bounds[:, 2:].max(axis=0)
    width = xmax - xmin
    graph_height = GRAPH_HEIGHT * width
    graph_origin = (xmin, ymin - GRAPH_GAP * width - graph_height)
    return SceneFrame(xmin, xmax, ymax, width, graph_origin, graph_height)


def aim_camera(server: viser.ViserServer, frame: SceneFrame, headroom: float) -> None:
    """Aim the initial camera of `server` straight down at the whole frame.

    Args:
        server: the viser server whose up direction and initial camera are set.
        frame: the frame to see whole.
        headroom: space kept above the arenas, as a fraction of the width (room for a caption).
    """
    width = frame.width
    bottom, top = frame.graph_origin[1] - MARGIN * width, frame.ymax + headroom * width
    center = ((frame.xmin + frame.xmax) / 2, (bottom + top) / 2)
    fov = np.radians(FOV_DEGREES)
    distance = 1.08 * (top - bottom) / 2 / np.tan(fov / 2)
    server.scene.set_up_direction("+y")
    camera = server.initial_camera
    camera.up = (0.0, 1.0, 0.0)
    camera.look_at = (center[0], center[1], 0.0)
    camera.position = (center[0], center[1], distance)
    camera.fov = fov
    camera.far = 100.0


def add_node_discs(server: viser.ViserServer, name: str, radius: float) -> viser.BatchedMeshHandle:
    """A batched mesh of flat discs of `radius` for a graph's nodes, one placeholder for now:
    a view moves, colours and counts them each frame by assigning new arrays."""
    return server.scene.add_batched_meshes_simple(
        name,
        *geo.disc_mesh(radius),
        batched_wxyzs=np.array([[1.0, 0.0, 0.0, 0.0]]),
        batched_positions=np.zeros((1, 3)),
        material="toon3",
        cast_shadow=False,
        receive_shadow=False,
        side="double",
    )
