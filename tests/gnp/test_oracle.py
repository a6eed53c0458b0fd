"""The compiled engine matches the plain-Python reference interpreter exactly."""

from __future__ import annotations

import numpy as np
import pytest

import gnp
from gnp.reference import ReferenceController


def random_learning_population(
    cfg: gnp.GnpConfig, n: int, rng: np.random.Generator
) -> gnp.Population:
    """Random genomes with coarse random Q values, so greedy choices and ties both occur."""
    pop = gnp.init_population(cfg, n, rng)
    for q in (pop.q_ss, pop.q_bs, pop.q_cs):
        q[:] = rng.integers(0, 3, size=q.shape) * 0.5
    return pop


@pytest.mark.parametrize(
    "task_settings",
    [
        {},
        {"tie_break": "first"},
        {"skip_reward": "step", "q0": -0.5},
        {"processing_output": "function", "n_outputs": 3},
    ],
    ids=["robot", "tie-first", "skip-earns", "emit-function"],
)
@pytest.mark.parametrize("fuzzy", [True, False], ids=["fuzzy", "crisp"])
@pytest.mark.parametrize("method", ["RL", "BS", "CS"])
def test_engine_matches_reference(method: str, fuzzy: bool, task_settings: dict) -> None:
    cfg = gnp.GnpConfig.model_validate(
        dict(method=method, fuzzy=fuzzy, n_judgment=12, n_processing=6, n_sub=3, **task_settings)
    )
    rng = np.random.default_rng(7)
    n, steps = 16, 320
    pop = random_learning_population(cfg, n, rng)
    seeds = rng.integers(0, 2**63, size=n)
    refs = [ReferenceController(cfg, pop, i, int(seeds[i])) for i in range(n)]
    state = gnp.init_state(cfg, n, seeds)
    epsilon = rng.uniform(0.0, 0.4, size=n)
    reward = np.zeros(n)
    transitions = 0
    for t in range(steps):
        # Integer readings hit the crisp threshold (α+β)/2 and the fuzzy bounds exactly at times.
        obs = rng.integers(0, 1024, size=(n, 8)).astype(np.float64)
        learn = t % 50 != 7
        alpha = 0.1 if t % 3 else 0.5
        commands, trace = gnp.step(cfg, pop, state, obs, reward, epsilon, alpha, learn, trace=True)
        for i, ref in enumerate(refs):
            (left, right), visits = ref.step(list(obs[i]), reward[i], epsilon[i], alpha, learn)
            assert (commands[i, 0], commands[i, -1]) == (left, right)
            k = int(trace.count[i])
            columns = (trace.node, trace.sub, trace.branch, trace.u, trace.skipped)
            got = [tuple(int(col[i, j]) for col in columns) for j in range(k)]
            want = [(v.node, v.sub, v.branch, v.u, int(v.credit)) for v in visits]
            assert got == want, f"controller {i} step {t}"
            assert np.all(trace.node[i, k:] == -1)
            transitions += k
        reward = rng.uniform(0.0, 1.0, size=n).round(3)
        if t % 97 == 96:  # a new episode for half the controllers, Q tables kept
            gnp.reset_episode(state)
            for ref in refs:
                ref.reset_episode()
    assert transitions >= 10_000
    for i, ref in enumerate(refs):
        np.testing.assert_array_equal(pop.q_ss[i], ref.q_ss)
        np.testing.assert_array_equal(pop.q_bs[i], ref.q_bs)
        np.testing.assert_array_equal(pop.q_cs[i], ref.q_cs)
        assert state.node[i] == ref.node


