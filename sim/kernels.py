"""numba kernels of the hot loop: IR ray casting, the force drive and per-robot random streams.

The random streams are counter-based: 64 random bits are a hash of (robot key, step, block), so
a robot's draws depend on nothing but its own key and clock (see docs/decisions.md).
"""

import math
from typing import Literal, get_args

import numba as nb
import numpy as np
from numba.core.dispatcher import Dispatcher

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
REACH_MM = BODY_RADIUS_MM + IR_RANGE_MM + 1.0
"""No ray reaches a wall farther than this from the robot's centre (the rays end within
BODY_RADIUS_MM + IR_RANGE_MM of it; the extra millimetre dwarfs any rounding)."""


def _constants() -> np.ndarray:
    """Every robot constant the kernels use, as one array."""
    scalars = (
        AXLE_MM,
        BODY_RADIUS_MM,
        IR_BACKOFF_MM,
        IR_MAX,
        IR_RANGE_MM,
        MASS,
        MAX_COMMAND,
        MOMENT,
        WHEEL_RADIUS_MM,
    )
    out = np.empty(len(scalars) + 4 * N_SENSORS)
    for k, value in enumerate(scalars):
        out[k] = value
    for j in range(N_SENSORS):
        out[9 + 4 * j] = _SENSOR_X[j]
        out[10 + 4 * j] = _SENSOR_Y[j]
        out[11 + 4 * j] = _SENSOR_COS[j]
        out[12 + 4 * j] = _SENSOR_SIN[j]
    return out


_frozen_constants = nb.njit(cache=True)(_constants)
"""The constants as numba froze them into its cache (see ``_drop_stale_cache``)."""


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
    every = np.arange(table.shape[0])
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
        if 0.0 <= col < frame[3] and 0.0 <= row < frame[4]:
            cell = int(row) * int(frame[3]) + int(col)
            listed = members[starts[cell] : starts[cell + 1]]
        else:
            listed = every
        m = 0
        for w in listed:
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


# --- counter-based random streams ---

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_TWO_PI = 2.0 * np.pi
_INV_2_32 = 1.0 / 4294967296.0
_BLOCK_NORMAL = 0  # blocks 0..3: one Box–Muller pair each, for sensors 2b and 2b + 1
_BLOCK_UNIFORM = 4  # blocks 4..7: two uniforms each, for random faults of sensors 2b, 2b + 1
_BLOCK_ZIGGURAT = 8  # blocks 8..15: one ziggurat normal each, for sensor j (ziggurat-v1)
_INV_2_53 = 1.0 / 9007199254740992.0

NoiseStream = Literal["box-muller-v1", "ziggurat-v1"]
NOISE_STREAMS: tuple[NoiseStream, ...] = get_args(NoiseStream)
"""How the sensor noise's normal draws are made from a robot's stream; its code in the kernels
is its index here. ``box-muller-v1`` (the default, every run before the setting): one
Box–Muller pair per two sensors, glibc's ``log``, ``sqrt`` and ``sincos``. ``ziggurat-v1``: one
ziggurat draw per sensor (Doornik's ZIGNOR, 128 layers), from its own 64-bit hash of
(key, step, sensor): a table look-up and a multiply 98.8% of the time. Both are exact N(0, 1)
draws up to float64, from the same (key, step) counters, so a robot's noise still depends on
nothing but its key and clock; they give different numbers. A new way of drawing is a new
name, never a change to an old one (docs/decisions.md: A faster noise stream)."""


def noise_stream_code(stream: str) -> int:
    """The kernels' code of a noise stream; a one-line ValueError for an unknown one."""
    if stream not in NOISE_STREAMS:
        raise ValueError(
            f"unknown noise stream {stream!r}: expected one of {', '.join(NOISE_STREAMS)}"
        )
    return NOISE_STREAMS.index(stream)


def _ziggurat_tables(
    layers: int = 128, r: float = 3.442619855899, v: float = 9.91256303526217e-3
) -> tuple[np.ndarray, np.ndarray, float]:
    """ZIGNOR's tables (Doornik 2005, "An improved ziggurat method to generate normal random
    samples"): x[i] the layers' right edges (x[0] = V / f(R) for the base, x[layers] = 0), and
    ratio[i] = x[i + 1] / x[i], for the unnormalised density f(x) = exp(−x²/2). Built with
    Python's ``math`` (the platform's libm, as the Box–Muller stream's calls are)."""
    x = [0.0] * (layers + 1)
    f = math.exp(-0.5 * r * r)
    x[0] = v / f
    x[1] = r
    for i in range(2, layers):
        x[i] = math.sqrt(-2.0 * math.log(v / x[i - 1] + f))
        f = math.exp(-0.5 * x[i] * x[i])
    ratio = [x[i + 1] / x[i] for i in range(layers)]
    return np.array(x), np.array(ratio), r


