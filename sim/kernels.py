"""numba kernels of the hot loop: IR ray casting, the force drive and per-robot random streams.

The random streams are counter-based: a value is a hash of (robot key, step, sensor, draw), so a
robot's draws depend on nothing but its own key and clock (see docs/decisions/sim.md).
"""

import numba as nb
import numpy as np

from sim.khepera import (
    AXLE_MM,
    BODY_RADIUS_MM,
    IR_BACKOFF_MM,
    IR_MAX,
    IR_RANGE_MM,
    MASS,
    MAX_COMMAND,
    MOMENT,
    N_SENSORS,
    SENSOR_HEADINGS_RAD,
    SENSOR_ORIGINS_MM,
    WHEEL_RADIUS_MM,
)

_SENSOR_X = SENSOR_ORIGINS_MM[:, 0].copy()
_SENSOR_Y = SENSOR_ORIGINS_MM[:, 1].copy()
_SENSOR_COS = np.cos(SENSOR_HEADINGS_RAD)
_SENSOR_SIN = np.sin(SENSOR_HEADINGS_RAD)
_REACH = BODY_RADIUS_MM + IR_RANGE_MM + 1.0
"""No ray reaches a wall farther than this from the robot's centre."""


@nb.njit(cache=True, inline="always")
def _ray_hit(
    ax: float, ay: float, dx: float, dy: float, length: float, p: np.ndarray, q: np.ndarray
) -> float:
    """Distance along the ray a + t·d (|d| = 1, 0 ≤ t ≤ length) to segment pq, or inf."""
    ex = q[0] - p[0]
    ey = q[1] - p[1]
    denom = dx * ey - dy * ex
    if denom == 0.0:
        return np.inf  # parallel: a grazing ray sees the wall edge-on, i.e. nothing
    wx = p[0] - ax
    wy = p[1] - ay
    t = (wx * ey - wy * ex) / denom
    u = (wx * dy - wy * dx) / denom
    if u < 0.0 or u > 1.0 or t < 0.0 or t > length:
        return np.inf
    return t


@nb.njit(cache=True)
def ir_readings(poses: np.ndarray, walls: np.ndarray, out: np.ndarray) -> None:
    """True IR readings (N, 8) for poses (N, 3) in the frame of walls (K, 2, 2), into out."""
    n = poses.shape[0]
    k = walls.shape[0]
    near = np.empty(k, dtype=np.int64)
    length = IR_RANGE_MM + IR_BACKOFF_MM
    for i in range(n):
        x = poses[i, 0]
        y = poses[i, 1]
        c = np.cos(poses[i, 2])
        s = np.sin(poses[i, 2])
        m = 0
        for w in range(k):  # only walls within reach of the body's rays
            px = walls[w, 0, 0]
            py = walls[w, 0, 1]
            ex = walls[w, 1, 0] - px
            ey = walls[w, 1, 1] - py
            t = ((x - px) * ex + (y - py) * ey) / (ex * ex + ey * ey)
            t = min(1.0, max(0.0, t))
            cx = px + t * ex - x
            cy = py + t * ey - y
            if cx * cx + cy * cy <= _REACH * _REACH:
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
                t = _ray_hit(ax, ay, dx, dy, length, walls[w, 0], walls[w, 1])
                best = min(best, t)
            d = max(0.0, best - IR_BACKOFF_MM)
            out[i, j] = IR_MAX * max(0.0, 1.0 - d / IR_RANGE_MM)


