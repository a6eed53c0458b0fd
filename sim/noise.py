"""numba kernels of what a controller sees: per-robot random streams, the sensor noise drawn
from them (Eq. 2.6), then the sensors' faults.

The random streams are counter-based: 64 random bits are a hash of (robot key, step, block), so
a robot's draws depend on nothing but its own key and clock (see docs/decisions.md).
"""

import math

import numba as nb
import numpy as np

from sim.faults import DEAD_CODE, RANDOM_CODE, SATURATED_CODE, STUCK_CODE
from sim.kernel_cache import KHEPERA_CONSTANTS, drop_stale_cache
from sim.khepera import IR_MAX, N_SENSORS
from sim.kinds import NOISE_STREAMS
from sim.kinds import NoiseStream as NoiseStream  # still importable from here

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_TWO_PI = 2.0 * np.pi
_INV_2_32 = 1.0 / 4294967296.0
_BLOCK_NORMAL = 0  # blocks 0..3: one Box–Muller pair each, for sensors 2b and 2b + 1
_BLOCK_UNIFORM = 4  # blocks 4..7: two uniforms each, for random faults of sensors 2b, 2b + 1
_BLOCK_ZIGGURAT = 8  # blocks 8..15: one ziggurat normal each, for sensor j (ziggurat-v1)
_INV_2_53 = 1.0 / 9007199254740992.0


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
        mode: (N, 8) int8 fault modes (see ``sim.faults.FAULT_MODES``; 0 = healthy).
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
    if mode[i, 2 * b] == RANDOM_CODE or mode[i, 2 * b + 1] == RANDOM_CODE:
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
    if f == DEAD_CODE:
        x = 0.0
    elif f == SATURATED_CODE:
        x = IR_MAX
    elif f == STUCK_CODE:
        x = stuck
    elif f == RANDOM_CODE:
        x = IR_MAX * uniform
    return x


COMPILED_AGAINST = np.concatenate(
    [KHEPERA_CONSTANTS, np.array([DEAD_CODE, SATURATED_CODE, STUCK_CODE, RANDOM_CODE], np.float64)]
)
"""What this module's kernels freeze from other files: the robot's constants and the fault
codes (``sim.faults``)."""


@nb.njit(cache=True)
def _frozen_constants() -> np.ndarray:
    """``COMPILED_AGAINST`` as numba froze it into this module's cache."""
    return COMPILED_AGAINST.copy()


drop_stale_cache(globals(), _frozen_constants, COMPILED_AGAINST)
