"""The brain's settings made for tasks (issue #45): initial Q value and tie-breaking."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import gnp
from gnp.controller_file import controller_body, controller_from_body


def _cfg(**changes: object) -> gnp.GnpConfig:
    base = gnp.GnpConfig(method="RL", fuzzy=False, n_judgment=6, n_processing=4, n_sub=3)
    return gnp.GnpConfig.model_validate({**base.model_dump(), **changes})


@given(q0=st.floats(-1e6, 1e6, allow_nan=False, width=32))
@settings(max_examples=25, deadline=None)
def test_q0_fills_every_q_table_and_draws_the_same_genes(q0: float) -> None:
    for method in ("RL", "BS", "CS"):
        base = gnp.GnpConfig(method=method, n_judgment=6, n_processing=4, n_sub=2)
        shifted = base.model_copy(update={"q0": q0})
        a = gnp.init_population(base, 5, np.random.default_rng(3))
        b = gnp.init_population(shifted, 5, np.random.default_rng(3))
        for name in ("q_ss", "q_bs", "q_cs"):
            assert np.all(getattr(a, name) == 0.0)
            assert np.all(getattr(b, name) == np.float32(q0))
        for name in ("function", "mu_beta", "mu_alpha", "speed", "conn", "credit"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_q0_is_bounded() -> None:
    with pytest.raises(ValueError):
        _cfg(q0=1e7)


def _walk(cfg: gnp.GnpConfig, seed: int, steps: int = 40) -> list[tuple[int, ...]]:
    """The sub nodes chosen over `steps` steps with ε = α = 0 (learning off)."""
    pop = gnp.init_population(cfg, 4, np.random.default_rng(11))
    state = gnp.init_state(cfg, 4, np.arange(4) + seed)
    obs_rng = np.random.default_rng(5)  # the same readings for every seed
    subs = []
    for _ in range(steps):
        obs = obs_rng.integers(0, 1024, size=(4, cfg.n_inputs)).astype(np.float64)
        _, trace = gnp.step(cfg, pop, state, obs, np.zeros(4), 0.0, 0.0, trace=True)
        assert trace is not None
        subs.append(tuple(int(s) for s in trace.sub[trace.sub >= 0]))
    return subs


def test_tie_break_first_takes_the_first_sub_node_when_q_values_are_equal() -> None:
    walk = _walk(_cfg(tie_break="first"), seed=1)
    assert all(s == 0 for step in walk for s in step)
    assert sum(len(step) for step in walk) > 40


def test_learning_off_is_deterministic_with_first_but_not_with_random() -> None:
    assert _walk(_cfg(tie_break="first"), 1) == _walk(_cfg(tie_break="first"), 2)
    random = _walk(_cfg(), 1)
    assert random != _walk(_cfg(), 2)
    assert {s for step in random for s in step} == {0, 1, 2}


def test_tie_break_first_picks_the_lowest_of_the_maxima_only() -> None:
    cfg = _cfg(tie_break="first")
    pop = gnp.init_population(cfg, 1, np.random.default_rng(0))
    pop.q_ss[:] = np.array([0.0, 1.0, 1.0], np.float32)  # sub nodes 1 and 2 tie at the top
    state = gnp.init_state(cfg, 1, [9])
    for _ in range(20):
        obs = np.full((1, 8), 300.0)
        _, trace = gnp.step(cfg, pop, state, obs, np.zeros(1), 0.0, 0.0, False, True)
        assert trace is not None
        visited = trace.node[0] > 0  # the start node excluded
        assert set(trace.sub[0, visited].tolist()) == {1}


def test_a_controller_document_names_the_task_settings_only_when_set() -> None:
    cfg = _cfg()
    entry, _ = controller_body(cfg, gnp.init_population(cfg, 1, np.random.default_rng(0)))
    assert "q0" not in entry and "tie_break" not in entry
    tuned = _cfg(q0=-10.0, tie_break="first")
    pop = gnp.init_population(tuned, 1, np.random.default_rng(0))
    entry, nodes = controller_body(tuned, pop)
    assert entry["q0"] == -10.0 and entry["tie_break"] == "first"
    back, read = controller_from_body(entry, nodes)
    assert back == tuned
    np.testing.assert_array_equal(read.q_ss, pop.q_ss)


def _skipper(skip_reward: str) -> tuple[gnp.GnpConfig, gnp.Population, gnp.EngineState]:
    """A CS controller whose every node prefers its credit branch (Q_CS credit 1, normal 0)."""
    cfg = gnp.GnpConfig.model_validate(
        dict(method="CS", fuzzy=False, gamma=0.0, tie_break="first", skip_reward=skip_reward)
    )
    pop = gnp.init_population(cfg, 1, np.random.default_rng(4))
    pop.q_cs[..., 1] = 1.0
    return cfg, pop, gnp.init_state(cfg, 1, [3])


@pytest.mark.parametrize(("skip_reward", "earned"), [("zero", 0.0), ("step", -1.0)])
def test_a_credit_skip_that_ends_a_step_earns_the_steps_reward_only_when_set(
    skip_reward: str, earned: float
) -> None:
    """The CS defect on tasks (#45): a step of five credit skips hid its reward (r = 0 for a
    skip), so where every step pays −1 skipping every node looked best. With γ = 0 and
    α = 0.5 the step's last skip moves halfway to the reward it earns: hand-computed."""
    cfg, pop, state = _skipper(skip_reward)
    obs = np.full((1, 8), 500.0)
    _, trace = gnp.step(cfg, pop, state, obs, np.zeros(1), 0.0, 0.5, trace=True)
    assert trace is not None and trace.skipped[0, 1:6].tolist() == [1] * 5  # skips only
    node, sub = int(state.pending[0, 0]), int(state.pending[0, 1])
    before = float(pop.q_cs[0, node, sub, 1])
    _, trace = gnp.step(cfg, pop, state, obs, np.full(1, -1.0), 0.0, 0.5, trace=True)
    assert trace is not None and node not in trace.node[0, : trace.count[0] - 1].tolist()
    assert pop.q_cs[0, node, sub, 1] == np.float32(before + 0.5 * (earned - before))


