"""The reward of Eq. 2.7, as named terms."""

import numpy as np

from sim.khepera import MAX_COMMAND

NEAR_WALL_MAX = 1000.0
"""C = 0 if any true reading reaches this (touching a wall)."""
NEAR_WALL_MIN = 100.0
"""C = 0 unless some true reading exceeds this (a wall is near)."""

TERM_NAMES = ("reward", "reward/speed", "reward/straightness", "reward/near_wall")
"""The named reward terms `reward_terms` returns, in this order (the store's column order)."""


def reward_terms(true_readings: np.ndarray, commands: np.ndarray) -> dict[str, np.ndarray]:
    """Eq. 2.7: r = (vR + vL)/20 · (1 − sqrt(|vR − vL|/20)) · C.

    Args:
        true_readings: (N, 8) true readings (``world.sense()``), not what the controller saw.
        commands: (N, 2) left, right wheel commands of the step, clipped to −10..10 as the
            world applies them.

    Returns:
        (N,) arrays: ``reward``, ``reward/speed`` = (vR + vL)/20, ``reward/straightness`` =
        1 − sqrt(|vR − vL|/20), ``reward/near_wall`` = C (1 iff every reading < 1000 and at
        least one > 100).
    """
    readings = np.asarray(true_readings, dtype=np.float64)
    cmd = np.asarray(commands, dtype=np.float64)
    if readings.ndim != 2 or readings.shape[1] != 8:
        raise ValueError(f"true_readings must have shape (N, 8), got {readings.shape}")
    if cmd.shape != (readings.shape[0], 2):
        raise ValueError(f"commands must have shape ({readings.shape[0]}, 2), got {cmd.shape}")
    cmd = np.clip(cmd, -MAX_COMMAND, MAX_COMMAND)
    left, right = cmd[:, 0], cmd[:, 1]
    span = 2 * MAX_COMMAND
    speed = (right + left) / span
    straightness = 1.0 - np.sqrt(np.abs(right - left) / span)
    near_wall = (
        np.all(readings < NEAR_WALL_MAX, axis=1) & np.any(readings > NEAR_WALL_MIN, axis=1)
    ).astype(np.float64)
    return {
        "reward": speed * straightness * near_wall,
        "reward/speed": speed,
        "reward/straightness": straightness,
        "reward/near_wall": near_wall,
    }
