"""IR sensing of N robots from their poses and the arena's walls, and ray geometry for drawing.

The hot loop's readings come from ``ir_readings``: any physics that knows the robots' poses
calls it (the numba kernels are in ``sim.rays``). A ``WallGrid``, built once per arena, lists
for each square cell the walls that may come within reach of a robot centred in it, so a robot
tests a few walls rather than all of them; the readings are those of testing every wall, to the
bit (a wall out of reach cannot be hit, and every wall within reach is listed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim import rays
from sim.khepera import IR_MAX, IR_RANGE_MM, N_SENSORS, SENSOR_HEADINGS_RAD, SENSOR_ORIGINS_MM

GRID_CELL_MM = 20.0
"""Side of a ``WallGrid`` cell: small against the reach (80 mm), so a cell lists few more walls
than its robots can reach (1.2 on average in the shipped arenas, of 18-19)."""
_SLACK_MM = 1.0
"""Margin on the listing distance: a robot rounded into a neighbour cell is still covered."""


@dataclass(frozen=True, eq=False)
class WallGrid:
    """The walls near each cell of a square grid over an arena.

    Attributes:
        table: (K, 5) ``sim.rays.wall_table`` rows of the walls.
        frame: (5,) x0, y0, cell side, columns, rows: cell (col, row) is the square from
            (x0 + col·side, y0 + row·side), numbered row·columns + col.
        starts: (cells + 1,) int64: cell c lists members[starts[c]:starts[c + 1]].
        members: int64 wall indices, ascending within each cell.
    """

    table: np.ndarray
    frame: np.ndarray
    starts: np.ndarray
    members: np.ndarray


def wall_grid(walls: np.ndarray, cell: float = GRID_CELL_MM) -> WallGrid:
    """The ``WallGrid`` of wall segments (K, 2, 2), with square cells of side ``cell`` mm.

    A cell lists every wall within reach + half its diagonal + a slack of its centre: by the
    triangle inequality, every wall within reach of any point of the cell.
    """
    walls = np.asarray(walls, dtype=np.float64)
    table = rays.wall_table(walls)
    lo = walls.reshape(-1, 2).min(axis=0) - rays.REACH_MM
    hi = walls.reshape(-1, 2).max(axis=0) + rays.REACH_MM
    cols, rows = (int(v) for v in np.ceil((hi - lo) / cell))
    centres = np.stack(
        np.meshgrid(lo[0] + (np.arange(cols) + 0.5) * cell, lo[1] + (np.arange(rows) + 0.5) * cell),
        axis=-1,
    ).reshape(-1, 2)  # row-major: cell row·cols + col
    gaps = np.empty((len(walls), len(centres)))
    for w in range(len(walls)):  # a few dozen walls: one vector pass each
        rays.wall_distances(centres, table[w : w + 1], gaps[w])
    radius = rays.REACH_MM + cell * np.sqrt(0.5) + _SLACK_MM
    listed = radius >= gaps.T  # (cells, K)
    starts = np.concatenate([[0], np.cumsum(listed.sum(axis=1))]).astype(np.int64)
    members = np.nonzero(listed)[1].astype(np.int64)  # row by row: ascending within a cell
    frame = np.array([lo[0], lo[1], cell, cols, rows], dtype=np.float64)
    return WallGrid(table=table, frame=frame, starts=starts, members=members)


def ir_readings(poses: np.ndarray, grid: WallGrid, out: np.ndarray | None = None) -> np.ndarray:
    """True IR readings (N, 8) of robots at poses (N, 3) among the grid's walls.

    Args:
        poses: (N, 3) x mm, y mm, heading rad (arena frame).
        grid: The arena's ``WallGrid`` (``Arena.wall_grid``).
        out: An (N, 8) float64 C-contiguous array to write into (a new one by default).
    """
    poses = np.ascontiguousarray(poses, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"poses must have shape (N, 3), got {poses.shape}")
    if out is None:
        out = np.empty((len(poses), N_SENSORS))
    rays.ir_readings_grid(poses, grid.table, grid.frame, grid.starts, grid.members, out)
    return out


def sensor_rays(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sensor ray origins and unit directions in the arena frame.

    Args:
        poses: (N, 3) x mm, y mm, heading rad.

    Returns:
        origins (N, 8, 2) mm and directions (N, 8, 2); a ray's reach is ``sim.IR_RANGE_MM``.
    """
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    c = np.cos(poses[:, 2])[:, None]
    s = np.sin(poses[:, 2])[:, None]
    ox, oy = SENSOR_ORIGINS_MM[:, 0], SENSOR_ORIGINS_MM[:, 1]
    origins = np.stack([poses[:, 0:1] + c * ox - s * oy, poses[:, 1:2] + s * ox + c * oy], axis=-1)
    angles = poses[:, 2:3] + SENSOR_HEADINGS_RAD
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    return origins, directions


def ir_distances(readings: np.ndarray) -> np.ndarray:
    """How far each ray reaches, in mm from its sensor, given its true reading (for drawing).

    The inverse of reading = IR_MAX · max(0, 1 − d / IR_RANGE_MM): a ray that sees a wall ends
    on it; one reading 0 sees nothing within ``IR_RANGE_MM`` and is that long.

    Args:
        readings: true readings (any shape), in 0..IR_MAX (noise or faults would lie).
    """
    clipped = np.clip(np.asarray(readings, dtype=np.float64), 0.0, IR_MAX)
    return IR_RANGE_MM * (1.0 - clipped / IR_MAX)
