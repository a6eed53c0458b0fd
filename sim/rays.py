"""numba kernels of the IR sensors and the arena's geometry: rays cast against wall segments,
distances to the walls, points inside a polygon."""

import numba as nb
import numpy as np

from sim.kernel_cache import KHEPERA_CONSTANTS, drop_stale_cache
from sim.khepera import (
    BODY_RADIUS_MM,
    IR_BACKOFF_MM,
    IR_MAX,
    IR_RANGE_MM,
    N_SENSORS,
    SENSOR_HEADINGS_RAD,
    SENSOR_ORIGINS_MM,
)

_SENSOR_X = SENSOR_ORIGINS_MM[:, 0].copy()
_SENSOR_Y = SENSOR_ORIGINS_MM[:, 1].copy()
_SENSOR_COS = np.cos(SENSOR_HEADINGS_RAD)
_SENSOR_SIN = np.sin(SENSOR_HEADINGS_RAD)
REACH_MM = BODY_RADIUS_MM + IR_RANGE_MM + 1.0
"""No ray reaches a wall farther than this from the robot's centre (the rays end within
BODY_RADIUS_MM + IR_RANGE_MM of it; the extra millimetre dwarfs any rounding)."""


def wall_table(walls: np.ndarray) -> np.ndarray:
    """(K, 5) rows of px, py, ex, ey, 1/|e|² for wall segments (K, 2, 2) from p to p + e."""
    p = walls[:, 0]
    e = walls[:, 1] - walls[:, 0]
    return np.ascontiguousarray(
        np.column_stack([p, e, 1.0 / np.einsum("ij,ij->i", e, e)]), dtype=np.float64
    )


@nb.njit(cache=True)
def ir_readings(poses: np.ndarray, table: np.ndarray, out: np.ndarray) -> None:
    """True IR readings (N, 8) into out, for poses (N, 3) among walls given by ``wall_table``.

    The reference that ``ir_readings_grid`` equals to the bit (tested); it tests every wall for
    reach. Each ray starts ``IR_BACKOFF_MM`` behind its sensor and is intersected with every wall
    within reach of the body: t = ((p − a) × e) / (d × e), u = ((p − a) × d) / (d × e), a hit
    iff 0 ≤ u ≤ 1 and 0 ≤ t ≤ length. Parallel walls are not seen (edge-on).
    """
    n = poses.shape[0]
    k = table.shape[0]
    near = np.empty(k, dtype=np.int64)
    length = IR_RANGE_MM + IR_BACKOFF_MM
    reach2 = REACH_MM * REACH_MM
    for i in range(n):
        x = poses[i, 0]
        y = poses[i, 1]
        c = np.cos(poses[i, 2])
        s = np.sin(poses[i, 2])
        m = 0
        for w in range(k):  # only walls within reach of the body's rays
            px = table[w, 0]
            py = table[w, 1]
            ex = table[w, 2]
            ey = table[w, 3]
            t = min(1.0, max(0.0, ((x - px) * ex + (y - py) * ey) * table[w, 4]))
            cx = px + t * ex - x
            cy = py + t * ey - y
            if cx * cx + cy * cy <= reach2:
                near[m] = w
                m += 1
        for j in range(N_SENSORS):
            dx = c * _SENSOR_COS[j] - s * _SENSOR_SIN[j]
            dy = s * _SENSOR_COS[j] + c * _SENSOR_SIN[j]
            ax = x + c * _SENSOR_X[j] - s * _SENSOR_Y[j] - IR_BACKOFF_MM * dx
            ay = y + s * _SENSOR_X[j] + c * _SENSOR_Y[j] - IR_BACKOFF_MM * dy
            best = np.inf
            for q in range(m):
                w = near[q]
                ex = table[w, 2]
                ey = table[w, 3]
                denom = dx * ey - dy * ex
                if denom == 0.0:
                    continue
                wx = table[w, 0] - ax
                wy = table[w, 1] - ay
                t = (wx * ey - wy * ex) / denom
                if t < 0.0 or t >= best or t > length:
                    continue
                u = (wx * dy - wy * dx) / denom
                if 0.0 <= u <= 1.0:
                    best = t
            d = max(0.0, best - IR_BACKOFF_MM)
            out[i, j] = IR_MAX * max(0.0, 1.0 - d / IR_RANGE_MM)


