"""Multi-way judgment (`GnpConfig.judgment_branches` k): k equal bins of β..α, crisp."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

import gnp
from gnp.controller_file import controller_body, controller_from_body
from gnp.reference import ReferenceController
from gnp.structure import reachable


def _judge_cfg(k: int) -> gnp.GnpConfig:
    """Start → node 1 (one judgment sub node, every branch to node 2) → node 2 (processing)."""
    return gnp.GnpConfig(
        method="RL", fuzzy=False, judgment_branches=k, n_judgment=1, n_processing=1, n_sub=1,
        n_inputs=1, n_outputs=2,
    )  # fmt: skip


def _branches(k: int, beta: int, alpha: int, readings: list[float]) -> tuple[list[int], list[int]]:
    """The branch node 1 takes for each reading: (kernel's, reference's)."""
    cfg = _judge_cfg(k)
    n = len(readings)
    pop = gnp.init_population(cfg, n, np.random.default_rng(0))
    pop.conn[:, 0, 0, 0, 0] = 1
    pop.conn[:, 1] = 2
    pop.conn[:, 2] = 1
    pop.mu_beta[:, 1, 0], pop.mu_alpha[:, 1, 0] = beta, alpha
    state = gnp.init_state(cfg, n, np.arange(n))
    obs = np.asarray(readings, np.float64)[:, None]
    _, trace = gnp.step(cfg, pop, state, obs, np.zeros(n), 0.0, 0.0, learn=False, trace=True)
    assert trace is not None
    assert np.all(trace.node[:, 1] == 1)
    kernel = [int(b) for b in trace.branch[:, 1]]
    reference = []
    for i, x in enumerate(readings):
        _, visits = ReferenceController(cfg, pop, i, i).step([x], 0.0, 0.0, 0.0, learn=False)
        assert visits[1].node == 1
        reference.append(visits[1].branch)
    return kernel, reference


@pytest.mark.parametrize(
    ("k", "beta", "alpha", "readings", "want"),
    [
        # β = 0, α = 90, 3 bins with edges 30 and 60: branch A (0) is the high bin.
        (3, 0, 90, [-5.0, 0.0, 29.9, 30.0, 45.0, 59.99, 60.0, 89.0, 90.0, 1023.0],
         [2, 2, 2, 1, 1, 1, 0, 0, 0, 0]),
        # β = 100, α = 500, 4 bins with edges 200, 300, 400.
        (4, 100, 500, [0.0, 100.0, 199.5, 200.0, 299.0, 300.0, 399.99, 400.0, 500.0, 600.0],
         [3, 3, 3, 2, 2, 1, 1, 0, 0, 0]),
        # Edges 100 + 100/3·j fall between integers: 133.33…, 166.66….
        (3, 100, 200, [133.0, 134.0, 166.0, 167.0], [2, 1, 1, 0]),
        # β = α: below is the lowest bin, at or above the highest (as k = 2's midpoint).
        (5, 300, 300, [299.0, 300.0, 301.0], [4, 0, 0]),
        # k = 2 is the midpoint split (β + α)/2 = 511.5.
        (2, 500, 523, [511.0, 511.5, 512.0], [1, 0, 0]),
    ],
)  # fmt: skip
def test_a_k_way_judgment_takes_the_bin_of_its_reading(
    k: int, beta: int, alpha: int, readings: list[float], want: list[int]
) -> None:
    kernel, reference = _branches(k, beta, alpha, readings)
    assert kernel == want
    assert reference == want


@given(seed=st.integers(0, 2**32 - 1), k=st.sampled_from([3, 4]))
@settings(max_examples=6, deadline=None)
def test_the_engine_matches_the_reference_with_k_branches(seed: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    for method in ("RL", "BS", "CS"):
        cfg = gnp.GnpConfig(
            method=method, fuzzy=False, judgment_branches=k, n_judgment=10, n_processing=5,
            n_sub=2, tie_break=("random", "first")[seed % 2],
        )  # fmt: skip
        n, steps = 8, 120
        pop = gnp.init_population(cfg, n, rng)
        for q in (pop.q_ss, pop.q_bs, pop.q_cs):
            q[:] = rng.integers(0, 3, size=q.shape) * 0.5
        seeds = rng.integers(0, 2**63, size=n)
        refs = [ReferenceController(cfg, pop, i, int(seeds[i])) for i in range(n)]
        state = gnp.init_state(cfg, n, seeds)
        epsilon = rng.uniform(0.0, 0.4, size=n)
        reward = np.zeros(n)
        branches: set[int] = set()
        for t in range(steps):
            obs = rng.integers(0, 1024, size=(n, 8)).astype(np.float64)  # edges hit at times
            commands, trace = gnp.step(cfg, pop, state, obs, reward, epsilon, 0.2, trace=True)
            assert trace is not None
            for i, ref in enumerate(refs):
                (left, right), visits = ref.step(list(obs[i]), reward[i], epsilon[i], 0.2)
                assert (commands[i, 0], commands[i, -1]) == (left, right)
                c = int(trace.count[i])
                columns = (trace.node, trace.sub, trace.branch, trace.u, trace.skipped)
                got = [tuple(int(col[i, j]) for col in columns) for j in range(c)]
                assert got == [(v.node, v.sub, v.branch, v.u, int(v.credit)) for v in visits]
                branches.update(v.branch for v in visits if 1 <= v.node <= cfg.n_judgment)
            reward = rng.uniform(0.0, 1.0, size=n).round(3)
            if t % 37 == 36:
                gnp.reset_episode(state)
                for ref in refs:
                    ref.reset_episode()
        for i, ref in enumerate(refs):
            np.testing.assert_array_equal(pop.q_ss[i], ref.q_ss)
            np.testing.assert_array_equal(pop.q_bs[i], ref.q_bs)
            np.testing.assert_array_equal(pop.q_cs[i], ref.q_cs)
        assert branches >= set(range(k))


def test_fuzzy_judgment_with_more_than_two_branches_is_refused() -> None:
    with pytest.raises(ValidationError, match="needs crisp judgment"):
        gnp.GnpConfig(fuzzy=True, judgment_branches=3)
    assert gnp.GnpConfig(fuzzy=True, judgment_branches=2).judgment_branches == 2


@pytest.mark.parametrize("k", [0, 1, 9])
def test_judgment_branches_outside_2_to_8_are_refused(k: int) -> None:
    with pytest.raises(ValidationError):
        gnp.GnpConfig(fuzzy=False, judgment_branches=k)


def test_the_branch_axis_has_k_entries_and_evolution_keeps_it_valid() -> None:
    cfg = gnp.GnpConfig(method="BS", fuzzy=False, judgment_branches=4, n_judgment=8)
    rng = np.random.default_rng(1)
    pop = gnp.init_population(cfg, 12, rng)
    assert pop.conn.shape[1:] == (cfg.n_nodes, 2, 4, 2)
    assert pop.q_bs.shape == pop.conn.shape
    evo = gnp.EvolutionConfig(p_mutation=0.2, p_add_delete=0.5)
    for g in range(5):
        pop = gnp.evolve(cfg, pop, rng.normal(size=12), g, 5, rng, evo)
        gnp.check_population(cfg, pop)
    assert pop.conn.shape[1:] == (cfg.n_nodes, 2, 4, 2)


def test_every_branch_of_a_judgment_node_is_reachable() -> None:
    cfg = gnp.GnpConfig(
        fuzzy=False, judgment_branches=3, n_judgment=3, n_processing=1, n_sub=1
    )  # fmt: skip
    pop = gnp.init_population(cfg, 1, np.random.default_rng(0))
    pop.conn[:] = 4  # everything to the processing node (4), which goes back to it
    pop.conn[0, 0, 0, 0, 0] = 1
    pop.conn[0, 1, 0, 2, 0] = 3  # node 1's branch C only
    assert reachable(cfg, pop)[0].tolist() == [True, True, False, True, True]


def test_a_controller_document_names_every_branch_and_reads_back() -> None:
    cfg = gnp.GnpConfig(method="BS", fuzzy=False, judgment_branches=3, n_judgment=4)
    pop = gnp.init_population(cfg, 1, np.random.default_rng(2))
    entry, nodes = controller_body(cfg, pop)
    assert entry["judgment_branches"] == 3
    assert list(nodes[1]["sub_nodes"][0]["next"]) == ["A", "B", "C"]
    back_cfg, back = controller_from_body(entry, nodes)
    assert back_cfg == cfg
    np.testing.assert_array_equal(back.records, pop.records)
    two = gnp.GnpConfig(fuzzy=False, n_judgment=4)
    entry, nodes = controller_body(two, gnp.init_population(two, 1, np.random.default_rng(2)))
    assert "judgment_branches" not in entry  # a document of k = 2 reads as before
    assert list(nodes[1]["sub_nodes"][0]["next"]) == ["A", "B"]
