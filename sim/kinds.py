"""The world's light names: the kinds of noise stream, physics and reward source, and the
reward's terms. No numba here, so the lab's settings import them without the kernels;
``sim.noise``, ``sim.world`` and ``sim.reward`` use them from here, and ``sim`` re-exports them.
"""

from typing import Literal, get_args

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
DEFAULT_NOISE_STREAM: NoiseStream = "box-muller-v1"
"""The noise stream of a world or a run that names none (every run before the setting)."""

Physics = Literal["pymunk", "analytic"]
PHYSICS: tuple[Physics, ...] = get_args(Physics)
"""The world's physics: pymunk (the reference) or analytic (numba, for sweeps; see
``sim.analytic``)."""
DEFAULT_PHYSICS: Physics = "pymunk"
"""The physics of a world or a run that names none: the reference."""

CFrom = Literal["true", "observed"]
"""What C of Eq. 2.7 is judged from: the true readings, or what the controller sees."""
C_FROM: tuple[CFrom, ...] = get_args(CFrom)
"""The values of `CFrom`, in order."""

TERM_NAMES = ("reward", "reward/speed", "reward/straightness", "reward/near_wall")
"""The named reward terms, in the order of `reward_table`'s columns (the store's order)."""