@nb.njit(cache=True, error_model="numpy")  # x / 0 is ±inf or NaN, not an exception
def ir_readings_grid(
    poses: np.ndarray,
    table: np.ndarray,
    frame: np.ndarray,
    starts: np.ndarray,
    members: np.ndarray,
    out: np.ndarray,
) -> None:
    """``ir_readings`` testing for reach only the walls listed for the robot's grid cell.

    The same arithmetic as ``ir_readings`` on the same walls, so the same bits: a wall out of
    reach cannot be hit and the cell lists every wall within reach. Walls outer, rays inner and
    no branches in the ray test (a mispredicted branch costs more than the test).

    Args:
        poses: (N, 3) poses.
        table: (K, 5) ``wall_table`` rows.
        frame: x0, y0, cell side, columns, rows of the grid (see ``sim.sensors.WallGrid``).
        starts: (cells + 1,) cell c's walls are members[starts[c]:starts[c + 1]].
        members: Wall indices, ascending within a cell; a superset of the walls within reach
            of any point of the cell. A robot off the grid tests every wall.
        out: (N, 8) readings.
    """
    near = np.empty(table.shape[0], dtype=np.int64)
    ray_dx = np.empty(N_SENSORS)
    ray_dy = np.empty(N_SENSORS)
    ray_ax = np.empty(N_SENSORS)
    ray_ay = np.empty(N_SENSORS)
    ray_best = np.empty(N_SENSORS)
    length = IR_RANGE_MM + IR_BACKOFF_MM
    reach2 = REACH_MM * REACH_MM
    for i in range(poses.shape[0]):
        x = poses[i, 0]
        y = poses[i, 1]
        col = np.floor((x - frame[0]) / frame[2])
        row = np.floor((y - frame[1]) / frame[2])
        # The cell's walls by index, not as a slice: a slice is a new array, whose reference
        # counting (two atomic operations) costs more than the loop it feeds.
        on_grid = 0.0 <= col < frame[3] and 0.0 <= row < frame[4]
        first, last = 0, table.shape[0]
        if on_grid:
            cell = int(row) * int(frame[3]) + int(col)
            first, last = starts[cell], starts[cell + 1]
        m = 0
        for listed in range(first, last):
            w = members[listed] if on_grid else listed
            px = table[w, 0]
            py = table[w, 1]
            ex = table[w, 2]
            ey = table[w, 3]
            t = min(1.0, max(0.0, ((x - px) * ex + (y - py) * ey) * table[w, 4]))
            cx = px + t * ex - x
            cy = py + t * ey - y
            if cx * cx + cy * cy <= reach2:
                near[m] = w
                m += 1
        if m == 0:  # nothing in reach: every ray misses (best = inf below) and reads 0
            for j in range(N_SENSORS):
                out[i, j] = 0.0
            continue
        c = np.cos(poses[i, 2])
        s = np.sin(poses[i, 2])
        for j in range(N_SENSORS):
            dx = c * _SENSOR_COS[j] - s * _SENSOR_SIN[j]
            dy = s * _SENSOR_COS[j] + c * _SENSOR_SIN[j]
            ray_dx[j] = dx
            ray_dy[j] = dy
            ray_ax[j] = x + c * _SENSOR_X[j] - s * _SENSOR_Y[j] - IR_BACKOFF_MM * dx
            ray_ay[j] = y + s * _SENSOR_X[j] + c * _SENSOR_Y[j] - IR_BACKOFF_MM * dy
            ray_best[j] = np.inf
        for q in range(m):
            w = near[q]
            px = table[w, 0]
            py = table[w, 1]
            ex = table[w, 2]
            ey = table[w, 3]
            for j in range(N_SENSORS):
                dx = ray_dx[j]
                dy = ray_dy[j]
                denom = dx * ey - dy * ex
                wx = px - ray_ax[j]
                wy = py - ray_ay[j]
                t = (wx * ey - wy * ex) / denom  # ±inf or NaN if denom = 0: rejected below
                u = (wx * dy - wy * dx) / denom
                best = ray_best[j]
                # ir_readings' "not (t < 0 or t ≥ best or t > length) and 0 ≤ u ≤ 1"
                hit = (not t < 0.0) & (not t >= best) & (not t > length) & (u >= 0.0) & (u <= 1.0)
                ray_best[j] = t if hit & (denom != 0.0) else best
        for j in range(N_SENSORS):
            d = max(0.0, ray_best[j] - IR_BACKOFF_MM)
            out[i, j] = IR_MAX * max(0.0, 1.0 - d / IR_RANGE_MM)


@nb.njit(cache=True)
def wall_distances(points: np.ndarray, table: np.ndarray, out: np.ndarray) -> None:
    """Distance (N,) from each point (N, 2) to the nearest wall of ``wall_table``, into out."""
    for i in range(points.shape[0]):
        x = points[i, 0]
        y = points[i, 1]
        best = np.inf
        for w in range(table.shape[0]):
            px = table[w, 0]
            py = table[w, 1]
            ex = table[w, 2]
            ey = table[w, 3]
            t = min(1.0, max(0.0, ((x - px) * ex + (y - py) * ey) * table[w, 4]))
            cx = px + t * ex - x
            cy = py + t * ey - y
            best = min(best, cx * cx + cy * cy)
        out[i] = np.sqrt(best)


@nb.njit(cache=True)
def in_polygon(points: np.ndarray, polygon: np.ndarray, out: np.ndarray) -> None:
    """Even-odd test: whether each point (N, 2) is inside polygon (M, 2), into out (N,)."""
    m = polygon.shape[0]
    for i in range(points.shape[0]):
        x = points[i, 0]
        y = points[i, 1]
        inside = False
        for k in range(m):
            x0 = polygon[k, 0]
            y0 = polygon[k, 1]
            x1 = polygon[(k + 1) % m, 0]
            y1 = polygon[(k + 1) % m, 1]
            if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
                inside = not inside
        out[i] = inside


@nb.njit(cache=True)
def _frozen_constants() -> np.ndarray:
    """``KHEPERA_CONSTANTS`` as numba froze them into this module's cache."""
    return KHEPERA_CONSTANTS.copy()


drop_stale_cache(globals(), _frozen_constants)
