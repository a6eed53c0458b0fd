"""The reward of Eq. 2.7, as named terms."""

import numba as nb
import numpy as np

from sim.kernel_cache import KHEPERA_CONSTANTS, drop_stale_cache
from sim.khepera import MAX_COMMAND, N_SENSORS
from sim.kinds import C_FROM as C_FROM  # C_FROM, CFrom: still importable from here
from sim.kinds import TERM_NAMES
from sim.kinds import CFrom as CFrom

NEAR_WALL_MAX = 1000.0
"""C = 0 if any reading reaches this (touching a wall)."""
NEAR_WALL_MIN = 100.0
"""C = 0 unless some reading exceeds this (a wall is near)."""


@nb.njit(cache=True)
def reward_kernel(readings: np.ndarray, commands: np.ndarray, out: np.ndarray) -> None:
    span = 2.0 * MAX_COMMAND
    for i in range(readings.shape[0]):
        left = min(max(commands[i, 0], -MAX_COMMAND), MAX_COMMAND)
        right = min(max(commands[i, 1], -MAX_COMMAND), MAX_COMMAND)
        touching = False
        near = False
        for j in range(readings.shape[1]):
            touching |= not readings[i, j] < NEAR_WALL_MAX
            near |= readings[i, j] > NEAR_WALL_MIN
        near_wall = 1.0 if near and not touching else 0.0
        speed = (right + left) / span
        straightness = 1.0 - np.sqrt(np.abs(right - left) / span)
        out[i, 0] = speed * straightness * near_wall
        out[i, 1] = speed
        out[i, 2] = straightness
        out[i, 3] = near_wall


def reward_table(
    readings: np.ndarray, commands: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """Eq. 2.7 for N robots as an (N, 4) table whose columns are `TERM_NAMES`.

    r = (vR + vL)/20 · (1 − sqrt(|vR − vL|/20)) · C, with the terms speed = (vR + vL)/20,
    straightness = 1 − sqrt(|vR − vL|/20) and near_wall = C (1 iff every reading < 1000 and at
    least one > 100). The readings serve C alone; which readings judge it is the caller's choice.

    Args:
        readings: (N, 8) readings C is judged from: the true readings (``world.sense()``) or
            what the controller sees (``world.observe()``: noise, then faults).
        commands: (N, 2) left, right wheel commands of the step, clipped to −10..10 as the
            world applies them.
        out: an (N, 4) float64 array to write into (a new one by default).
    """
    readings = np.ascontiguousarray(readings, dtype=np.float64)
    cmd = np.ascontiguousarray(commands, dtype=np.float64)
    if readings.ndim != 2 or readings.shape[1] != N_SENSORS:
        raise ValueError(f"readings must have shape (N, 8), got {readings.shape}")
    if cmd.shape != (readings.shape[0], 2):
        raise ValueError(f"commands must have shape ({readings.shape[0]}, 2), got {cmd.shape}")
    shape = (readings.shape[0], len(TERM_NAMES))
    if out is None:
        out = np.empty(shape)
    elif out.shape != shape or out.dtype != np.float64:
        raise ValueError(f"out must be a float64 array of shape {shape}, got {out.shape}")
    reward_kernel(readings, cmd, out)
    return out


def reward_terms(readings: np.ndarray, commands: np.ndarray) -> dict[str, np.ndarray]:
    """Eq. 2.7 as named (N,) arrays: ``reward``, ``reward/speed``, ``reward/straightness``,
    ``reward/near_wall``, C judged from `readings` (see `reward_table`)."""
    table = reward_table(readings, commands)
    return {name: table[:, column] for column, name in enumerate(TERM_NAMES)}


@nb.njit(cache=True)
def _frozen_constants() -> np.ndarray:
    """``KHEPERA_CONSTANTS`` as numba froze them into this module's cache."""
    return KHEPERA_CONSTANTS.copy()


drop_stale_cache(globals(), _frozen_constants)
