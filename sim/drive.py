"""numba kernels of the force drive: wheel commands clipped, turned into the forces and torques
that move the robots' bodies, and the bodies' poses read back."""

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
        turn_c = np.cos(spin * dt)
        turn_s = np.sin(spin * dt)
        r = rows[i]
        for j in range(out.shape[0]):
            out[j, r, 0] = force * c
            out[j, r, 1] = force * s
            out[j, r, 2] = torque
            c, s = c * turn_c - s * turn_s, s * turn_c + c * turn_s


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
