"""Batched neural controllers: an Elman net and NEAT's recurrent net, stepped for N at once.

A controller maps its config's `n_inputs` inputs in [0, 1] to `n_outputs` outputs in [−1, 1]
(the robot's 8 and 2 by default); the lab scales IR readings to the inputs and the outputs to
wheel commands. Each controller has its own weights (a leading batch
axis N on every array) and its own activations, carried from step to step (`init_state`). The
compiled kernels sum every product of a row in a fixed order, with no fast-math reassociation,
so a controller's outputs depend on its own weights and inputs only, never on its batch.
"""

from __future__ import annotations

from typing import TypeAlias

import numba
import numpy as np
import numpy.typing as npt

from neuro.net_configs import ElmanConfig, NetConfig, NeuroError
from neuro.net_configs import RecurrentConfig as RecurrentConfig  # still importable from here

Floats: TypeAlias = npt.NDArray[np.float64]
"""The nets' float64 arrays, as the kernels read them."""

#: NEAT's tanh: tanh(clamp(2.5 z, −60, 60)) (neat-python's `tanh_activation`).
NEAT_GAIN = 2.5
NEAT_CLAMP = 60.0


def field_dtype(name: str) -> np.dtype:
    """The dtype of a net array: int8 for the recurrent net's `active` mask, else float64."""
    return np.dtype(np.int8 if name == "active" else np.float64)


def zeros(cfg: NetConfig, n: int) -> dict[str, np.ndarray]:
    """N controllers with every weight zero (outputs 0)."""
    return {k: np.zeros((n, *s), field_dtype(k)) for k, s in cfg.shapes().items()}


def from_flat(cfg: ElmanConfig, flat: np.ndarray) -> dict[str, np.ndarray]:
    """Elman arrays of (N, n_params) flat weight vectors (the optimiser's search space)."""
    flat = np.asarray(flat, dtype=np.float64)
    if flat.ndim != 2 or flat.shape[1] != cfg.n_params:
        raise NeuroError(f"flat weights must be (N, {cfg.n_params}), got {flat.shape}")
    arrays, at = {}, 0
    for name, shape in cfg.shapes().items():
        size = int(np.prod(shape))
        arrays[name] = np.ascontiguousarray(flat[:, at : at + size].reshape(-1, *shape))
        at += size
    return arrays


def to_flat(cfg: ElmanConfig, arrays: dict[str, np.ndarray]) -> np.ndarray:
    """The inverse of `from_flat`."""
    check_arrays(cfg, arrays)
    n = len(arrays["b_out"])
    return np.concatenate([arrays[name].reshape(n, -1) for name in cfg.shapes()], axis=1)


def check_arrays(cfg: NetConfig, arrays: dict[str, np.ndarray]) -> int:
    """Raise NeuroError unless `arrays` are N controllers of `cfg`; returns N."""
    shapes = cfg.shapes()
    if set(arrays) != set(shapes):
        raise NeuroError(f"net arrays must be {sorted(shapes)}, got {sorted(arrays)}")
    n = len(next(iter(arrays.values())))
    for name, shape in shapes.items():
        a = arrays[name]
        if a.shape != (n, *shape) or a.dtype != field_dtype(name):
            raise NeuroError(
                f"{name} must be {(n, *shape)} {field_dtype(name)}, got {a.shape} {a.dtype}"
            )
        if not np.all(np.isfinite(a)):
            raise NeuroError(f"{name} holds a non-finite weight")
    return n


def take(arrays: dict[str, np.ndarray], index: np.ndarray | list[int]) -> dict[str, np.ndarray]:
    """Rows `index` of every array (copies)."""
    idx = np.asarray(index, dtype=np.int64)
    return {k: np.ascontiguousarray(v[idx]) for k, v in arrays.items()}


def init_state(cfg: NetConfig, n: int) -> np.ndarray:
    """(N, units) activations at an episode's start: all zero."""
    return np.zeros((n, cfg.n_units))


def step(
    cfg: NetConfig, arrays: dict[str, np.ndarray], state: np.ndarray, inputs: np.ndarray
) -> np.ndarray:
    """One step of N controllers: (N, n_outputs) outputs in [−1, 1]; `state` (N, units) is updated.

    Args:
        cfg: the nets' shape.
        arrays: the N controllers' weights (see `ElmanConfig.shapes`, `RecurrentConfig.shapes`).
        state: (N, units) activations of the previous step (`init_state` at a start).
        inputs: (N, n_inputs) inputs in [0, 1].

    Raises:
        NeuroError: the inputs' width is not the net's, or the inputs, state and arrays do not
            fit together.
    """
    n = len(state)
    x = np.ascontiguousarray(inputs, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != cfg.n_inputs:
        raise NeuroError(f"the net takes {cfg.n_inputs} inputs a row, got inputs {x.shape}")
    if len(x) != n or state.shape != (n, cfg.n_units):
        raise NeuroError(f"inputs {x.shape} and state {state.shape} do not fit {n} nets")
    out = np.empty((n, cfg.n_outputs))
    new = np.empty_like(state)
    if isinstance(cfg, ElmanConfig):
        a = arrays
        _elman(a["w_in"], a["w_rec"], a["b_h"], a["w_out"], a["b_out"], state, x, new, out)
    else:
        a = arrays
        _recurrent(a["weights"], a["bias"], a["response"], a["active"], state, x, new)
        out[:] = new[:, : cfg.n_outputs]
    state[...] = new
    return out


@numba.njit(cache=True)
def _elman(
    w_in: Floats,
    w_rec: Floats,
    b_h: Floats,
    w_out: Floats,
    b_out: Floats,
    hidden: Floats,
    x: Floats,
    new_hidden: Floats,
    out: Floats,
) -> None:
    n, h = hidden.shape
    for i in range(n):
        for j in range(h):
            s = b_h[i, j]
            for k in range(x.shape[1]):
                s += w_in[i, j, k] * x[i, k]
            for k in range(h):
                s += w_rec[i, j, k] * hidden[i, k]
            new_hidden[i, j] = np.tanh(s)
        for o in range(out.shape[1]):
            s = b_out[i, o]
            for k in range(h):
                s += w_out[i, o, k] * new_hidden[i, k]
            out[i, o] = np.tanh(s)


@numba.njit(cache=True)
def _recurrent(
    weights: Floats,
    bias: Floats,
    response: Floats,
    active: npt.NDArray[np.int8],
    values: Floats,
    x: Floats,
    new_values: Floats,
) -> None:
    n, m = values.shape
    n_in = x.shape[1]
    for i in range(n):
        for j in range(m):
            if active[i, j] == 0:
                new_values[i, j] = 0.0
                continue
            s = 0.0
            for k in range(n_in):
                s += weights[i, j, k] * x[i, k]
            for k in range(m):
                s += weights[i, j, n_in + k] * values[i, k]
            z = NEAT_GAIN * (bias[i, j] + response[i, j] * s)
            new_values[i, j] = np.tanh(min(NEAT_CLAMP, max(-NEAT_CLAMP, z)))
