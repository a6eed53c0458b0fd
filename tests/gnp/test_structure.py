"""Add/delete-node mutation (`gnp.structure`) and its setting in `evolve`."""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

import gnp
from gnp import structure
from gnp.population import FIELDS

configs = st.builds(
    gnp.GnpConfig,
    method=st.sampled_from(["RL", "BS", "CS"]),
    n_judgment=st.integers(1, 8),
    n_processing=st.integers(1, 5),
    n_sub=st.integers(1, 3),
    n_branch=st.integers(1, 3),
    q0=st.sampled_from([0.0, -3.0]),
    threshold_init=st.sampled_from(["uniform", "midpoint"]),
)


def _lived(cfg: gnp.GnpConfig, n: int, seed: int) -> gnp.Population:
    """A population after a few rounds of heavy mutation and add/delete (unreachable nodes
    exist), its Q values as lives leave them (not q0)."""
    rng = np.random.default_rng(seed)
    pop = gnp.init_population(cfg, n, rng)
    for g in range(3):
        pop = gnp.mutate(cfg, pop, g, 3, rng, p_mutation=0.3)
        pop = structure.add_delete_nodes(cfg, pop, 0.5, rng).population
    for f in ("q_ss", "q_bs", "q_cs"):
        getattr(pop, f)[...] = rng.normal(5.0, 1.0, size=getattr(pop, f).shape)
    return pop


@settings(max_examples=60, deadline=None)
@given(cfg=configs, n=st.integers(1, 12), seed=st.integers(0, 2**32 - 1))
def test_add_and_delete_keep_a_valid_genome_and_change_only_what_they_say(
    cfg: gnp.GnpConfig, n: int, seed: int
) -> None:
    pop = _lived(cfg, n, seed)
    before = {f: getattr(pop, f).copy() for f in FIELDS}
    drawn: list[gnp.Population] = []

    def recording(*args: Any) -> gnp.Population:
        fresh = gnp.init_population(*args)
        drawn.append(fresh)
        return fresh

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(structure, "init_population", recording)
        edited = structure.add_delete_nodes(cfg, pop, 1.0, np.random.default_rng(seed))
    out = edited.population
    gnp.check_population(cfg, out)
    for f in FIELDS:  # the input is not modified
        np.testing.assert_array_equal(getattr(pop, f), before[f], err_msg=f)
    assert not np.any((edited.added >= 0) & (edited.deleted >= 0))
    assert len(drawn) == int((edited.added >= 0).sum())
    reach_before, reach_after = structure.reachable(cfg, pop), structure.reachable(cfg, out)
    fresh_rows = iter(drawn)
    for i in range(n):
        a, d = int(edited.added[i]), int(edited.deleted[i])
        if d >= 0:
            assert reach_before[i, d] and not reach_after[i, d]
            assert not np.any(out.conn[i] == d) and not np.any(out.credit[i] == d)
            for f in FIELDS:  # only the connections that named d changed
                changed = getattr(out, f)[i] != before[f][i]
                if f in ("conn", "credit"):
                    assert np.array_equal(changed, before[f][i] == d), f
                else:
                    assert not changed.any(), f
        elif a >= 0:
            assert not reach_before[i, a] and reach_after[i, a] and a != 0
            fresh = next(fresh_rows)
            for f in FIELDS:  # the added node is generation 0's draw, Q values q0 included
                np.testing.assert_array_equal(getattr(out, f)[i, a], getattr(fresh, f)[0, a])
            assert np.all(out.q_ss[i, a] == cfg.q0)
            # elsewhere one connection was redirected to a, nothing else
            others = np.arange(cfg.n_nodes) != a
            moved = (out.conn[i, others] != before["conn"][i, others]).sum() + (
                out.credit[i, others] != before["credit"][i, others]
            ).sum()
            assert moved == 1
            for f in FIELDS:
                if f not in ("conn", "credit"):
                    np.testing.assert_array_equal(getattr(out, f)[i, others], before[f][i, others])
        else:  # no unreachable node to add: untouched
            assert reach_before[i, 1:].all()
            for f in FIELDS:
                np.testing.assert_array_equal(getattr(out, f)[i], before[f][i], err_msg=f)