_ZIG_X, _ZIG_RATIO, _ZIG_TAIL = _ziggurat_tables()
_ZIG_LAYER = np.uint64(0x7F)


@nb.njit(cache=True, inline="always")
def splitmix64(z: np.uint64) -> np.uint64:
    """The splitmix64 finaliser: a bijective 64-bit mix."""
    z = z + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


@nb.njit(cache=True, inline="always")
def _hash(key: np.uint64, step: np.uint64, block: int) -> np.uint64:
    """64 random bits from (robot key, step, block): a counter-based generator."""
    return splitmix64(key ^ splitmix64((step << np.uint64(4)) | np.uint64(block)))


@nb.njit(cache=True, inline="always")
def _halves(h: np.uint64) -> tuple[float, float]:
    """Two uniforms from 64 bits: the high half in (0, 1], the low half in [0, 1)."""
    hi = float(h >> np.uint64(32))
    lo = float(h & np.uint64(0xFFFFFFFF))
    return (hi + 1.0) * _INV_2_32, lo * _INV_2_32


@nb.njit(cache=True, inline="always")
def _redraw(h0: np.uint64, r: int) -> np.uint64:
    """The r-th further 64 bits after h0 (r ≥ 1): splitmix64's own sequence seeded at h0."""
    return splitmix64(h0 + np.uint64(r - 1) * _GOLDEN)


@nb.njit(cache=True, inline="always")
def ziggurat_normal(h: np.uint64) -> float:
    """A N(0, 1) draw from 64 random bits (``ziggurat-v1``): the low 7 bits pick a layer, the
    top 53 a signed uniform u in [−1, 1); |u| inside the layer's rectangle (98.8% of draws)
    returns u·x[layer], else ``_ziggurat_rest`` (the wedges and the tail) draws on from h."""
    i = int(h & _ZIG_LAYER)
    u = 2.0 * (float(h >> np.uint64(11)) * _INV_2_53) - 1.0
    if abs(u) < _ZIG_RATIO[i]:
        return u * _ZIG_X[i]
    return _ziggurat_rest(h, i, u)


@nb.njit(cache=True, inline="always")
def _ziggurat_rest(h0: np.uint64, i: int, u: float) -> float:
    """ZIGNOR past the rectangle test: the base layer samples the tail beyond R (Marsaglia's
    method), a wedge accepts x = u·x[i] under the density, else a new (layer, u) is drawn;
    every further uniform is the next of splitmix64's sequence seeded at h0."""
    r = 0
    while True:
        if i == 0:  # the base layer: its rectangle missed, so the tail beyond R
            while True:
                r += 1
                a, b = _halves(_redraw(h0, r))  # a in (0, 1], 1 − b in (0, 1]
                x = np.log(a) / _ZIG_TAIL
                y = np.log(1.0 - b)
                if -2.0 * y >= x * x:
                    return x - _ZIG_TAIL if u < 0.0 else _ZIG_TAIL - x
        x = u * _ZIG_X[i]
        f0 = np.exp(-0.5 * (_ZIG_X[i] * _ZIG_X[i] - x * x))
        f1 = np.exp(-0.5 * (_ZIG_X[i + 1] * _ZIG_X[i + 1] - x * x))
        r += 1
        uniform, _ = _halves(_redraw(h0, r))
        if f1 + (1.0 - uniform) * (f0 - f1) < 1.0:
            return x
        r += 1
        h = _redraw(h0, r)
        i = int(h & _ZIG_LAYER)
        u = 2.0 * (float(h >> np.uint64(11)) * _INV_2_53) - 1.0
        if abs(u) < _ZIG_RATIO[i]:
            return u * _ZIG_X[i]