@nb.njit(cache=True)
def drive_forces(
    angles: np.ndarray, commands: np.ndarray, rows: np.ndarray, dt: float, out: np.ndarray
) -> None:
    """Force and torque that give each robot its commanded wheel speeds after one substep.

    The space has damping 0, so a body's velocity after a substep is exactly force·dt/m (then
    contacts act): F = m·v/dt and τ = I·ω/dt, with no memory of the previous velocity.

    Args:
        angles: (N,) robot headings.
        commands: (N, 2) left, right wheel commands (rad/s), already clipped.
        rows: (N,) each robot's row in out.
        dt: Substep length (s).
        out: (B, 3) rows of fx, fy, τ for every body of the space; other rows are untouched.
    """
    for i in range(commands.shape[0]):
        left = commands[i, 0] * WHEEL_RADIUS_MM
        right = commands[i, 1] * WHEEL_RADIUS_MM
        speed = 0.5 * (left + right)
        spin = (right - left) / AXLE_MM
        r = rows[i]
        out[r, 0] = MASS * speed * np.cos(angles[i]) / dt
        out[r, 1] = MASS * speed * np.sin(angles[i]) / dt
        out[r, 2] = MOMENT * spin / dt


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


# --- counter-based random streams ---

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_TWO_PI = 2.0 * np.pi
_DRAW_NORMAL_A = 0
_DRAW_NORMAL_B = 1
_DRAW_UNIFORM = 2


@nb.njit(cache=True, inline="always")
def splitmix64(z: np.uint64) -> np.uint64:
    """The splitmix64 finaliser: a bijective 64-bit mix."""
    z = z + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


@nb.njit(cache=True, inline="always")
def _uniform(key: np.uint64, step: np.uint64, sensor: int, draw: int) -> float:
    """A uniform float in [0, 1) from (key, step, sensor, draw)."""
    counter = (step << np.uint64(8)) | np.uint64(sensor * 4 + draw)
    h = splitmix64(key ^ splitmix64(counter))
    return float(h >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@nb.njit(cache=True)
def robot_keys(seeds: np.ndarray) -> np.ndarray:
    """Stream keys (N,) uint64 from per-robot seeds (N,) uint64."""
    keys = np.empty(seeds.shape[0], dtype=np.uint64)
    for i in range(seeds.shape[0]):
        keys[i] = splitmix64(splitmix64(seeds[i]) ^ _MIX2)
    return keys


@nb.njit(cache=True)
def derive_seeds(seed: np.uint64, episode: np.uint64, n: int) -> np.ndarray:
    """Default per-robot seeds (n,) uint64 from (world seed, episode, robot index)."""
    base = splitmix64(splitmix64(seed) ^ splitmix64(episode + _MIX1))
    out = np.empty(n, dtype=np.uint64)
    for i in range(n):
        out[i] = splitmix64(base ^ splitmix64(np.uint64(i)))
    return out


@nb.njit(cache=True)
def observe(
    true: np.ndarray,
    keys: np.ndarray,
    step: np.uint64,
    sigma: float,
    mode: np.ndarray,
    stuck: np.ndarray,
    out: np.ndarray,
) -> None:
    """What the controller sees: Eq. 2.6 noise, then faults.

    Args:
        true: (N, 8) true readings.
        keys: (N,) robot stream keys.
        step: The world clock; draws are a function of (key, step, sensor).
        sigma: Noise standard deviation (reading units); 0 for none.
        mode: (N, 8) int8 fault modes (see ``sim.world.FAULT_MODES``; 0 = healthy).
        stuck: (N, 8) the value a ``stuck`` sensor keeps.
        out: (N, 8) result.
    """
    for i in range(true.shape[0]):
        key = keys[i]
        for j in range(N_SENSORS):
            x = true[i, j]
            if sigma > 0.0:
                u1 = 1.0 - _uniform(key, step, j, _DRAW_NORMAL_A)  # in (0, 1]
                u2 = _uniform(key, step, j, _DRAW_NORMAL_B)
                x += sigma * np.sqrt(-2.0 * np.log(u1)) * np.cos(_TWO_PI * u2)
                x = min(IR_MAX, max(0.0, x))
            f = mode[i, j]
            if f == 1:  # dead
                x = 0.0
            elif f == 2:  # saturated
                x = IR_MAX
            elif f == 3:  # stuck
                x = stuck[i, j]
            elif f == 4:  # random
                x = IR_MAX * _uniform(key, step, j, _DRAW_UNIFORM)
            out[i, j] = x
