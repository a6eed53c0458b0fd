"""The batched nets: hand-computed forward passes, batch independence, the package boundary."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import neuro


def _elman_one() -> tuple[neuro.ElmanConfig, dict[str, np.ndarray]]:
    cfg = neuro.ElmanConfig(hidden=1)
    arrays = neuro.zeros(cfg, 1)
    arrays["w_in"][0, 0] = [0.5, -0.25, 0, 0, 0, 0, 0, 1.0]
    arrays["w_rec"][0, 0, 0] = 2.0
    arrays["b_h"][0, 0] = 0.1
    arrays["w_out"][0, :, 0] = [1.5, -3.0]
    arrays["b_out"][0] = [0.0, 0.2]
    return cfg, arrays


def test_elman_forward_pass_by_hand_over_two_steps() -> None:
    cfg, arrays = _elman_one()
    state = neuro.init_state(cfg, 1)
    x1 = np.array([[1.0, 0.4, 0, 0, 0, 0, 0, 0.5]])
    h1 = math.tanh(0.1 + 0.5 * 1.0 - 0.25 * 0.4 + 1.0 * 0.5)  # context 0 at the start
    out = neuro.step(cfg, arrays, state, x1)
    assert out[0] == pytest.approx([math.tanh(1.5 * h1), math.tanh(0.2 - 3.0 * h1)], abs=1e-15)
    assert state[0, 0] == pytest.approx(h1, abs=1e-15)
    x2 = np.zeros((1, 8))
    h2 = math.tanh(0.1 + 2.0 * h1)  # only the bias and the context this time
    out = neuro.step(cfg, arrays, state, x2)
    assert out[0] == pytest.approx([math.tanh(1.5 * h2), math.tanh(0.2 - 3.0 * h2)], abs=1e-15)


def test_recurrent_forward_pass_by_hand() -> None:
    cfg = neuro.RecurrentConfig(max_hidden=1)  # units: out 0, out 1, hidden 2
    arrays = neuro.zeros(cfg, 1)
    arrays["active"][0] = [1, 0, 1]  # output 1 has no inputs: it stays 0
    arrays["weights"][0, 0, 8 + 2] = 0.7  # out 0 <- hidden (previous step)
    arrays["weights"][0, 0, 3] = -0.4  # out 0 <- input 3
    arrays["weights"][0, 2, 0] = 1.2  # hidden <- input 0
    arrays["weights"][0, 2, 8 + 2] = 0.5  # hidden <- itself
    arrays["bias"][0] = [0.1, 9.0, -0.3]
    arrays["response"][0] = [1.0, 1.0, 2.0]
    state = neuro.init_state(cfg, 1)
    x = np.zeros((1, 8))
    x[0, 0], x[0, 3] = 0.5, 1.0
    out = neuro.step(cfg, arrays, state, x)
    hidden1 = math.tanh(2.5 * (-0.3 + 2.0 * (1.2 * 0.5)))
    assert out[0] == pytest.approx([math.tanh(2.5 * (0.1 - 0.4)), 0.0], abs=1e-15)
    out = neuro.step(cfg, arrays, state, x)
    assert out[0, 0] == pytest.approx(math.tanh(2.5 * (0.1 - 0.4 + 0.7 * hidden1)), abs=1e-15)
    assert state[0, 2] == pytest.approx(
        math.tanh(2.5 * (-0.3 + 2.0 * (1.2 * 0.5 + 0.5 * hidden1))), abs=1e-15
    )


def test_recurrent_clamps_like_neat() -> None:
    cfg = neuro.RecurrentConfig(max_hidden=0)
    arrays = neuro.zeros(cfg, 1)
    arrays["active"][0] = [1, 1]
    arrays["bias"][0] = [1e300, -1e300]
    arrays["response"][0] = 1.0
    out = neuro.step(cfg, arrays, neuro.init_state(cfg, 1), np.zeros((1, 8)))
    assert out[0].tolist() == [math.tanh(60.0), math.tanh(-60.0)]


def _random_nets(cfg: neuro.NetConfig, n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    arrays = neuro.zeros(cfg, n)
    for name, a in arrays.items():
        a[...] = rng.integers(0, 2, a.shape) if name == "active" else rng.normal(0, 1, a.shape)
    return arrays


@settings(max_examples=20, deadline=None)
@given(
    kind=st.sampled_from(["elman", "recurrent"]),
    n=st.integers(2, 9),
    seed=st.integers(0, 2**32 - 1),
)
def test_a_controller_steps_the_same_alone_or_in_any_batch(kind: str, n: int, seed: int) -> None:
    cfg: neuro.NetConfig = (
        neuro.ElmanConfig(hidden=5) if kind == "elman" else neuro.RecurrentConfig(max_hidden=4)
    )
    arrays = _random_nets(cfg, n, seed)
    inputs = np.random.default_rng(seed + 1).uniform(0, 1, (6, n, 8))
    state = neuro.init_state(cfg, n)
    together = np.array([neuro.step(cfg, arrays, state, x) for x in inputs])
    for i in (0, n - 1):
        alone_state = neuro.init_state(cfg, 1)
        one = neuro.take(arrays, [i])
        alone = np.array([neuro.step(cfg, one, alone_state, x[i : i + 1]) for x in inputs])
        assert np.array_equal(alone[:, 0], together[:, i])  # bit for bit
        assert np.array_equal(alone_state[0], state[i])


def test_flat_round_trip_and_layout() -> None:
    cfg = neuro.ElmanConfig(hidden=3)
    assert cfg.n_params == 3 * 8 + 3 * 3 + 3 + 2 * 3 + 2
    flat = np.arange(2 * cfg.n_params, dtype=float).reshape(2, -1)
    arrays = neuro.from_flat(cfg, flat)
    assert arrays["w_in"][1, 0, 0] == cfg.n_params  # row-major, in `shapes` order
    assert arrays["b_out"][0].tolist() == [cfg.n_params - 2, cfg.n_params - 1]
    assert np.array_equal(neuro.to_flat(cfg, arrays), flat)


def test_bad_arrays_and_inputs_are_named() -> None:
    cfg = neuro.ElmanConfig(hidden=2)
    with pytest.raises(neuro.NeuroError, match="flat weights must be"):
        neuro.from_flat(cfg, np.zeros((1, 5)))
    arrays = neuro.zeros(cfg, 1)
    arrays["b_h"][0, 0] = np.nan
    with pytest.raises(neuro.NeuroError, match="non-finite"):
        neuro.check_arrays(cfg, arrays)
    with pytest.raises(neuro.NeuroError, match="do not fit"):
        neuro.step(cfg, neuro.zeros(cfg, 1), neuro.init_state(cfg, 1), np.zeros((2, 8)))


def test_neuro_imports_neither_sim_nor_app_nor_gnp() -> None:
    code = (
        "import sys, neuro, neuro.cmaes, neuro.neat_evolution\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('sim', 'app', 'gnp')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
