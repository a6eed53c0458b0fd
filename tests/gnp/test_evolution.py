"""Evolution operators, population helpers and schedules."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import gnp
from gnp.config import JUDGMENT, PROCESSING

configs = st.builds(
    gnp.GnpConfig,
    method=st.sampled_from(["RL", "BS", "CS"]),
    fuzzy=st.booleans(),
    n_judgment=st.integers(1, 10),
    n_processing=st.integers(1, 6),
    n_sub=st.integers(1, 4),
    n_branch=st.integers(1, 3),
)


def arrays_of(pop: gnp.Population) -> dict[str, np.ndarray]:
    return {k: v.copy() for k, v in gnp.population_to_arrays(pop).items()}


def assert_same(pop: gnp.Population, arrays: dict[str, np.ndarray]) -> None:
    for k, v in gnp.population_to_arrays(pop).items():
        np.testing.assert_array_equal(v, arrays[k], err_msg=k)


# --- population -------------------------------------------------------------------------------


def test_init_population_follows_table_2_4() -> None:
    cfg = gnp.GnpConfig()
    pop = gnp.init_population(cfg, 4, np.random.default_rng(0))
    gnp.check_population(cfg, pop)
    assert cfg.n_nodes == 61
    assert pop.conn.shape == (4, 61, 2, 2, 1)  # RL: one branch connection per branch
    assert gnp.GnpConfig(method="BS").n_conn_branches == 2
    judg, proc = cfg.node_type == JUDGMENT, cfg.node_type == PROCESSING
    assert judg.sum() == 40 and proc.sum() == 20 and cfg.node_type[0] == 0
    for p in range(cfg.n_sub):  # 5 judgment nodes per sensor, 10 processing nodes per wheel
        assert np.all(np.apply_along_axis(np.bincount, 1, pop.function[:, judg, p]) == 5)
        assert np.all(np.apply_along_axis(np.bincount, 1, pop.function[:, proc, p]) == 10)
    assert np.all(pop.mu_beta[:, judg] < pop.mu_alpha[:, judg])
    assert not pop.q_ss.any() and not pop.q_bs.any() and not pop.q_cs.any()


def test_arrays_round_trip_and_bad_arrays_are_named() -> None:
    cfg = gnp.GnpConfig(method="CS")
    pop = gnp.init_population(cfg, 3, np.random.default_rng(0))
    pop.q_cs[:] = 0.25
    widened = dict(gnp.population_to_arrays(pop), conn=pop.conn.astype(np.int64))
    back = gnp.population_from_arrays(cfg, widened)  # dtypes are normalised
    assert_same(back, arrays_of(pop))
    good = arrays_of(pop)
    with pytest.raises(gnp.GnpError, match="missing"):
        gnp.population_from_arrays(cfg, {k: v for k, v in good.items() if k != "q_ss"})
    with pytest.raises(gnp.GnpError, match=r"conn.*shape"):
        gnp.population_from_arrays(gnp.GnpConfig(method="BS"), good)
    bad = dict(good, conn=good["conn"].copy())
    bad["conn"][1, 5, 0, 0, 0] = 0
    with pytest.raises(gnp.GnpError, match="conn"):
        gnp.population_from_arrays(cfg, bad)
    bad = dict(good, mu_beta=good["mu_beta"].copy())
    bad["mu_beta"][0, 1, 0] = good["mu_alpha"][0, 1, 0] + 1
    with pytest.raises(gnp.GnpError, match="β"):
        gnp.population_from_arrays(cfg, bad)
    with pytest.raises(gnp.GnpError, match="integers"):
        gnp.population_from_arrays(cfg, dict(good, speed=good["speed"] + 0.5))


@pytest.mark.parametrize(("method", "lines"), [("RL", 1), ("CS", 1), ("BS", 2)])
def test_a_node_is_one_record_of_whole_cache_lines(method: str, lines: int) -> None:
    # m = 2, U = 2 (BS): Q values 2 + 8 + 4 float32 = 56 B, β, α, credit 2 + 2 + 2 and
    # connections 8 int16 = 28 B, functions and speeds 2 + 2 int8 = 4 B: 88 B, two lines.
    # RL, CS (U = 1): 40 + 20 + 4 = 64 B, one line.
    cfg = gnp.GnpConfig(method=method)
    pop = gnp.init_population(cfg, 3, np.random.default_rng(0))
    assert pop.records.shape == (3, cfg.n_nodes)
    assert pop.records.dtype.itemsize == 64 * lines
    assert pop.records.ctypes.data % 64 == 0
    for name in gnp.population_to_arrays(pop):
        assert np.shares_memory(getattr(pop, name), pop.records)
    pop.q_ss[1, 7, 1] = 2.5  # writing a field writes the node's record
    assert pop.records["q_ss"][1, 7, 1] == np.float32(2.5)
    source = gnp.population_to_arrays(pop)
    copied = gnp.Population(**source)  # the constructor copies
    copied.conn[0, 1, 0, 0, 0] = 5 if pop.conn[0, 1, 0, 0, 0] != 5 else 6
    assert copied.conn[0, 1, 0, 0, 0] != pop.conn[0, 1, 0, 0, 0]
    with pytest.raises(gnp.GnpError, match=r"q_bs.*shape"):
        gnp.Population(**dict(source, q_bs=source["q_bs"][:, :, :1]))
    with pytest.raises(gnp.GnpError, match=r"conn.*int16"):
        gnp.Population(**dict(source, conn=source["conn"] + 0.5))


def test_take_and_concat() -> None:
    cfg = gnp.GnpConfig(method="BS")
    pop = gnp.init_population(cfg, 5, np.random.default_rng(0))
    parts = [gnp.take(pop, [3, 4]), gnp.take(pop, [0]), gnp.take(pop, [1, 2])]
    joined = gnp.concat(parts)
    assert_same(joined, arrays_of(gnp.take(pop, [3, 4, 0, 1, 2])))
    with pytest.raises(gnp.GnpError):
        gnp.take(pop, [5])
    with pytest.raises(gnp.GnpError, match="disagree"):
        gnp.concat([pop, gnp.init_population(gnp.GnpConfig(), 1, np.random.default_rng(0))])


# --- evolution --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("n", "split"), [(300, (1, 120, 179)), (10, (1, 4, 5)), (2, (1, 0, 1)), (1, (1, 0, 0))]
)
def test_population_split_scales_table_2_4(n: int, split: tuple[int, int, int]) -> None:
    assert gnp.EvolutionConfig().split(n) == split


def test_evolve_is_pure_and_reproducible_and_keeps_the_elite() -> None:
    cfg = gnp.GnpConfig(method="BS")
    pop = gnp.init_population(cfg, 30, np.random.default_rng(0))
    pop.q_bs[:] = np.random.default_rng(1).normal(size=pop.q_bs.shape)
    fitness = np.random.default_rng(2).uniform(size=30)
    before = arrays_of(pop)
    a = gnp.evolve(cfg, pop, fitness, 3, 10, np.random.default_rng(42))
    b = gnp.evolve(cfg, pop, fitness, 3, 10, np.random.default_rng(42))
    assert_same(pop, before)  # the input is untouched
    assert_same(a, arrays_of(b))
    assert a.size == 30
    gnp.check_population(cfg, a)
    assert_same(gnp.take(a, [0]), arrays_of(gnp.take(pop, [int(np.argmax(fitness))])))
    with pytest.raises(gnp.GnpError, match="fitness"):
        gnp.evolve(cfg, pop, np.full(30, np.nan), 0, 10, np.random.default_rng(0))


def test_tournament_of_everyone_picks_the_best() -> None:
    fitness = np.array([0.1, 0.9, 0.3, 0.5])
    winners = gnp.tournament(fitness, 50, 7, np.random.default_rng(0))
    assert np.all(winners == 1)


def test_crossover_swaps_whole_nodes_with_their_q_values() -> None:
    cfg = gnp.GnpConfig(method="CS")
    rng = np.random.default_rng(0)
    mothers, fathers = gnp.init_population(cfg, 6, rng), gnp.init_population(cfg, 6, rng)
    mothers.q_cs[:] = 1.0
    fathers.q_cs[:] = 2.0
    kids = gnp.crossover(mothers, fathers, 0.5, np.random.default_rng(1))
    assert kids.size == 12
    first, second = gnp.take(kids, range(0, 12, 2)), gnp.take(kids, range(1, 12, 2))
    from_father = first.q_cs[:, :, 0, 0] == 2.0  # (pair, node)
    assert 0 < from_father.mean() < 1
    for f, a in gnp.population_to_arrays(first).items():
        m, d = getattr(mothers, f), getattr(fathers, f)
        mask = from_father.reshape(from_father.shape + (1,) * (a.ndim - 2))
        np.testing.assert_array_equal(a, np.where(mask, d, m), err_msg=f)
        np.testing.assert_array_equal(getattr(second, f), np.where(mask, m, d), err_msg=f)
    assert_same(
        gnp.take(gnp.crossover(mothers, fathers, 0.0, rng), range(0, 12, 2)), arrays_of(mothers)
    )


def test_full_mutation_changes_every_item_and_keeps_bounds() -> None:
    cfg = gnp.GnpConfig(method="CS", n_judgment=16, n_processing=8)
    pop = gnp.init_population(cfg, 10, np.random.default_rng(0))
    pop.q_ss[:] = 3.0
    mutant = gnp.mutate(cfg, pop, 0, 10, np.random.default_rng(1), p_mutation=1.0)
    gnp.check_population(cfg, mutant)
    assert np.all(mutant.conn != pop.conn) and np.all(mutant.credit != pop.credit)
    assert np.all(mutant.function[:, 1:] != pop.function[:, 1:])
    assert np.all(mutant.q_ss == 3.0)  # Q values are inherited
    same = gnp.mutate(cfg, pop, 0, 10, np.random.default_rng(1), p_mutation=0.0)
    assert_same(same, arrays_of(pop))


@settings(max_examples=25, deadline=None)
@given(
    cfg=configs,
    n=st.integers(1, 12),
    seed=st.integers(0, 2**32),
    ops=st.lists(
        st.sampled_from(["evolve", "mutate", "crossover", "learn"]), min_size=1, max_size=5
    ),
)
def test_any_operator_sequence_yields_a_valid_genome(
    cfg: gnp.GnpConfig, n: int, seed: int, ops: list[str]
) -> None:
    rng = np.random.default_rng(seed)
    pop = gnp.init_population(cfg, n, rng)
    for g, op in enumerate(ops):
        if op == "evolve":
            pop = gnp.evolve(
                cfg,
                pop,
                rng.normal(size=n),
                g,
                len(ops),
                rng,
                gnp.EvolutionConfig(p_mutation=0.3, p_crossover=0.5),
            )
        elif op == "mutate":
            pop = gnp.mutate(cfg, pop, g, len(ops), rng, p_mutation=float(rng.uniform()))
        elif op == "crossover":
            partners = gnp.take(pop, rng.permutation(n))
            pop = gnp.take(gnp.crossover(pop, partners, 0.5, rng), range(n))
        else:
            state = gnp.init_state(cfg, n, range(n))
            for _ in range(5):
                gnp.step(
                    cfg, pop, state, rng.uniform(0, 1023, (n, 8)), rng.normal(size=n), 0.2, 0.3
                )
        gnp.check_population(cfg, pop)
        assert pop.size == n


@settings(max_examples=40, deadline=None)
@given(
    value=st.integers(0, 1023),
    bounds=st.tuples(st.integers(0, 1023), st.integers(0, 1023)).map(sorted),
    g=st.tuples(st.integers(0, 100), st.integers(0, 100)).map(sorted),
    seed=st.integers(0, 2**32),
)
def test_nonuniform_mutation_step_shrinks_as_g_approaches_G(value, bounds, g, seed) -> None:
    lo, hi = bounds
    v = np.full(200, min(max(value, lo), hi), dtype=np.int16)
    lower, upper = np.full(200, lo), np.full(200, hi)
    early = gnp.nonuniform_mutation(v, lower, upper, g[0], 100, 2.0, np.random.default_rng(seed))
    late = gnp.nonuniform_mutation(v, lower, upper, g[1], 100, 2.0, np.random.default_rng(seed))
    assert np.all((lo <= early) & (early <= hi)) and np.all((lo <= late) & (late <= hi))
    # Same draws (ζ, r): the step |a' − a| can only shrink as g grows; it vanishes at g = G.
    assert np.all(np.abs(late.astype(int) - v) <= np.abs(early.astype(int) - v))
    final = gnp.nonuniform_mutation(v, lower, upper, 100, 100, 2.0, np.random.default_rng(seed))
    np.testing.assert_array_equal(final, v)


def test_nonuniform_mutation_mean_step_decreases() -> None:
    v = np.full(20000, 500, dtype=np.int16)
    lo, hi = np.zeros(20000), np.full(20000, 1023)
    steps = []
    for g in (0, 50, 90, 100):
        mutated = gnp.nonuniform_mutation(v, lo, hi, g, 100, 2.0, np.random.default_rng(g))
        steps.append(np.abs(mutated.astype(int) - 500).mean())
    # At g = 0, Δ = y(1 − r): mean jump y/2 ≈ 256 (towards 1023 or 0 equally often).
    assert steps[0] == pytest.approx((523 + 500) / 4, rel=0.05)
    assert steps[0] > steps[1] > steps[2] > steps[3] == 0


# --- schedules --------------------------------------------------------------------------------


def test_schedules_over_generations_eq_4_1() -> None:
    eps = gnp.Schedule(max=0.15, min=0.01, n=1.0)
    alpha = gnp.Schedule(max=0.70, min=0.10, n=2.0)
    assert gnp.epsilon_alpha_over_generations(eps, alpha, 0, 100) == pytest.approx((0.15, 0.70))
    assert gnp.epsilon_alpha_over_generations(eps, alpha, 50, 100, "g-over-G") == pytest.approx(
        (0.08, 0.6 * 0.25 + 0.1)
    )
    assert gnp.epsilon_alpha_over_generations(eps, alpha, 100, 100) == pytest.approx((0.01, 0.1))
    assert gnp.schedule_over_generations(gnp.Schedule.fixed(0.1), 37, 100) == 0.1


def test_schedules_after_fault_eq_4_3() -> None:
    eps = gnp.Schedule(max=0.015, min=0.0, n=1.0)
    assert gnp.schedule_after_fault(eps, 100, 500, 3000) == pytest.approx(0.015)  # before t'
    assert gnp.schedule_after_fault(eps, 500, 500, 3000) == pytest.approx(0.015)
    assert gnp.schedule_after_fault(eps, 1750, 500, 3000) == pytest.approx(0.0075)
    assert gnp.schedule_after_fault(eps, 3000, 500, 3000) == pytest.approx(0.0)
    with pytest.raises(gnp.GnpError):
        gnp.schedule_after_fault(eps, 0, 500, 500)
    with pytest.raises(ValueError, match="min"):
        gnp.Schedule(max=0.1, min=0.2)


@pytest.mark.parametrize("method", ["RL", "BS", "CS"])
def test_copies_taken_joined_and_pickled_populations_keep_their_layout(method: str) -> None:
    """Block copies of the records (take, concat, copy, pickling to a worker) give the same
    genes, aligned records whose fields are views, and memory of their own."""
    cfg = gnp.GnpConfig(method=method)
    pop = gnp.init_population(cfg, 6, np.random.default_rng(1))
    pop.q_ss[...] = np.random.default_rng(2).normal(size=pop.q_ss.shape)
    for other in (
        pop.copy(),
        gnp.take(pop, [5, -6, 2]),
        gnp.concat([gnp.take(pop, [0, 1]), gnp.take(pop, [2, 3, 4, 5])]),
        pickle.loads(pickle.dumps(pop)),
    ):
        expected = arrays_of(gnp.take(gnp.Population(**arrays_of(pop)), [5, 0, 2]))
        if other.size == 6:
            expected = arrays_of(pop)
        assert_same(other, expected)
        assert other.records.ctypes.data % 64 == 0
        assert other.records.dtype == pop.records.dtype  # padded to whole cache lines
        assert not np.shares_memory(other.records, pop.records)
        other.q_bs[0, 3] = 7.0  # a field write lands in the records the engine reads
        assert np.all(other.records["q_bs"][0, 3] == 7.0)


# --- fidelity: Eq. 4.1–4.2 progress, the judgment pair {β, α} ----------------------------------


def test_generation_progress_reaches_min_at_the_last_generation() -> None:
    eps = gnp.Schedule(max=0.15, min=0.01, n=1.0)  # Table 4.1, TSRLch
    alpha = gnp.Schedule(max=0.70, min=0.10, n=1.0)
    over = gnp.epsilon_alpha_over_generations
    # Faithful default: g = 0 → max, g = G − 1 → min exactly (G = 1000: 0.15, ..., 0.01).
    assert over(eps, alpha, 0, 1000) == (0.15, 0.70)
    assert over(eps, alpha, 999, 1000) == pytest.approx((0.01, 0.10), abs=1e-15)
    # G = 5: progress g/4 → ε = 0.15 − 0.14·g/4.
    assert [over(eps, alpha, g, 5)[0] for g in range(5)] == pytest.approx(
        [0.15, 0.115, 0.08, 0.045, 0.01]
    )
    # The printed g/G: the last evaluated generation stays 0.14/1000 above min (0.01014).
    assert over(eps, alpha, 999, 1000, "g-over-G")[0] == pytest.approx(0.01 + 0.14 / 1000)
    assert over(eps, alpha, 1000, 1000, "g-over-G") == pytest.approx((0.01, 0.10))
    assert gnp.schedule_over_generations(eps, 3, 5, "g-over-G") == pytest.approx(0.15 - 0.14 * 0.6)
    # G = 1: the only generation uses max in both readings (no division by zero).
    assert over(eps, alpha, 0, 1) == (0.15, 0.70)
    assert over(eps, alpha, 0, 1, "g-over-G") == (0.15, 0.70)
    with pytest.raises(gnp.GnpError):
        gnp.schedule_over_generations(eps, 0, 0)
    with pytest.raises(gnp.GnpError, match="progress"):
        gnp.schedule_over_generations(eps, 0, 10, "bogus")  # type: ignore[arg-type]


def _pairs_changed(judgment_pair: str, seed: int) -> tuple[float, gnp.Population]:
    """Fraction of judgment sub nodes whose (β, α) changed in one mutation of a big population
    (β = 300, α = 700 at g = 0: a selected pair moves, bar a ~1e-6 rounding chance)."""
    from gnp.evolution import mutate

    cfg = gnp.GnpConfig(method="RL", n_sub=2)
    pop = gnp.init_population(cfg, 5000, np.random.default_rng(seed))
    judg = cfg.node_type == JUDGMENT
    pop.mu_alpha[:, judg] = 700
    pop.mu_beta[:, judg] = 300
    mutant = mutate(
        cfg,
        pop,
        0,
        100,
        np.random.default_rng(seed + 1),
        0.01,
        2.0,
        judgment_pair,  # type: ignore[arg-type]
    )
    changed = (mutant.mu_alpha != pop.mu_alpha) | (mutant.mu_beta != pop.mu_beta)
    return float(changed[:, judg].mean()), mutant


def test_joint_judgment_pair_changes_with_p_m_independent_with_about_2_p_m() -> None:
    # 5000 individuals × 40 judgment nodes × 2 sub nodes = 400,000 pairs: sd of the fraction
    # ≈ 0.00016 at P_m = 0.01; the tolerance (0.001) is > 6 sd and the seed is fixed.
    joint, mutant = _pairs_changed("joint", 11)
    assert joint == pytest.approx(0.01, abs=0.001)
    independent, _ = _pairs_changed("independent", 11)
    assert independent == pytest.approx(2 * 0.01 - 0.01**2, abs=0.001)
    assert np.all(mutant.mu_beta <= mutant.mu_alpha)
    # The default is the joint reading, in evolve as in mutate.
    assert gnp.EvolutionConfig().judgment_pair == "joint"


def test_joint_pair_moves_both_values_by_one_fraction_eq_2_4() -> None:
    from gnp.evolution import mutate_judgment_pair

    alpha = np.array([700, 700, 1023, 10], dtype=np.int16)
    beta = np.array([300, 300, 0, 10], dtype=np.int16)
    new_a, new_b = mutate_judgment_pair(alpha, beta, 0, 100, 2.0, np.random.default_rng(5))
    rng = np.random.default_rng(5)  # the same draws, by hand: ζ then r, one each per pair
    zeta, r = rng.integers(0, 2, size=4), rng.random(4)
    s = 1.0 - r  # Δ(0, y) = y(1 − r^1) at g = 0
    a, b = alpha.astype(float), beta.astype(float)
    want_a = np.where(zeta == 0, a + s * (1023 - a), a - s * a)
    want_b = np.where(zeta == 0, b + s * (a - b), b - s * b)
    np.testing.assert_array_equal(new_a, np.rint(want_a))
    np.testing.assert_array_equal(new_b, np.rint(want_b))
    assert new_a.dtype == np.int16 and new_b.dtype == np.int16
    # At g = G there is no step at all (fine tuning ends).
    same_a, same_b = mutate_judgment_pair(alpha, beta, 100, 100, 2.0, np.random.default_rng(5))
    np.testing.assert_array_equal(same_a, alpha)
    np.testing.assert_array_equal(same_b, beta)


@settings(max_examples=60, deadline=None)
@given(
    pair=st.tuples(st.integers(0, 1023), st.integers(0, 1023)).map(sorted),
    g=st.integers(0, 100),
    big_g=st.integers(1, 100),
    b=st.floats(0.1, 5.0),
    seed=st.integers(0, 2**32),
    judgment_pair=st.sampled_from(["joint", "independent"]),
    p_m=st.floats(0.0, 1.0),
)
def test_beta_never_exceeds_alpha_after_mutation(
    pair, g, big_g, b, seed, judgment_pair, p_m
) -> None:
    from gnp.evolution import mutate, mutate_judgment_pair

    beta0, alpha0 = pair
    alpha = np.full(64, alpha0, dtype=np.int16)
    beta = np.full(64, beta0, dtype=np.int16)
    gen = min(g, big_g)
    new_a, new_b = mutate_judgment_pair(alpha, beta, gen, big_g, b, np.random.default_rng(seed))
    assert np.all((new_b >= 0) & (new_b <= new_a) & (new_a <= 1023))
    cfg = gnp.GnpConfig(n_judgment=4, n_processing=2)
    pop = gnp.init_population(cfg, 8, np.random.default_rng(seed))
    pop.mu_alpha[:] = alpha0
    pop.mu_beta[:] = beta0
    mutant = mutate(cfg, pop, gen, big_g, np.random.default_rng(seed), p_m, b, judgment_pair)
    assert np.all(mutant.mu_beta <= mutant.mu_alpha)
    gnp.check_population(cfg, mutant)
