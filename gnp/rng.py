"""Per-controller counter-based random streams (splitmix64), in numba and in plain Python.

Each controller owns one 64-bit state. A draw adds the golden-ratio increment to the state and
mixes it, so a controller's numbers depend only on its own seed and on how many draws it made:
never on the batch it runs in nor on how a population is split across processes.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from gnp.config import GnpError

GAMMA = 0x9E3779B97F4A7C15
MIX1 = 0xBF58476D1CE4E5B9
MIX2 = 0x94D049BB133111EB
MASK64 = (1 << 64) - 1
TO_UNIT = 1.0 / (1 << 53)

_GAMMA = np.uint64(GAMMA)
_MIX1 = np.uint64(MIX1)
_MIX2 = np.uint64(MIX2)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)


@njit(cache=True, inline="always")
def next_uniform(state: np.uint64) -> tuple[np.uint64, float]:
    """Advance a splitmix64 state; return (new state, uniform float in [0, 1))."""
    state = state + _GAMMA
    z = state
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    z = z ^ (z >> _S31)
    return state, float(z >> _S11) * TO_UNIT


def py_next_uniform(state: int) -> tuple[int, float]:
    """Pure-Python twin of `next_uniform` (the reference interpreter uses it)."""
    state = (state + GAMMA) & MASK64
    z = state
    z = ((z ^ (z >> 30)) * MIX1) & MASK64
    z = ((z ^ (z >> 27)) * MIX2) & MASK64
    z ^= z >> 31
    return state, float(z >> 11) * TO_UNIT


def py_mix64(x: int) -> int:
    """The splitmix64 finaliser of x + γ: a well-spread 64-bit state from a small seed."""
    z = (x + GAMMA) & MASK64
    z = ((z ^ (z >> 30)) * MIX1) & MASK64
    z = ((z ^ (z >> 27)) * MIX2) & MASK64
    return z ^ (z >> 31)


def seed_states(seeds: np.ndarray | list[int] | tuple[int, ...]) -> np.ndarray:
    """(N,) uint64 initial stream states from (N,) non-negative integer seeds."""
    arr = np.asarray(seeds)
    if arr.ndim != 1:
        raise GnpError(f"seeds must be a 1-D array of integers, got shape {arr.shape}")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise GnpError(f"seeds must be integers, got {arr.dtype}")
    values = [int(s) for s in arr]
    if any(s < 0 or s > MASK64 for s in values):
        raise GnpError("seeds must lie in 0..2**64-1")
    return np.array([py_mix64(s) for s in values], dtype=np.uint64)
