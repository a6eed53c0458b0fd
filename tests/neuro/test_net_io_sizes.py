"""Nets of a task's sizes (#46): inputs and outputs are the config's, the robot's by default."""

from __future__ import annotations

import json
import math

import neat
import numpy as np
import pydantic
import pytest

import neuro
from neuro.cmaes import Cmaes
from neuro.neat_evolution import NeatParams, NeatSearch, encode
from neuro.net_configs import MAX_WIDTH

SIZES = [(4, 2), (3, 1)]  # CartPole-v1's, Pendulum-v1's


def _net(kind: str, n_inputs: int, n_outputs: int) -> neuro.NetConfig:
    if kind == "elman":
        return neuro.ElmanConfig(hidden=3, n_inputs=n_inputs, n_outputs=n_outputs)
    return neuro.RecurrentConfig(max_hidden=2, n_inputs=n_inputs, n_outputs=n_outputs)


def _random_nets(cfg: neuro.NetConfig, n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    arrays = neuro.zeros(cfg, n)
    for name, a in arrays.items():
        a[...] = rng.integers(0, 2, a.shape) if name == "active" else rng.normal(0, 1, a.shape)
    return arrays


def _run(cfg: neuro.NetConfig, arrays: dict[str, np.ndarray], inputs: np.ndarray) -> np.ndarray:
    """Outputs (T, N, n_outputs) of `inputs` (T, N, n_inputs) from a start."""
    state = neuro.init_state(cfg, len(inputs[0]))
    return np.array([neuro.step(cfg, arrays, state, x) for x in inputs])


def test_the_robots_sizes_are_the_defaults_and_left_out_of_dumps() -> None:
    assert neuro.ElmanConfig(hidden=3).model_dump() == {"kind": "elman", "hidden": 3}
    assert neuro.RecurrentConfig().model_dump_json() == '{"kind":"recurrent","max_hidden":32}'
    robot = neuro.ElmanConfig(hidden=3, n_inputs=neuro.N_INPUTS, n_outputs=neuro.N_OUTPUTS)
    assert robot == neuro.ElmanConfig(hidden=3)
    assert neuro.RecurrentConfig(n_inputs=4).model_dump() == {
        "kind": "recurrent",
        "max_hidden": 32,
        "n_inputs": 4,
    }
    assert NeatParams(max_hidden=5).net_config() == neuro.RecurrentConfig(max_hidden=5)


@pytest.mark.parametrize("field", ["n_inputs", "n_outputs"])
@pytest.mark.parametrize("value", [0, MAX_WIDTH + 1])
def test_sizes_are_bounded(field: str, value: int) -> None:
    for model in (neuro.ElmanConfig, neuro.RecurrentConfig):
        with pytest.raises(pydantic.ValidationError, match=field):
            model.model_validate({field: value})


@pytest.mark.parametrize("kind", ["elman", "recurrent"])
@pytest.mark.parametrize(("n_inputs", "n_outputs"), SIZES)
def test_a_batch_steps_with_the_configs_sizes_deterministically_row_by_row(
    kind: str, n_inputs: int, n_outputs: int
) -> None:
    cfg = _net(kind, n_inputs, n_outputs)
    inputs = np.random.default_rng(1).uniform(0, 1, (5, 6, n_inputs))
    outputs = _run(cfg, _random_nets(cfg, 6, seed=7), inputs)
    assert outputs.shape == (5, 6, n_outputs)
    assert np.all(np.abs(outputs) <= 1.0) and np.any(outputs != 0.0)
    assert np.array_equal(_run(cfg, _random_nets(cfg, 6, seed=7), inputs), outputs)
    for i in (0, 5):  # a row alone steps as in the batch, bit for bit
        alone = _run(cfg, neuro.take(_random_nets(cfg, 6, seed=7), [i]), inputs[:, i : i + 1])
        assert np.array_equal(alone[:, 0], outputs[:, i])


def test_a_wrong_input_width_names_both_widths() -> None:
    cfg = neuro.ElmanConfig(hidden=2, n_inputs=4, n_outputs=2)
    with pytest.raises(neuro.NeuroError, match=r"takes 4 inputs a row, got inputs \(3, 8\)"):
        neuro.step(cfg, neuro.zeros(cfg, 3), neuro.init_state(cfg, 3), np.zeros((3, 8)))


def test_elman_by_hand_with_two_inputs_one_output_one_unit_to_the_bit() -> None:
    # h_t = tanh(W_in x_t + W_rec h_{t−1} + b_h), y_t = tanh(W_out h_t + b_out)
    cfg = neuro.ElmanConfig(hidden=1, n_inputs=2, n_outputs=1)
    assert cfg.n_params == 2 + 1 + 1 + 1 + 1
    w_in, w_rec, b_h, w_out, b_out = (0.3, -1.7), 0.9, 0.05, -2.1, 0.4
    arrays = neuro.from_flat(cfg, np.array([[*w_in, w_rec, b_h, w_out, b_out]]))
    state, h = neuro.init_state(cfg, 1), 0.0
    for x in ((0.25, 0.8), (1.0, 0.1)):
        y = neuro.step(cfg, arrays, state, np.array([x]))
        h = math.tanh(b_h + w_in[0] * x[0] + w_in[1] * x[1] + w_rec * h)
        assert state.tolist() == [[h]]
        assert y.tolist() == [[math.tanh(b_out + w_out * h)]]


@pytest.mark.parametrize(("n_inputs", "n_outputs"), SIZES)
def test_cmaes_evolves_an_elman_net_of_a_tasks_sizes(n_inputs: int, n_outputs: int) -> None:
    cfg = neuro.ElmanConfig(hidden=2, n_inputs=n_inputs, n_outputs=n_outputs)
    inputs = np.random.default_rng(0).uniform(0, 1, (4, 1, n_inputs))

    def evolve() -> np.ndarray:
        es = Cmaes(n=cfg.n_params, sigma0=0.5, popsize=6, seed=3)
        for _ in range(2):
            arrays = neuro.from_flat(cfg, es.ask())
            outputs = _run(cfg, arrays, np.repeat(inputs, 6, axis=1))
            es.tell(outputs[..., 0].sum(axis=0))  # toy fitness: the first output, summed
        assert es.generation == 2
        return es.ask()

    assert np.array_equal(evolve(), evolve())


@pytest.mark.parametrize(("n_inputs", "n_outputs"), SIZES)
def test_neat_evolves_nets_of_a_tasks_sizes_as_neat_python_runs_them(
    n_inputs: int, n_outputs: int
) -> None:
    params = NeatParams(node_add_prob=0.8, max_hidden=8)
    inputs = np.random.default_rng(0).uniform(0, 1, (4, 1, n_inputs))

    def evolve() -> NeatSearch:
        search = NeatSearch(params, 8, seed=5, n_inputs=n_inputs, n_outputs=n_outputs)
        assert search.net == params.net_config(n_inputs, n_outputs)
        for _ in range(2):
            arrays = search.arrays()
            assert neuro.check_arrays(search.net, arrays) == 8
            outputs = _run(search.net, arrays, np.repeat(inputs, 8, axis=1))
            search.tell(outputs[..., 0].sum(axis=0) + arrays["active"].sum(axis=1))
        assert search.generation == 2
        return search

    search, again = evolve(), evolve()
    a, b = search.arrays(), again.arrays()
    assert all(np.array_equal(a[k], b[k]) for k in a)
    for _, genome in search.genomes():  # the dense mapping of other sizes: neat-python's net
        arrays = encode(genome, search.config.genome_config, search.net)
        oracle = neat.nn.RecurrentNetwork.create(genome, search.config)
        state = neuro.init_state(search.net, 1)
        for x in inputs[:, 0]:
            ours = neuro.step(search.net, arrays, state, x[None])[0]
            np.testing.assert_allclose(ours, oracle.activate(x.tolist()), rtol=0, atol=1e-12)


def test_a_genome_of_other_sizes_is_refused() -> None:
    search = NeatSearch(NeatParams(max_hidden=2), 4, seed=0, n_inputs=3, n_outputs=1)
    _, genome = search.genomes()[0]
    with pytest.raises(neuro.NeuroError, match="3 inputs and 1 outputs is not a net of 8 and 2"):
        encode(genome, search.config.genome_config, neuro.RecurrentConfig(max_hidden=2))


@pytest.mark.parametrize("kind", ["elman", "recurrent"])
def test_the_controller_body_keeps_the_sizes(kind: str) -> None:
    cfg = _net(kind, 3, 1)
    arrays = _random_nets(cfg, 1, seed=2)
    net_entry, body = json.loads(json.dumps(neuro.net_body(cfg, arrays)))
    assert (net_entry["n_inputs"], net_entry["n_outputs"]) == (3, 1)
    loaded, loaded_arrays = neuro.net_from_body(net_entry, body)
    assert loaded == cfg
    assert all(np.array_equal(loaded_arrays[k], arrays[k]) for k in arrays)
