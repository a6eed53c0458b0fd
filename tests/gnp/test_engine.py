"""Hand-computed expectations for the engine: time units, judgment, ε-greedy, Sarsa updates."""

from __future__ import annotations

import numpy as np
import pytest

import gnp

A, B = 0, 1
RIGHT, LEFT = 0, 1  # processing functions: P0 sets the right wheel, P1 the left


def graph(cfg: gnp.GnpConfig, n: int = 1) -> gnp.Population:
    """n copies of one individual with all Q values 0, ready to be wired by hand."""
    pop = gnp.init_population(cfg, 1, np.random.default_rng(0))
    return gnp.take(pop, np.zeros(n, dtype=int))


def wire(pop: gnp.Population, node: int, target: int, sub: int = 0, branch: int = A) -> None:
    """Every branch connection (and the credit branch) of (node, sub, branch) → target."""
    pop.conn[:, node, sub, branch, :] = target
    pop.credit[:, node, sub] = target


def sensors(value: float, n: int = 1) -> np.ndarray:
    return np.full((n, 8), float(value))


def run(cfg, pop, state, obs, reward=0.0, eps=0.0, alpha=0.5, learn=True):
    n = state.size
    return gnp.step(cfg, pop, state, obs, np.full(n, reward), eps, alpha, learn, trace=True)


def visited(trace: gnp.StepTrace, i: int = 0) -> list[int]:
    return [int(v) for v in trace.node[i, : trace.count[i]]]


# --- time units -------------------------------------------------------------------------------


def chain_cfg() -> gnp.GnpConfig:
    return gnp.GnpConfig(method="RL", fuzzy=False, n_judgment=5, n_processing=2, n_sub=1)


def test_processing_node_ends_the_step_and_start_runs_once() -> None:
    cfg = chain_cfg()  # nodes: 0 start, 1..5 judgment, 6..7 processing
    pop = graph(cfg)
    wire(pop, 0, 6)
    wire(pop, 6, 7)
    wire(pop, 7, 6)
    pop.function[:, 6, 0], pop.speed[:, 6, 0] = RIGHT, 7
    pop.function[:, 7, 0], pop.speed[:, 7, 0] = LEFT, -3
    state = gnp.init_state(cfg, 1, [1])
    commands, trace = run(cfg, pop, state, sensors(0))
    assert visited(trace) == [0, 6]
    np.testing.assert_array_equal(commands, [[0.0, 7.0]])  # (left, right): right wheel set
    commands, trace = run(cfg, pop, state, sensors(0))
    assert visited(trace) == [7]  # the current node carried over; no start node
    np.testing.assert_array_equal(commands, [[-3.0, 7.0]])  # the right wheel kept its speed
    gnp.reset_episode(state)
    commands, trace = run(cfg, pop, state, sensors(0))
    assert visited(trace) == [0, 6]
    np.testing.assert_array_equal(commands, [[0.0, 7.0]])


def test_five_judgments_end_the_step_and_the_overshooting_node_runs() -> None:
    cfg = chain_cfg()
    pop = graph(cfg)
    wire(pop, 0, 1)
    for j in range(1, 5):  # J1 → J2 → J3 → J4 → P6 on both branches
        wire(pop, j, j + 1, branch=A)
        wire(pop, j, j + 1, branch=B)
    wire(pop, 4, 6, branch=A)
    wire(pop, 4, 6, branch=B)
    wire(pop, 6, 1)
    pop.function[:, 6, 0], pop.speed[:, 6, 0] = LEFT, 5
    state = gnp.init_state(cfg, 1, [1])
    commands, trace = run(cfg, pop, state, sensors(0))
    # 4 judgments (4 units) then P6 (5 more): it overshoots the budget of 5 but still runs.
    assert visited(trace) == [0, 1, 2, 3, 4, 6]
    np.testing.assert_array_equal(commands, [[5.0, 0.0]])
    wire(pop, 4, 5, branch=A)
    wire(pop, 4, 5, branch=B)
    wire(pop, 5, 1, branch=A)
    wire(pop, 5, 1, branch=B)
    commands, trace = run(cfg, pop, state, sensors(0))
    assert visited(trace) == [1, 2, 3, 4, 5]  # five judgments spend the budget
    commands, trace = run(cfg, pop, state, sensors(0))
    assert visited(trace) == [1, 2, 3, 4, 5]


# --- judgment ---------------------------------------------------------------------------------


def judgment_cfg(fuzzy: bool) -> gnp.GnpConfig:
    return gnp.GnpConfig(method="RL", fuzzy=fuzzy, n_judgment=1, n_processing=2, n_sub=1)