SECOND_STAGE_PATTERNS = {
    "off": lambda _t: False,
    "toggled": lambda t: (t // 23) % 2 == 1,  # off and on in turns, mid-episode
}


@pytest.mark.parametrize("pattern", sorted(SECOND_STAGE_PATTERNS))
@pytest.mark.parametrize("fuzzy", [True, False], ids=["fuzzy", "crisp"])
@pytest.mark.parametrize("method", ["RL", "BS", "CS"])
def test_second_stage_off_matches_reference(method: str, fuzzy: bool, pattern: str) -> None:
    """Live ablation (`second_stage=False`): the kernel and the reference agree bit for bit.

    Off, BS takes the greedy branch connection and leaves Q_BS alone, CS never skips and
    leaves Q_CS alone; RL is unaffected.
    """
    cfg = gnp.GnpConfig(
        method=method,  # type: ignore[arg-type]
        fuzzy=fuzzy,
        n_judgment=12,
        n_processing=6,
        n_sub=3,
    )
    rng = np.random.default_rng(11)
    n, steps = 16, 320
    pop = random_learning_population(cfg, n, rng)
    q_bs0, q_cs0 = pop.q_bs.copy(), pop.q_cs.copy()
    seeds = rng.integers(0, 2**63, size=n)
    refs = [ReferenceController(cfg, pop, i, int(seeds[i])) for i in range(n)]
    state = gnp.init_state(cfg, n, seeds)
    epsilon = rng.uniform(0.1, 0.5, size=n)
    reward = np.zeros(n)
    transitions = off_transitions = 0
    on_at = SECOND_STAGE_PATTERNS[pattern]
    for t in range(steps):
        obs = rng.integers(0, 1024, size=(n, 8)).astype(np.float64)
        alpha = 0.1 if t % 3 else 0.5
        on = on_at(t)
        q_bs, q_cs = pop.q_bs.copy(), pop.q_cs.copy()
        commands, trace = gnp.step(
            cfg, pop, state, obs, reward, epsilon, alpha, trace=True, second_stage=on
        )
        for i, ref in enumerate(refs):
            (left, right), visits = ref.step(
                list(obs[i]), reward[i], epsilon[i], alpha, second_stage=on
            )
            assert (commands[i, 0], commands[i, -1]) == (left, right)
            k = int(trace.count[i])
            columns = (trace.node, trace.sub, trace.branch, trace.u, trace.skipped)
            got = [tuple(int(col[i, j]) for col in columns) for j in range(k)]
            want = [(v.node, v.sub, v.branch, v.u, int(v.credit)) for v in visits]
            assert got == want, f"controller {i} step {t}"
            transitions += k
            if not on:
                off_transitions += k
        if not on:
            # Off: no credit skip, the greedy u, and no second-stage learning.
            assert not np.any(trace.skipped == 1)
            np.testing.assert_array_equal(pop.q_bs, q_bs)
            np.testing.assert_array_equal(pop.q_cs, q_cs)
            if method == "BS":
                for i in range(n):
                    for j in range(int(trace.count[i])):
                        node, sub, branch, u = (
                            int(trace.node[i, j]),
                            int(trace.sub[i, j]),
                            int(trace.branch[i, j]),
                            int(trace.u[i, j]),
                        )
                        if node > 0:
                            assert u == int(np.argmax(pop.q_bs[i, node, sub, branch]))
        reward = rng.uniform(0.0, 1.0, size=n).round(3)
        if t % 97 == 96:
            gnp.reset_episode(state)
            for ref in refs:
                ref.reset_episode()
    assert transitions >= 10_000
    assert off_transitions >= (10_000 if pattern == "off" else 4_000)
    for i, ref in enumerate(refs):
        np.testing.assert_array_equal(pop.q_ss[i], ref.q_ss)
        np.testing.assert_array_equal(pop.q_bs[i], ref.q_bs)
        np.testing.assert_array_equal(pop.q_cs[i], ref.q_cs)
        assert state.node[i] == ref.node
    if pattern == "off":
        np.testing.assert_array_equal(pop.q_bs, q_bs0)
        np.testing.assert_array_equal(pop.q_cs, q_cs0)


def test_split_batch_is_identical() -> None:
    """A controller's behaviour does not depend on its batch: two halves equal the whole."""
    cfg = gnp.GnpConfig(method="BS", n_judgment=8, n_processing=4)
    rng = np.random.default_rng(3)
    pop = random_learning_population(cfg, 10, rng)
    halves = [gnp.take(pop, range(0, 4)), gnp.take(pop, range(4, 10))]
    seeds = np.arange(100, 110)
    whole_state = gnp.init_state(cfg, 10, seeds)
    half_states = [gnp.init_state(cfg, 4, seeds[:4]), gnp.init_state(cfg, 6, seeds[4:])]
    reward = np.zeros(10)
    for _ in range(200):
        obs = rng.uniform(0, 1023, size=(10, 8))
        whole, _ = gnp.step(cfg, pop, whole_state, obs, reward, 0.2, 0.1)
        parts = [
            gnp.step(cfg, halves[0], half_states[0], obs[:4], reward[:4], 0.2, 0.1)[0],
            gnp.step(cfg, halves[1], half_states[1], obs[4:], reward[4:], 0.2, 0.1)[0],
        ]
        np.testing.assert_array_equal(whole, np.concatenate(parts))
        reward = rng.uniform(0, 1, size=10)
    np.testing.assert_array_equal(pop.q_bs, gnp.concat(halves).q_bs)
    np.testing.assert_array_equal(pop.q_ss, gnp.concat(halves).q_ss)


@pytest.mark.parametrize("method", ["RL", "BS", "CS"])
def test_tracing_changes_nothing(method: str) -> None:
    """The dashboard's trace is a read-out: with or without it, the same commands and Q."""
    cfg = gnp.GnpConfig(method=method, n_judgment=8, n_processing=4)
    rng = np.random.default_rng(5)
    traced = random_learning_population(cfg, 6, rng)
    plain = gnp.take(traced, range(6))
    states = [gnp.init_state(cfg, 6, range(6)), gnp.init_state(cfg, 6, range(6))]
    reward = np.zeros(6)
    for _ in range(100):
        obs = rng.uniform(0, 1023, size=(6, 8))
        with_trace, trace = gnp.step(cfg, traced, states[0], obs, reward, 0.3, 0.2, trace=True)
        without, no_trace = gnp.step(cfg, plain, states[1], obs, reward, 0.3, 0.2)
        np.testing.assert_array_equal(with_trace, without)
        assert trace is not None and no_trace is None  # one shape, the trace only when asked
        assert np.all(trace.count >= 1)
        reward = rng.uniform(0, 1, size=6)
    for f in ("q_ss", "q_bs", "q_cs"):
        np.testing.assert_array_equal(getattr(traced, f), getattr(plain, f))