@nb.njit(cache=True)
def normal_draws(keys: np.ndarray, steps: int, stream: int, out: np.ndarray) -> None:
    """The standard normals (before σ) the sensor noise of ``stream`` (a ``NOISE_STREAMS``
    code) draws for robots ``keys`` (N,) over world steps 0..steps − 1, into out (steps, N, 8):
    what ``observe`` adds, σ·out, before clipping and faults (for tests and benches)."""
    for t in range(steps):
        for i in range(keys.shape[0]):
            for b in range(N_SENSORS // 2):
                z0, z1 = _normal_pair(keys[i], np.uint64(t), 1.0, stream, b)
                out[t, i, 2 * b] = z0
                out[t, i, 2 * b + 1] = z1


@nb.njit(cache=True, inline="always")
def _normal_pair(
    key: np.uint64, step: np.uint64, sigma: float, stream: int, b: int
) -> tuple[float, float]:
    """Sensors 2b and 2b + 1's N(0, σ²) noise at ``step`` in ``stream`` (box-muller-v1's
    operations in their order of old: σ·√(−2 ln u1) first, then times cos and sin)."""
    if stream == 1:  # ziggurat-v1
        return (
            sigma * ziggurat_normal(_hash(key, step, _BLOCK_ZIGGURAT + 2 * b)),
            sigma * ziggurat_normal(_hash(key, step, _BLOCK_ZIGGURAT + 2 * b + 1)),
        )
    u1, u2 = _halves(_hash(key, step, _BLOCK_NORMAL + b))  # box-muller-v1
    r = sigma * np.sqrt(-2.0 * np.log(u1))
    return r * np.cos(_TWO_PI * u2), r * np.sin(_TWO_PI * u2)


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
    stream: int = 0,
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
        stream: How the normals are drawn: the index of a ``NOISE_STREAMS`` name.
    """
    for i in range(true.shape[0]):
        for b in range(N_SENSORS // 2):
            observe_pair(true, keys, step, sigma, mode, stuck, out, i, b, stream)


@nb.njit(cache=True, inline="always")
def observe_pair(
    true: np.ndarray,
    keys: np.ndarray,
    step: np.uint64,
    sigma: float,
    mode: np.ndarray,
    stuck: np.ndarray,
    out: np.ndarray,
    i: int,
    b: int,
    stream: int = 0,
) -> None:
    """``observe`` of robot i's sensors 2b and 2b + 1 alone (their two normal draws, and one
    pair of uniforms if either sensor reads at random): the same values, drawn only when
    needed."""
    key = keys[i]
    noise_0 = noise_1 = 0.0
    if sigma > 0.0:
        noise_0, noise_1 = _normal_pair(key, step, sigma, stream, b)
    uniform_0 = uniform_1 = 0.0
    if mode[i, 2 * b] == 4 or mode[i, 2 * b + 1] == 4:
        uniform_0, uniform_1 = _halves(_hash(key, step, _BLOCK_UNIFORM + b))
    out[i, 2 * b] = _seen(
        true[i, 2 * b], sigma, noise_0, mode[i, 2 * b], stuck[i, 2 * b], uniform_0
    )
    out[i, 2 * b + 1] = _seen(
        true[i, 2 * b + 1], sigma, noise_1, mode[i, 2 * b + 1], stuck[i, 2 * b + 1], uniform_1
    )


@nb.njit(cache=True, inline="always")
def _seen(x: float, sigma: float, noise: float, f: int, stuck: float, uniform: float) -> float:
    """One sensor as the controller sees it: the true reading x, noise, then its fault."""
    if sigma > 0.0:
        x = min(IR_MAX, max(0.0, x + noise))
    if f == 1:  # dead
        x = 0.0
    elif f == 2:  # saturated
        x = IR_MAX
    elif f == 3:  # stuck
        x = stuck
    elif f == 4:  # random
        x = IR_MAX * uniform
    return x


def _drop_stale_cache() -> None:
    """Recompile every kernel if numba's cache holds old ``sim/khepera.py`` constants.

    numba freezes globals into its cached machine code and only notices changes to this file,
    not to sim/khepera.py. Recompiling a dispatcher flushes its cache, so every kernel compiles
    afresh, with today's constants, on its first call (and caches that).
    """
    if np.array_equal(_frozen_constants(), _constants()):
        return
    for kernel in list(globals().values()):
        if isinstance(kernel, Dispatcher):
            kernel.recompile()
    if not np.array_equal(_frozen_constants(), _constants()):
        raise RuntimeError("numba still runs old sim/khepera.py constants after recompiling")


_drop_stale_cache()