def judge_once(fuzzy: bool, x: float, n: int = 1) -> np.ndarray:
    """Branch taken by judgment node 1 (sensor 3, β = 100, α = 300) on reading x, n times."""
    cfg = judgment_cfg(fuzzy)
    pop = graph(cfg, n)
    wire(pop, 0, 1)
    wire(pop, 1, 2, branch=A)
    wire(pop, 1, 3, branch=B)
    pop.function[:, 1, 0] = 3
    pop.mu_beta[:, 1, 0], pop.mu_alpha[:, 1, 0] = 100, 300
    obs = np.zeros((n, 8))
    obs[:, 3] = x
    state = gnp.init_state(cfg, n, np.arange(n))
    _, trace = run(cfg, pop, state, obs)
    assert np.all(trace.node[:, 1] == 1)
    np.testing.assert_array_equal(trace.node[:, 2], np.where(trace.branch[:, 1] == A, 2, 3))
    return trace.branch[:, 1]


@pytest.mark.parametrize(("x", "branch"), [(0, B), (199.99, B), (200, A), (250, A), (1023, A)])
def test_crisp_threshold_is_the_midpoint(x: float, branch: int) -> None:
    assert judge_once(False, x)[0] == branch


@pytest.mark.parametrize(("x", "mu"), [(50, 0.0), (100, 0.0), (150, 0.25), (250, 0.75), (300, 1.0)])
def test_fuzzy_branch_frequency_matches_membership(x: float, mu: float) -> None:
    n = 4000
    share_a = float(np.mean(judge_once(True, x, n) == A))
    if mu in (0.0, 1.0):
        assert share_a == mu
    else:  # binomial: within 5 standard deviations
        assert abs(share_a - mu) < 5 * np.sqrt(mu * (1 - mu) / n)


# --- ε-greedy ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("q", "eps", "expected"),
    [
        ([0.0, 1.0, 0.0, 0.0], 0.2, [0.05, 0.85, 0.05, 0.05]),
        ([0.0, 1.0, 0.0, 0.0], 0.0, [0.0, 1.0, 0.0, 0.0]),
        ([2.0, 2.0, 0.0, 2.0], 0.0, [1 / 3, 1 / 3, 0.0, 1 / 3]),  # uniform among tied maxima
        ([2.0, 2.0, 0.0, 0.0], 1.0, [0.25, 0.25, 0.25, 0.25]),
    ],
)
def test_epsilon_greedy_frequencies(q: list[float], eps: float, expected: list[float]) -> None:
    cfg = gnp.GnpConfig(method="RL", fuzzy=False, n_judgment=1, n_processing=1, n_sub=4)
    n = 6000
    pop = graph(cfg, n)
    wire(pop, 0, 2)
    pop.q_ss[:, 2, :] = q
    state = gnp.init_state(cfg, n, np.arange(n))
    _, trace = run(cfg, pop, state, sensors(0, n), eps=eps, learn=False)
    share = np.bincount(trace.sub[:, 1], minlength=4) / n
    for got, want in zip(share, expected, strict=True):
        assert abs(got - want) <= 5 * np.sqrt(want * (1 - want) / n)


# --- Sarsa ------------------------------------------------------------------------------------


def test_sarsa_rl_two_processing_nodes() -> None:
    """Each step runs one processing node; its reward arrives with the next step (Eq. 2.3)."""
    cfg = gnp.GnpConfig(method="RL", n_judgment=1, n_processing=2, n_sub=1, gamma=0.9)
    pop = graph(cfg)
    wire(pop, 0, 2)
    wire(pop, 2, 3)
    wire(pop, 3, 2)
    state = gnp.init_state(cfg, 1, [5])
    run(cfg, pop, state, sensors(0), reward=99.0)  # reward before the first visit: ignored
    assert pop.q_ss[0, :, 0].tolist() == [0, 0, 0, 0]
    run(cfg, pop, state, sensors(0), reward=1.0)
    assert pop.q_ss[0, 2, 0] == pytest.approx(0.5 * (1.0 + 0.9 * 0.0))
    run(cfg, pop, state, sensors(0), reward=2.0)
    assert pop.q_ss[0, 3, 0] == pytest.approx(0.5 * (2.0 + 0.9 * 0.5))  # 1.225
    run(cfg, pop, state, sensors(0), reward=0.0)
    assert pop.q_ss[0, 2, 0] == pytest.approx(0.5 + 0.5 * (0.0 + 0.9 * 1.225 - 0.5))  # 0.80125


