"""Brains with any number of inputs and outputs (GnpConfig.n_inputs / n_outputs)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import gnp
from gnp.config import JUDGMENT, PROCESSING, SENSOR_MAX, SPEED_MAX
from gnp.controller_file import controller_body, controller_from_body

io_configs = st.builds(
    gnp.GnpConfig,
    method=st.sampled_from(["RL", "BS", "CS"]),
    fuzzy=st.booleans(),
    n_judgment=st.integers(1, 12),
    n_processing=st.integers(1, 8),
    n_sub=st.integers(1, 3),
    n_branch=st.integers(1, 3),
    n_inputs=st.integers(1, 20),
    n_outputs=st.integers(1, 6),
)


@settings(max_examples=40, deadline=None)
@given(cfg=io_configs, seed=st.integers(0, 2**32 - 1), n=st.integers(2, 8))
def test_random_populations_validate_and_mutate_within_ranges(
    cfg: gnp.GnpConfig, seed: int, n: int
) -> None:
    rng = np.random.default_rng(seed)
    pop = gnp.init_population(cfg, n, rng)
    gnp.check_population(cfg, pop)
    for _ in range(3):
        pop = gnp.mutate(cfg, pop, 1, 4, rng, p_mutation=0.5)
        gnp.check_population(cfg, pop)
        judg = cfg.node_type == JUDGMENT
        proc = cfg.node_type == PROCESSING
        assert pop.function[:, judg].min() >= 0 and pop.function[:, judg].max() < cfg.n_inputs
        assert pop.function[:, proc].min() >= 0 and pop.function[:, proc].max() < cfg.n_outputs
        assert pop.mu_alpha[:, judg].max() <= SENSOR_MAX
        assert np.abs(pop.speed[:, proc]).max() <= SPEED_MAX
    fitness = rng.random(n)
    nxt = gnp.evolve(cfg, pop, fitness, 0, 5, rng)
    gnp.check_population(cfg, nxt)
    state = gnp.init_state(cfg, n, np.arange(n))
    obs = rng.uniform(0, SENSOR_MAX, (n, cfg.n_inputs))
    commands, _ = gnp.step(cfg, nxt, state, obs, np.zeros(n), 0.1, 0.1)
    assert commands.shape == (n, cfg.n_outputs)
    assert np.abs(commands).max() <= SPEED_MAX


def test_processing_node_sets_its_output_in_reversed_column() -> None:
    # Output j (processing function j) sits in column k − 1 − j: the robot's (left, right).
    cfg = gnp.GnpConfig(n_judgment=1, n_processing=1, n_sub=1, n_inputs=3, n_outputs=4)
    pop = gnp.init_population(cfg, 1, np.random.default_rng(0))
    arrays = {k: v.copy() for k, v in gnp.population_to_arrays(pop).items()}
    arrays["function"][0, 2, 0] = 1  # the processing node sets output 1
    arrays["speed"][0, 2, 0] = 7
    arrays["conn"][0, 0] = 2  # start → processing node
    arrays["conn"][0, 2] = 2
    pop = gnp.population_from_arrays(cfg, arrays)
    state = gnp.init_state(cfg, 1, [0])
    commands, _ = gnp.step(cfg, pop, state, np.zeros((1, 3)), np.zeros(1), 0.0, 0.1)
    np.testing.assert_array_equal(commands, [[0.0, 0.0, 7.0, 0.0]])


def test_out_of_range_functions_are_refused() -> None:
    cfg = gnp.GnpConfig(n_inputs=3, n_outputs=1)
    pop = gnp.init_population(cfg, 2, np.random.default_rng(1))
    arrays = {k: v.copy() for k, v in gnp.population_to_arrays(pop).items()}
    arrays["function"][0, 1, 0] = 3
    with pytest.raises(gnp.GnpError, match=r"sensors 0\.\.2"):
        gnp.population_from_arrays(cfg, arrays)
    wrong = gnp.init_population(gnp.GnpConfig(), 2, np.random.default_rng(1))
    with pytest.raises(gnp.GnpError, match="observations must have shape"):
        gnp.step(cfg, pop, gnp.init_state(cfg, 2, [0, 1]), np.zeros((2, 8)), np.zeros(2), 0, 0)
    assert wrong.size == 2


def test_default_io_keeps_the_controller_document_and_others_record_theirs() -> None:
    robot = gnp.GnpConfig()
    pop = gnp.init_population(robot, 1, np.random.default_rng(2))
    entry, nodes = controller_body(robot, pop)
    assert "n_inputs" not in entry and "n_outputs" not in entry
    assert controller_from_body(entry, nodes)[0] == robot
    task = gnp.GnpConfig(n_inputs=4, n_outputs=1)
    pop = gnp.init_population(task, 1, np.random.default_rng(2))
    entry, nodes = controller_body(task, pop)
    assert (entry["n_inputs"], entry["n_outputs"]) == (4, 1)
    cfg, back = controller_from_body(entry, nodes)
    assert cfg == task
    np.testing.assert_array_equal(back.function, pop.function)


@pytest.mark.parametrize("method", ["RL", "BS", "CS"])
def test_end_episode_credits_the_last_visit_without_a_successor(method: str) -> None:
    # With γ = 0 the next step's first visit would make exactly the terminal update: compare
    # with the kernel on every Q entry the next step does not touch again.
    cfg = gnp.GnpConfig(method=method, gamma=0.0, n_inputs=3, n_outputs=2)
    n = 16
    rng = np.random.default_rng(5)
    pop = gnp.init_population(cfg, n, rng)
    state = gnp.init_state(cfg, n, np.arange(n))
    for _ in range(6):
        obs = rng.uniform(0, SENSOR_MAX, (n, 3))
        gnp.step(cfg, pop, state, obs, rng.uniform(-1, 1, n), 0.3, 0.5)
    reward = rng.uniform(-2, 2, n)
    which = np.arange(n) % 4 != 0
    ended = gnp.take(pop, np.arange(n))
    ended_state = gnp.EngineState(state.walk.copy(), state.wheels.copy(), state.rng.copy())
    pending = state.walk[:, 1:6].copy()
    pending_bs = state.walk[:, 6:10].copy()
    gnp.end_episode(cfg, ended, ended_state, reward, 0.5, which)
    stepped = gnp.take(pop, np.arange(n))
    _, trace = gnp.step(cfg, stepped, state, np.zeros((n, 3)), reward, 0.3, 0.5, trace=True)
    assert trace is not None
    checked_bs = 0
    for c in range(n):
        pn, pp, _, _, pc = pending[c]
        if not which[c]:
            np.testing.assert_array_equal(ended.q_ss[c], pop.q_ss[c])
            assert ended_state.walk[c, 1] == pn
            continue
        assert ended_state.walk[c, 1] == -1
        visited = {(int(v), int(s)) for v, s in zip(trace.node[c], trace.sub[c], strict=True)}
        if (pn, pp) not in visited:
            assert ended.q_ss[c, pn, pp] == stepped.q_ss[c, pn, pp]
            if method == "CS":
                assert ended.q_cs[c, pn, pp, pc] == stepped.q_cs[c, pn, pp, pc]
        before = tuple(int(v) for v in pending_bs[c])
        if method == "BS" and before[0] >= 0 and before[:2] not in visited | {(pn, pp)}:
            checked_bs += 1
            assert ended.q_bs[c][before] == stepped.q_bs[c][before]
            assert ended.q_bs[c][before] != pop.q_bs[c][before] or reward[c] == 0
        r = 0.0 if pc == 1 else reward[c]
        q = np.float64(pop.q_ss[c, pn, pp])
        assert ended.q_ss[c, pn, pp] == np.float32(q + 0.5 * (r - q))
    assert checked_bs > 0 or method != "BS"