def test_reachable_follows_the_walk_a_method_can_take() -> None:
    cfg = gnp.GnpConfig(method="RL", n_judgment=2, n_processing=2, n_sub=1)  # nodes 0..4
    pop = gnp.init_population(cfg, 1, np.random.default_rng(0))
    pop.conn[...] = 1
    pop.credit[...] = 4
    pop.conn[0, 0, 0, 0, 0] = 3  # start → 3 (processing) → its branch A → 2 (judgment)
    pop.conn[0, 3, 0, 0, 0] = 2
    pop.conn[0, 3, 0, 1, 0] = 4  # a processing node's branch B is never taken
    pop.conn[0, 2, 0, :, 0] = 2  # 2 loops on itself
    pop.conn[0, 4] = 2  # reached only by a credit branch (CS)
    assert structure.reachable(cfg, pop)[0].tolist() == [True, False, True, True, False]
    cs = gnp.GnpConfig(method="CS", n_judgment=2, n_processing=2, n_sub=1)
    pop_cs = gnp.init_population(cs, 1, np.random.default_rng(0))
    for f in ("conn", "credit"):
        getattr(pop_cs, f)[...] = getattr(pop, f)
    assert structure.reachable(cs, pop_cs)[0].tolist() == [True, False, True, True, True]


def test_off_draws_nothing_and_changes_nothing() -> None:
    cfg = gnp.GnpConfig(method="CS", n_judgment=5, n_processing=3)
    pop = _lived(cfg, 6, 1)
    rng = np.random.default_rng(2)
    edited = structure.add_delete_nodes(cfg, pop, 0.0, rng)
    assert rng.random() == np.random.default_rng(2).random()
    assert (edited.added == -1).all() and (edited.deleted == -1).all()
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(edited.population, f), getattr(pop, f))
    with pytest.raises(gnp.GnpError, match=r"p_add_delete must be in 0\.\.1"):
        structure.add_delete_nodes(cfg, pop, 1.5, rng)


def _evolve_digest(evo: gnp.EvolutionConfig) -> str:
    """Three generations of `evolve` for each method, and the Generator's next draws, hashed."""
    h = hashlib.sha256()
    for method in ("RL", "BS", "CS"):
        cfg = gnp.GnpConfig(method=method, n_judgment=7, n_processing=4)
        rng = np.random.default_rng(11)
        pop = gnp.init_population(cfg, 20, rng)
        for g in range(3):
            pop = gnp.evolve(cfg, pop, rng.normal(size=20), g, 3, rng, evo)
        for f in FIELDS:
            h.update(np.ascontiguousarray(getattr(pop, f)).tobytes())
        h.update(rng.random(4).tobytes())
    return h.hexdigest()[:16]


def test_evolve_with_the_setting_off_is_the_evolve_before_it() -> None:
    # d041a87df7cc3a1b: `_evolve_digest` computed by the gnp of 3743908, before the setting
    old = gnp.EvolutionConfig(p_mutation=0.2, p_crossover=0.3)
    assert old.p_add_delete == 0.0
    assert _evolve_digest(old) == "d041a87df7cc3a1b"
    assert _evolve_digest(old.model_copy(update={"p_add_delete": 0.0})) == "d041a87df7cc3a1b"
    on = old.model_copy(update={"p_add_delete": 0.3})
    assert _evolve_digest(on) == _evolve_digest(on) != "d041a87df7cc3a1b"


def test_evolve_edits_the_mutants_only() -> None:
    cfg = gnp.GnpConfig(n_judgment=6, n_processing=3)
    pop = _lived(cfg, 30, 4)
    fitness = np.random.default_rng(5).normal(size=30)
    evo = gnp.EvolutionConfig(p_mutation=0.0, p_crossover=0.0)
    base = gnp.evolve(cfg, pop, fitness, 0, 5, np.random.default_rng(6), evo)
    evo_on = evo.model_copy(update={"p_add_delete": 1.0})
    on = gnp.evolve(cfg, pop, fitness, 0, 5, np.random.default_rng(6), evo_on)
    gnp.check_population(cfg, on)
    first_mutant = sum(evo.split(30)[:2])
    differs = np.array([not np.array_equal(on.records[i], base.records[i]) for i in range(30)])
    assert not differs[:first_mutant].any() and differs[first_mutant:].any()


@pytest.mark.parametrize("bad", [-0.1, 1.5, "often"])
def test_a_bad_setting_is_refused(bad: object) -> None:
    with pytest.raises(ValidationError, match="p_add_delete"):
        gnp.EvolutionConfig(p_add_delete=bad)  # type: ignore[arg-type]