def test_sarsa_rl_transitions_inside_a_step_earn_zero() -> None:
    """J1 → P2 → J1: the step's reward goes to P2 (its last node); J1's transition earns 0."""
    cfg = gnp.GnpConfig(method="RL", fuzzy=False, n_judgment=1, n_processing=1, n_sub=1)
    pop = graph(cfg)
    wire(pop, 0, 1)
    wire(pop, 1, 2, branch=A)
    wire(pop, 1, 2, branch=B)
    wire(pop, 2, 1)
    state = gnp.init_state(cfg, 1, [5])
    _, trace = run(cfg, pop, state, sensors(0))
    assert visited(trace) == [0, 1, 2]
    _, trace = run(cfg, pop, state, sensors(0), reward=1.0)
    assert visited(trace) == [1, 2]
    q_j, q_p = pop.q_ss[0, 1, 0], pop.q_ss[0, 2, 0]
    assert q_p == pytest.approx(0.5 * (1.0 + 0.0))
    assert q_j == pytest.approx(0.5 * (0.0 + 0.9 * 0.5))  # 0.225
    run(cfg, pop, state, sensors(0), reward=1.0)
    assert pop.q_ss[0, 2, 0] == pytest.approx(0.5 + 0.5 * (1.0 + 0.9 * 0.225 - 0.5))  # 0.85125
    assert pop.q_ss[0, 1, 0] == pytest.approx(0.225 + 0.5 * (0.9 * 0.85125 - 0.225))


def test_learn_false_leaves_q_tables_alone() -> None:
    cfg = gnp.GnpConfig(method="CS")
    pop = gnp.init_population(cfg, 5, np.random.default_rng(1))
    before = {k: v.copy() for k, v in gnp.population_to_arrays(pop).items()}
    state = gnp.init_state(cfg, 5, range(5))
    rng = np.random.default_rng(2)
    for _ in range(20):
        gnp.step(cfg, pop, state, rng.uniform(0, 1023, (5, 8)), np.ones(5), 0.1, 0.5, learn=False)
    for k, v in gnp.population_to_arrays(pop).items():
        np.testing.assert_array_equal(v, before[k])


def test_sarsa_bs_branch_connection_earns_the_next_nodes_reward() -> None:
    """Eq. 3.2: Q_BS of the branch connection P2 chose gets r_{t+1}, the reward of P3 it led to."""
    cfg = gnp.GnpConfig(method="BS", n_judgment=1, n_processing=3, n_sub=1, n_branch=2)
    pop = graph(cfg)  # nodes: 0 start, 1 judgment, 2..4 processing
    wire(pop, 0, 2)
    pop.conn[0, 2, 0, A, :] = [3, 4]
    pop.conn[0, 3, 0, A, :] = [2, 2]
    pop.conn[0, 4, 0, A, :] = [2, 2]
    for node in (2, 3, 4):
        pop.q_bs[0, node, 0, A, :] = [1.0, 0.0]  # greedy: branch connection u = 0
    state = gnp.init_state(cfg, 1, [9])
    _, trace = run(cfg, pop, state, sensors(0))
    assert visited(trace) == [0, 2] and trace.u[0, 1] == 0
    _, trace = run(cfg, pop, state, sensors(0), reward=1.0)
    assert visited(trace) == [3]
    assert pop.q_ss[0, 2, 0] == pytest.approx(0.5)  # Eq. 3.1 with r_t = 1
    assert pop.q_bs[0, 2, 0, A, 0] == 1.0  # P2's branch connection still awaits r_{t+1}
    _, trace = run(cfg, pop, state, sensors(0), reward=2.0)
    assert visited(trace) == [2]
    assert pop.q_ss[0, 3, 0] == pytest.approx(0.5 * (2.0 + 0.9 * 0.5))
    assert pop.q_bs[0, 2, 0, A, 0] == pytest.approx(1.0 + 0.5 * (2.0 + 0.9 * 1.0 - 1.0))  # 1.95
    assert pop.q_bs[0, 2, 0, A, 1] == 0.0