@pytest.mark.parametrize(("skip_reward", "earned"), [("zero", 0.0), ("step", -1.0)])
def test_the_terminal_update_credits_a_last_skip_as_the_setting_says(
    skip_reward: str, earned: float
) -> None:
    cfg, pop, state = _skipper(skip_reward)
    gnp.step(cfg, pop, state, np.full((1, 8), 500.0), np.zeros(1), 0.0, 0.5)
    node, sub = int(state.pending[0, 0]), int(state.pending[0, 1])
    before = float(pop.q_cs[0, node, sub, 1])
    gnp.end_episode(cfg, pop, state, np.full(1, -1.0), 0.5)
    assert pop.q_cs[0, node, sub, 1] == np.float32(before + 0.5 * (earned - before))


def test_midpoint_thresholds_halve_every_feature_and_leave_the_other_genes_alone() -> None:
    base = gnp.GnpConfig(n_judgment=10, n_processing=4, n_inputs=3, n_outputs=2)
    mid = base.model_copy(update={"threshold_init": "midpoint"})
    a = gnp.init_population(base, 6, np.random.default_rng(8))
    b = gnp.init_population(mid, 6, np.random.default_rng(8))
    judg = slice(1, 11)
    assert np.all(b.mu_beta[:, judg] == 511) and np.all(b.mu_alpha[:, judg] == 512)
    assert np.all((b.mu_beta[:, judg] + b.mu_alpha[:, judg]) / 2 == 1023 / 2)
    assert len(np.unique(a.mu_alpha[:, judg])) > 10  # uniform: drawn
    for name in ("function", "speed", "conn", "credit", "q_ss"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    gnp.population_from_arrays(mid, gnp.population_to_arrays(b))  # a valid genome (checked)
    # a crisp midpoint judgment: branch A from reading 512 up, B below
    crisp = gnp.GnpConfig(method="RL", fuzzy=False, n_sub=1, threshold_init="midpoint")
    pop = gnp.init_population(crisp, 2, np.random.default_rng(1))
    state = gnp.init_state(crisp, 2, [1, 2])
    obs = np.array([[512.0] * 8, [511.0] * 8])
    _, trace = gnp.step(crisp, pop, state, obs, np.zeros(2), 0.0, 0.0, trace=True)
    assert trace is not None
    judged = (trace.node > 0) & (trace.node <= crisp.n_judgment)
    assert set(trace.branch[0][judged[0]].tolist()) == {0}
    assert set(trace.branch[1][judged[1]].tolist()) == {1}


@pytest.mark.parametrize("k", [2, 3, 5])
def test_emitting_the_function_sets_output_0_to_the_centre_of_the_functions_bin(k: int) -> None:
    cfg = gnp.GnpConfig(
        method="RL", fuzzy=False, n_outputs=k, processing_output="function", n_sub=1
    )
    pop = gnp.init_population(cfg, 12, np.random.default_rng(k))
    state = gnp.init_state(cfg, 12, np.arange(12))
    seen = set()
    for _ in range(30):
        obs = np.random.default_rng(len(seen)).integers(0, 1024, (12, 8)).astype(float)
        commands, trace = gnp.step(cfg, pop, state, obs, np.zeros(12), 0.0, 0.0, trace=True)
        assert trace is not None
        for i in range(12):
            ran = [
                int(pop.function[i, node, 0])
                for node in trace.node[i, : trace.count[i]]
                if node > cfg.n_judgment
            ]
            if ran:  # at most one processing node per step: it ends the step
                (f,) = ran
                v = commands[i, -1]
                assert v == -10 + (f + 0.5) * 20 / k
                assert min(int((v + 10) / 20 * k), k - 1) == f  # its bin is its function
                assert np.all(commands[i, :-1] == 0.0)  # the other outputs stay unset
                seen.add(f)
    assert seen == set(range(k))


def test_a_step_of_minus_one_falls_on_a_processing_node_that_runs_and_past_one_skipped() -> None:
    """Why tuned CS tests at the floor on −1-a-step tasks (#45, docs/decisions.md): Sarsa
    credits a step's reward to its last visit, so a processing node that runs (five time
    units: the step's only visit) takes the step's −1, while one skipped through its credit
    branch (one unit) passes it to the judgments after it. Start → P; P's normal branch and
    its credit branch both lead to J; J judges and leads to itself. Controller 0 prefers running P
    (Q_CS(P) = [0, −0.5]), controller 1 skipping it ([−0.5, 0]). γ = 0.9, α = 1, ε = 0,
    `skip_reward = "step"`; hand-computed: after the first step pays −1, Q_CS(P, normal) of
    controller 0 is −1 + 0.9·0 = −1, Q_CS(P, skip) of controller 1 stays 0 + 0.9·0 = 0, and
    its −1 lands on J (then −0.9, −0.81, −0.729, −0.6561 over J's next four visits)."""
    cfg = gnp.GnpConfig(
        method="CS", fuzzy=False, n_judgment=1, n_processing=1, n_sub=1, gamma=0.9,
        tie_break="first", skip_reward="step",
    )  # fmt: skip
    pop = gnp.init_population(cfg, 2, np.random.default_rng(0))
    start, j, p = 0, 1, 2
    pop.conn[:, start, 0, 0, 0] = p
    pop.conn[:, j, 0, :, 0] = j
    pop.conn[:, p, 0, 0, 0] = j
    pop.credit[:, j, 0] = j
    pop.credit[:, p, 0] = j
    pop.speed[:, p, 0] = 7
    pop.q_cs[0, p, 0] = [0.0, -0.5]
    pop.q_cs[1, p, 0] = [-0.5, 0.0]
    pop.q_cs[:, j, 0, 1] = -100.0  # J always runs (judges)
    state = gnp.init_state(cfg, 2, [1, 2])
    obs = np.full((2, cfg.n_inputs), 500.0)
    wheels, trace = gnp.step(cfg, pop, state, obs, np.zeros(2), 0.0, 1.0, trace=True)
    assert trace is not None
    assert trace.node[0, : trace.count[0]].tolist() == [start, p]  # P runs: the step is spent
    assert trace.node[1, : trace.count[1]].tolist() == [start, p, j, j, j, j]
    assert trace.skipped[1, 1] == 1
    assert np.any(wheels[0] == 7.0) and np.all(wheels[1] == 0.0)  # only controller 0 acted
    gnp.step(cfg, pop, state, obs, np.full(2, -1.0), 0.0, 1.0)
    np.testing.assert_array_equal(pop.q_cs[0, p, 0], np.float32([-1.0, -0.5]))
    np.testing.assert_array_equal(pop.q_cs[1, p, 0], np.float32([-0.5, 0.0]))
    assert pop.q_cs[0, j, 0, 0] == 0.0
    assert pop.q_cs[1, j, 0, 0] == pytest.approx(-0.6561, abs=1e-6)
    # greedy (ties to the first), controller 0 now prefers the skip at P (−0.5 > −1)
    assert int(np.argmax(pop.q_cs[0, p, 0])) == 1
