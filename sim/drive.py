"""numba kernels of the force drive: wheel commands clipped, turned into the forces and torques
that move the robots' bodies, and the bodies' poses read back."""

import functools

import numba as nb
import numpy as np

from sim.kernel_cache import KHEPERA_CONSTANTS, drop_stale_cache
from sim.khepera import AXLE_MM, MASS, MAX_COMMAND, MOMENT, WHEEL_RADIUS_MM


@nb.njit(cache=True)
def drive_forces(
    angles: np.ndarray,
    spins: np.ndarray,
    commands: np.ndarray,
    rows: np.ndarray,
    dt: float,
    out: np.ndarray,
    turns: np.ndarray,
) -> None:
    """Forces and torques that drive each robot at its wheel commands, for every substep.

    The space has damping 0, so after a physics step a body's velocity is force·dt/m (then the
    contacts act, and frictionless contacts on a disc exert no torque): F = m·v/dt, τ = I·ω/dt.
    Chipmunk moves a body with the velocity set in the step before, so the velocity set in
    substep j is aimed along the heading halfway through substep j + 1: the chord of the arc.

    Args:
        angles: (N,) headings now.
        spins: (N,) angular velocities the bodies carry into the first substep.
        commands: (N, 2) left, right wheel commands (rad/s), already clipped.
        rows: (N,) each robot's body row in out.
        dt: Substep length (s).
        out: (K, B, 3) fx, fy, τ for K substeps and every body of the space; rows of other
            bodies are left as they are.
        turns: ``turn_table(dt)``, the turn per substep of whole-number commands (their
            `cos` and `sin` looked up, not computed: the same bits), or an empty (0, 2) array
            to compute every one.
    """
    for i in range(commands.shape[0]):
        left = commands[i, 0] * WHEEL_RADIUS_MM
        right = commands[i, 1] * WHEEL_RADIUS_MM
        force = MASS * 0.5 * (left + right) / dt
        spin = (right - left) / AXLE_MM
        torque = MOMENT * spin / dt
        heading = angles[i] + spins[i] * dt + 0.5 * spin * dt
        c = np.cos(heading)  # direction in substep 0, then turned by spin·dt per substep
        s = np.sin(heading)
        turn_c, turn_s = _turn(commands[i, 0], commands[i, 1], spin * dt, turns)
        r = rows[i]
        for j in range(out.shape[0]):
            out[j, r, 0] = force * c
            out[j, r, 1] = force * s
            out[j, r, 2] = torque
            c, s = c * turn_c - s * turn_s, s * turn_c + c * turn_s


TURN_SPAN = 2 * int(MAX_COMMAND)
"""Whole-number commands −MAX_COMMAND..MAX_COMMAND differ by −TURN_SPAN..TURN_SPAN."""


@functools.cache
def turns_for(dt: float) -> np.ndarray:
    """``turn_table(dt)``, made once per substep length (read-only)."""
    table = turn_table(dt)
    table.setflags(write=False)
    return table


@nb.njit(cache=True)
def turn_table(dt: float) -> np.ndarray:
    """(2·TURN_SPAN + 1, 2) `cos` and `sin` of the turn per substep of `dt` for wheel commands
    that are whole numbers, by their difference right − left = d (row d + TURN_SPAN): the
    operations `drive_forces` does on them. Both commands times WHEEL_RADIUS_MM are exact
    (halves of whole numbers), so their difference is d·WHEEL_RADIUS_MM exactly, whichever
    the pair; `cos` and `sin` are the same libm calls on the same argument."""
    table = np.empty((2 * TURN_SPAN + 1, 2))
    for d in range(-TURN_SPAN, TURN_SPAN + 1):
        spin = float(d) * WHEEL_RADIUS_MM / AXLE_MM
        table[d + TURN_SPAN, 0] = np.cos(spin * dt)
        table[d + TURN_SPAN, 1] = np.sin(spin * dt)
    return table


@nb.njit(cache=True, inline="always")
def _turn(left: float, right: float, angle: float, turns: np.ndarray) -> tuple[float, float]:
    """`cos` and `sin` of `angle`, the turn per substep at commands (left, right): a row of
    `turns` when both are whole numbers within ±MAX_COMMAND (commands take few values: a GNP
    controller's are whole numbers), exactly (1, angle) for no turn (cos ±0 = 1 and sin ±0 =
    ±0, the zero's sign kept), else computed."""
    if angle == 0.0:
        return 1.0, angle
    if (
        turns.shape[0] > 0
        and abs(left) <= MAX_COMMAND
        and abs(right) <= MAX_COMMAND
        and left == np.floor(left)
        and right == np.floor(right)
    ):
        d = int(right) - int(left) + TURN_SPAN
        return turns[d, 0], turns[d, 1]
    return np.cos(angle), np.sin(angle)


@nb.njit(cache=True)
def wheel_spins(commands: np.ndarray, out: np.ndarray) -> None:
    """Angular velocities (N,) of robots driven at commands (N, 2)."""
    for i in range(commands.shape[0]):
        out[i] = (commands[i, 1] - commands[i, 0]) * WHEEL_RADIUS_MM / AXLE_MM


@nb.njit(cache=True)
def gather_poses(
    buffer: np.ndarray, rows: np.ndarray, offsets: np.ndarray, out: np.ndarray
) -> None:
    """Arena-local poses (n, 3) from a pymunk batch buffer of x, y, angle rows."""
    for i in range(rows.shape[0]):
        r = 3 * rows[i]
        out[i, 0] = buffer[r] - offsets[i, 0]
        out[i, 1] = buffer[r + 1] - offsets[i, 1]
        out[i, 2] = buffer[r + 2]


@nb.njit(cache=True)
def clip_commands(commands: np.ndarray, out: np.ndarray) -> bool:
    """Clip commands to ±MAX_COMMAND into out; False if any is NaN."""
    for i in range(commands.shape[0]):
        for j in range(2):
            v = commands[i, j]
            if v != v:
                return False
            out[i, j] = min(MAX_COMMAND, max(-MAX_COMMAND, v))
    return True


@nb.njit(cache=True)
def _frozen_constants() -> np.ndarray:
    """``KHEPERA_CONSTANTS`` as numba froze them into this module's cache."""
    return KHEPERA_CONSTANTS.copy()


drop_stale_cache(globals(), _frozen_constants)