def test_sarsa_cs_credit_skip_earns_zero() -> None:
    """Eq. 5.1–5.3: a skipped node runs nothing, costs 1 unit and earns reward 0."""
    cfg = gnp.GnpConfig(method="CS", n_judgment=1, n_processing=2, n_sub=1)
    pop = graph(cfg)  # nodes: 0 start, 1 judgment, 2..3 processing
    wire(pop, 0, 2)
    wire(pop, 2, 3)
    wire(pop, 3, 2)
    pop.function[0, 2, 0], pop.speed[0, 2, 0] = LEFT, 9
    pop.function[0, 3, 0], pop.speed[0, 3, 0] = RIGHT, 4
    pop.q_cs[0, 2, 0] = [0.0, 1.0]  # P2 prefers its credit branch
    pop.q_cs[0, 3, 0] = [1.0, 0.0]  # P3 prefers normal
    state = gnp.init_state(cfg, 1, [3])
    commands, trace = run(cfg, pop, state, sensors(0))
    assert visited(trace) == [0, 2, 3]  # the skip cost 1 unit, so P3 ran in the same step
    assert trace.skipped[0, :3].tolist() == [0, 1, 0]
    np.testing.assert_array_equal(commands, [[0.0, 4.0]])  # P2's left wheel never set
    assert pop.q_cs[0, 2, 0, 1] == pytest.approx(1.0 + 0.5 * (0.0 + 0.9 * 1.0 - 1.0))  # 0.95
    _, trace = run(cfg, pop, state, sensors(0), reward=1.0)
    assert visited(trace) == [2, 3]
    # P3 (normal, last node of step 1) earned 1; it bootstraps on P2's chosen credit branch.
    assert pop.q_ss[0, 3, 0] == pytest.approx(0.5 * (1.0 + 0.0))
    assert pop.q_cs[0, 3, 0, 0] == pytest.approx(1.0 + 0.5 * (1.0 + 0.9 * 0.95 - 1.0))  # 1.4275
    # The skip of P2 earned 0 (Eq. 5.3).
    assert pop.q_ss[0, 2, 0] == pytest.approx(0.5 * (0.0 + 0.9 * 0.5))
    assert pop.q_cs[0, 2, 0, 1] == pytest.approx(0.95 + 0.5 * (0.9 * 1.4275 - 0.95))
    assert pop.q_cs[0, 2, 0, 0] == 0.0


def test_cs_skip_ending_a_step_earns_zero_not_the_world_reward() -> None:
    cfg = gnp.GnpConfig(method="CS", fuzzy=False, n_judgment=4, n_processing=1, n_sub=1)
    pop = graph(cfg)  # J1 → J2 → J3 → J4 → P5 (skipped) → J1
    wire(pop, 0, 1)
    for j in range(1, 5):
        wire(pop, j, j + 1, branch=A)
        wire(pop, j, j + 1, branch=B)
    wire(pop, 5, 1)
    pop.q_cs[0, 1:5, 0] = [1.0, 0.0]
    pop.q_cs[0, 5, 0] = [0.0, 1.0]
    state = gnp.init_state(cfg, 1, [3])
    _, trace = run(cfg, pop, state, sensors(0))
    assert visited(trace) == [0, 1, 2, 3, 4, 5] and trace.skipped[0, 5] == 1
    run(cfg, pop, state, sensors(0), reward=10.0)
    assert pop.q_ss[0, 5, 0] == pytest.approx(0.0)  # 0.5·(0 + 0.9·Q_SS(J1) = 0)
    # J1's normal branch fell to 0.95 in step 1 (J1 → J2 inside the step earned 0).
    assert pop.q_cs[0, 5, 0, 1] == pytest.approx(1.0 + 0.5 * (0.0 + 0.9 * 0.95 - 1.0))


# --- bad input --------------------------------------------------------------------------------


def test_bad_input_raises_gnp_error() -> None:
    cfg = gnp.GnpConfig()
    pop = gnp.init_population(cfg, 3, np.random.default_rng(0))
    state = gnp.init_state(cfg, 3, [0, 1, 2])
    ok = np.zeros((3, 8))
    with pytest.raises(gnp.GnpError, match="observations"):
        gnp.step(cfg, pop, state, np.zeros((3, 7)), np.zeros(3), 0.1, 0.1)
    with pytest.raises(gnp.GnpError, match="reward"):
        gnp.step(cfg, pop, state, ok, np.zeros(2), 0.1, 0.1)
    with pytest.raises(gnp.GnpError, match="epsilon"):
        gnp.step(cfg, pop, state, ok, np.zeros(3), 1.5, 0.1)
    with pytest.raises(gnp.GnpError, match="alpha"):
        gnp.step(cfg, pop, state, ok, np.zeros(3), 0.1, np.array([0.1, 0.2]))
    with pytest.raises(gnp.GnpError, match="individuals"):
        gnp.step(cfg, gnp.take(pop, [0, 1]), state, ok, np.zeros(3), 0.1, 0.1)
    with pytest.raises(gnp.GnpError, match="config"):
        gnp.step(gnp.GnpConfig(n_sub=3), pop, state, ok, np.zeros(3), 0.1, 0.1)
    with pytest.raises(gnp.GnpError, match="seeds"):
        gnp.init_state(cfg, 3, [0, 1])
    with pytest.raises(gnp.GnpError, match="seeds"):
        gnp.init_state(cfg, 2, [0, -1])
