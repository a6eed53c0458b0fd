"""The arena seen from above: walls, start poses and up to three robots (body, heading, IR rays,
broken sensors, reward-coloured trail).

Everything is drawn with line segments (screen-thick, cheap); per-frame updates assign new arrays
of a fixed shape to existing handles, so a long session never adds nodes.
"""

from __future__ import annotations

import numpy as np
import viser

import sim
from app.phases.live import RobotSnapshot
from app.views import geometry as geo
from sim.sensors import ir_distances

ROBOT_COLORS = ((30, 110, 220), (225, 110, 20), (30, 150, 70))
"""Robot 1 blue, robot 2 orange, robot 3 green (also their reward curves)."""
BROKEN_RED = (230, 20, 20)
WALL_COLOR = (40, 40, 48)
TRAIL_POINTS = 600


class ArenaView:
    """Walls, start poses and up to three robots (body, heading, rays, faults, trail)."""

    def __init__(
        self, server: viser.ViserServer, arena: sim.Arena, max_robots: int = len(ROBOT_COLORS)
    ):
        self._server = server
        self._root = "/arena"
        self._walls = server.scene.add_line_segments(
            f"{self._root}/walls",
            geo.flat_to_3d(arena.walls * geo.MM),
            WALL_COLOR,
            thickness=3.0,
            thickness_units="screen",
        )
        starts = arena.start_poses
        heads = starts[:, :2] + 40.0 * np.stack([np.cos(starts[:, 2]), np.sin(starts[:, 2])], 1)
        self._starts = server.scene.add_line_segments(
            f"{self._root}/starts",
            geo.arrow_segments(starts[:, :2] * geo.MM, heads * geo.MM, head=0.012),
            (150, 150, 160),
            thickness=1.5,
            thickness_units="screen",
        )
        self._start_labels = [
            server.scene.add_label(
                f"{self._root}/start_label_{i}",
                str(i),
                position=(float(x) * geo.MM, float(y) * geo.MM, 0.0),
                font_screen_scale=0.7,
                anchor="top-right",
            )
            for i, (x, y, _) in enumerate(starts)
        ]
        self.arena = arena
        self._robots = [self._add_robot(i) for i in range(max_robots)]

    def _add_robot(self, i: int) -> dict[str, viser.LineSegmentsHandle]:
        blank = np.zeros((1, 2, 3))
        black = np.zeros((1, 2, 3), np.uint8)
        root = f"{self._root}/robot{i}"
        return {
            "trail": self._server.scene.add_line_segments(
                f"{root}/trail", blank, black, thickness=3.0, thickness_units="screen"
            ),
            "body": self._server.scene.add_line_segments(
                f"{root}/body", blank, black, thickness=2.5, thickness_units="screen"
            ),
            "rays": self._server.scene.add_line_segments(
                f"{root}/rays", blank, black, thickness=2.0, thickness_units="screen"
            ),
            "faults": self._server.scene.add_line_segments(
                f"{root}/faults", blank, black, thickness=4.0, thickness_units="screen"
            ),
        }

    def set_arena(self, arena: sim.Arena) -> None:
        """Redraw walls and start poses for another arena (same handles)."""
        if arena is self.arena:
            return
        self._walls.points = geo.flat_to_3d(arena.walls * geo.MM).astype(np.float32)
        starts = arena.start_poses
        heads = starts[:, :2] + 40.0 * np.stack([np.cos(starts[:, 2]), np.sin(starts[:, 2])], 1)
        arrows = geo.arrow_segments(starts[:, :2] * geo.MM, heads * geo.MM, head=0.012)
        self._starts.points = arrows.astype(np.float32)
        for label, (x, y, _) in zip(self._start_labels, starts, strict=True):
            label.position = (float(x) * geo.MM, float(y) * geo.MM, 0.0)
        self.arena = arena

    def set_visible(self, visible: bool) -> None:
        """Show or hide the whole arena (a task run on show draws its task's frame here)."""
        robots = [h for handles in self._robots for h in handles.values()]
        for handle in (self._walls, self._starts, *self._start_labels, *robots):
            if handle.visible != visible:
                handle.visible = visible

    def update(self, robots: tuple[RobotSnapshot, ...]) -> None:
        """Draw the robots of a snapshot; hide the unused slots."""
        for i, handles in enumerate(self._robots):
            if i >= len(robots):
                for handle in handles.values():
                    handle.visible = False
                continue
            self._draw_robot(handles, robots[i], ROBOT_COLORS[i])

    def _draw_robot(
        self,
        handles: dict[str, viser.LineSegmentsHandle],
        robot: RobotSnapshot,
        color: tuple[int, int, int],
    ) -> None:
        pose = robot.pose[None, :]
        x, y, heading = robot.pose
        nose = np.array(
            [[x + sim.BODY_RADIUS_MM * np.cos(heading), y + sim.BODY_RADIUS_MM * np.sin(heading)]]
        )
        body = np.concatenate(
            [
                geo.circle_segments(pose[:, :2] * geo.MM, sim.BODY_RADIUS_MM * geo.MM),
                geo.flat_to_3d(np.stack([pose[:, :2], nose], axis=1) * geo.MM),
            ]
        )
        handles["body"].points = body.astype(np.float32)
        handles["body"].colors = np.broadcast_to(np.array(color, np.uint8), body.shape).copy()

        origins, directions = sim.sensor_rays(pose)
        readings = robot.seen_readings
        # A ray ends where it meets a wall (its true reading says how far; through nothing it is
        # as long as the range), brighter the higher what the controller saw.
        reach = ir_distances(robot.true_readings)
        ends = origins[0] + directions[0] * reach[:, None]
        rays = geo.flat_to_3d(np.stack([origins[0], ends], axis=1) * geo.MM, z=0.001)
        ray_colors = np.repeat(geo.reading_colors(readings)[:, None, :], 2, axis=1)
        ray_colors[robot.broken] = BROKEN_RED
        handles["rays"].points = rays.astype(np.float32)
        handles["rays"].colors = ray_colors

        # A broken sensor: a red cross at its origin (degenerate when intact, fixed shape).
        marks = origins[0] + directions[0] * 12.0  # just outside the body, on the ray
        crosses = geo.cross_segments(marks * geo.MM, 0.014).reshape(sim.N_SENSORS, 2, 2, 3)
        crosses[~robot.broken] = 0.0
        crosses[~robot.broken] += np.array([x, y, 0.0]) * geo.MM
        faults = crosses.reshape(2 * sim.N_SENSORS, 2, 3)
        handles["faults"].points = faults.astype(np.float32)
        handles["faults"].colors = np.broadcast_to(
            np.array(BROKEN_RED, np.uint8), faults.shape
        ).copy()

        trail = _padded(robot.trajectory, TRAIL_POINTS)
        segments = geo.polyline_segments(trail * geo.MM)
        point_colors = geo.reward_colors(_padded(robot.trajectory_reward, TRAIL_POINTS), 0.0, 0.8)
        handles["trail"].points = segments.astype(np.float32)
        handles["trail"].colors = geo.segment_colors(point_colors)
        for handle in handles.values():
            handle.visible = True


def _padded(values: np.ndarray, n: int) -> np.ndarray:
    """The last n rows, front-padded by repeating the first row (so shapes never change)."""
    values = np.asarray(values)[-n:]
    if len(values) == 0:
        raise ValueError("nothing to pad")
    pad = np.repeat(values[:1], n - len(values), axis=0)
    return np.concatenate([pad, values])
