"""Descriptive statistics of an experiment's claims, checked against hand-computed values.

The verdicts (intervals, Holm, looks) are tested in test_sequential.py; here `decide` and
`interval` only check that the claims these statistics describe get the verdict they should.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from app.experiments.results import VERDICTS, Direction
from app.experiments.sequential import ClaimData, Design, decide, interval, judge
from app.experiments.stats import (
    compare,
    hedges_g,
    holm,
    mann_whitney,
    paired_t_test,
    probability_of_improvement,
    share_improved,
    summarise,
    welch_test,
    wilcoxon_signed_rank,
)

A = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
B = np.array([0.0, 1.0, 2.0, 3.0, 4.0])


def one_verdict(
    a: np.ndarray, b: np.ndarray, direction: Direction = "greater", paired: bool = False
) -> str:
    """The verdict of a lone claim at one look (α = 0.05, no margin)."""
    data = ClaimData(np.asarray(a, float), np.asarray(b, float), direction, paired, None)
    (claim,) = judge([[data]], Design((max(len(a), len(b)),)))
    return claim.verdict


def welch_t_and_df(a: list[float], b: list[float]) -> tuple[float, float]:
    """Welch's t and Welch–Satterthwaite df from their textbook formulas."""
    na, nb = len(a), len(b)
    ma, mb = sum(a) / na, sum(b) / nb
    va = sum((x - ma) ** 2 for x in a) / (na - 1)
    vb = sum((x - mb) ** 2 for x in b) / (nb - 1)
    sa, sb = va / na, vb / nb
    t = (ma - mb) / math.sqrt(sa + sb)
    df = (sa + sb) ** 2 / (sa**2 / (na - 1) + sb**2 / (nb - 1))
    return t, df


def student_t_cdf_even_df(t: float, df: int) -> float:
    """Student's t CDF for an even df, from its closed-form finite series."""
    cos2 = df / (df + t * t)
    series = sum(
        math.factorial(2 * k) / (4**k * math.factorial(k) ** 2) * cos2**k for k in range(df // 2)
    )
    return 0.5 + t / (2 * math.sqrt(df + t * t)) * series


def test_welch_matches_the_hand_formulas() -> None:
    t_hand, df_hand = welch_t_and_df(list(A), list(B))
    assert t_hand == pytest.approx(1.0) and df_hand == pytest.approx(8.0)  # both variances 2.5
    p_hand = 1 - student_t_cdf_even_df(1.0, 8)  # ≈ 0.1733
    t, df, p = welch_test(A, B, "greater")
    assert (t, df, p) == (pytest.approx(t_hand), pytest.approx(df_hand), pytest.approx(p_hand))
    _, _, p_less = welch_test(A, B, "less")
    assert p_less == pytest.approx(1 - p_hand)


def test_welch_unequal_variances_uses_the_satterthwaite_df() -> None:
    a, b = [2.0, 4.0, 6.0, 8.0], [1.0, 2.0, 3.0]
    t_hand, df_hand = welch_t_and_df(a, b)
    t, df, _ = welch_test(np.array(a), np.array(b), "greater")
    assert t == pytest.approx(t_hand) and df == pytest.approx(df_hand)
    assert df < len(a) + len(b) - 2  # Welch's df falls below the pooled df


def test_mann_whitney_exact_p_by_counting_splits() -> None:
    a, b = [3.0, 5.0, 6.0], [1.0, 2.0, 4.0]
    u_hand = sum(x > y for x in a for y in b)  # 2 + 3 + 3 = 8
    pooled = a + b
    splits = list(itertools.combinations(range(6), 3))
    us = [
        sum(pooled[i] > pooled[j] for i in chosen for j in range(6) if j not in chosen)
        for chosen in splits
    ]
    u, p = mann_whitney(np.array(a), np.array(b), "greater")
    assert u == u_hand == 8
    assert p == pytest.approx(sum(x >= u_hand for x in us) / len(splits))  # 2/20
    _, p_less = mann_whitney(np.array(a), np.array(b), "less")
    assert p_less == pytest.approx(sum(x <= u_hand for x in us) / len(splits))  # 19/20


def test_probability_of_improvement_counts_pairs() -> None:
    a, b = [1.0, 2.0, 3.0], [0.0, 1.0, 2.0]
    wins = sum(x > y for x in a for y in b)  # 6
    ties = sum(x == y for x in a for y in b)  # 2
    greater = probability_of_improvement(np.array(a), np.array(b), "greater")
    assert greater == pytest.approx((wins + ties / 2) / 9)  # 7/9
    less = probability_of_improvement(np.array(a), np.array(b), "less")
    assert less == pytest.approx((sum(x < y for x in a for y in b) + ties / 2) / 9)  # 2/9


def test_hedges_g_by_hand() -> None:
    pooled_sd = math.sqrt(2.5)
    correction = math.gamma(4) / (math.sqrt(4) * math.gamma(3.5))  # ν = 8
    expected = correction * 1.0 / pooled_sd  # ≈ 0.571
    assert hedges_g(A, B, "greater") == pytest.approx(expected)
    assert hedges_g(A, B, "less") == pytest.approx(-expected)


def test_holm_by_hand() -> None:
    # sorted: 0.01·4 = 0.04, 0.03·3 = 0.09, 0.04·2 = 0.08 → 0.09 (monotone), 0.20·1 = 0.20
    assert holm([0.01, 0.04, 0.03, 0.20]) == pytest.approx([0.04, 0.09, 0.09, 0.20])
    assert holm([0.3, 0.4]) == pytest.approx([0.6, 0.6])  # 0.6, then max(0.6, 0.4)
    assert holm([0.5, 0.9, 0.7]) == pytest.approx([1.0, 1.0, 1.0])  # capped at 1


def test_holm_leaves_untested_claims_out_of_the_family() -> None:
    adjusted = holm([0.01, math.nan, 0.04])
    assert adjusted[0] == pytest.approx(0.02) and adjusted[2] == pytest.approx(0.04)
    assert math.isnan(adjusted[1])


@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=12))
def test_holm_is_at_least_raw_capped_and_monotone_in_rank(p: list[float]) -> None:
    adjusted = holm(p)
    raw = np.asarray(p)
    assert np.all(adjusted >= raw) and np.all(adjusted <= 1.0)
    in_rank_order = adjusted[np.argsort(raw, kind="stable")]
    assert np.all(np.diff(in_rank_order) >= 0)


values = st.lists(st.integers(-5, 5).map(float), min_size=1, max_size=8).map(np.array)


@given(values, values)
def test_probability_of_improvement_of_both_orders_sums_to_one(a: np.ndarray, b: np.ndarray):
    ab = probability_of_improvement(a, b, "greater")
    assert ab + probability_of_improvement(b, a, "greater") == pytest.approx(1.0)
    assert ab + probability_of_improvement(a, b, "less") == pytest.approx(1.0)


@given(values, values)
def test_compare_never_fails_and_its_p_values_are_probabilities(a: np.ndarray, b: np.ndarray):
    stats = compare(a, b, "greater")
    assert one_verdict(a, b) in VERDICTS
    tested = a.size >= 2 and b.size >= 2
    for p in (stats.p, stats.p_opposite, stats.rank_p):
        assert (0.0 <= p <= 1.0) if tested else math.isnan(p)
    assert 0.0 <= stats.prob_improvement <= 1.0


def test_a_clear_effect_the_other_way_is_reversed() -> None:
    stats = compare(B - 10.0, B, "greater")
    assert one_verdict(B - 10.0, B) == "reversed"
    assert stats.prob_improvement == 0.0 and stats.hedges_g < 0
    assert stats.p + stats.p_opposite == pytest.approx(1.0) and stats.p_opposite < 1e-4


def test_a_clear_effect_in_the_claimed_direction_is_held() -> None:
    assert compare(B, B + 10.0, "less").prob_improvement == 1.0
    assert one_verdict(B, B + 10.0, "less") == "held"


def test_a_weak_effect_is_undecided_and_its_two_sided_p_says_why() -> None:
    stats = compare(A + 0.5, B, "greater")  # t = 1.5 / √1 = 1.5, df 8
    assert stats.t == pytest.approx(1.5) and stats.p == pytest.approx(
        1 - student_t_cdf_even_df(1.5, 8)
    )
    assert 0.05 < stats.p < 0.1  # ≈ 0.086: not below α/2 = 0.025 of the two-sided interval
    assert one_verdict(A + 0.5, B) == "undecided"


def test_an_equivalence_claim_is_described_as_greater() -> None:
    assert compare(A, B, "equivalent") == compare(A, B, "greater")


def test_unfinished_runs_are_dropped_and_counted() -> None:
    summary = summarise(np.array([1.0, 2.0, 3.0, math.nan]))
    assert (summary.n, summary.dropped, summary.mean, summary.sd) == (3, 1, 2.0, 1.0)
    stats = compare(np.array([1.0, 2.0, 3.0, math.nan]), B, "greater")
    assert stats.a.dropped == 1 and stats.b.dropped == 0
    assert any("1 unfinished run(s) of arm a" in note for note in stats.notes)
    assert math.isfinite(stats.p)


def test_an_arm_with_one_finite_value_is_not_tested() -> None:
    a = np.array([1.0, math.nan, math.nan])
    stats = compare(a, B, "greater")
    assert one_verdict(a, B) == "undecided"
    assert stats.a.n == 1 and stats.a.dropped == 2 and math.isnan(stats.a.sd)
    assert all(math.isnan(p) for p in (stats.p, stats.rank_p))
    assert math.isnan(stats.hedges_g)
    assert not interval(ClaimData(a, B, "greater", False, None), 0.05).tested
    assert stats.difference == pytest.approx(1.0 - 2.0)
    assert any("fewer than 2" in note for note in stats.notes)


def test_identical_constant_arms_show_nothing_without_nan() -> None:
    same = np.full(4, 3.0)
    stats = compare(same, same, "greater")
    assert (stats.t, stats.p, stats.p_opposite) == (0.0, 1.0, 1.0)
    assert (stats.rank_p, stats.prob_improvement, stats.hedges_g) == (1.0, 0.5, 0.0)
    iv = interval(ClaimData(same, same, "greater", False, None), 0.05)
    assert (iv.low, iv.high) == (0.0, 0.0)  # the zero-variance point interval
    assert one_verdict(same, same) == "undecided"
    assert decide(iv, "greater", 0.01) == "ruled out"  # no spread: any margin is excluded
    assert any("constant" in note for note in stats.notes)


def test_different_constant_arms_take_the_zero_variance_limit() -> None:
    a, b = np.full(4, 2.0), np.full(3, 1.0)
    stats = compare(a, b, "greater")
    assert stats.t == math.inf and (stats.p, stats.p_opposite) == (0.0, 1.0)
    iv = interval(ClaimData(a, b, "greater", False, None), 0.05)
    assert stats.hedges_g == math.inf and (iv.low, iv.high) == (1.0, 1.0)
    assert one_verdict(a, b) == "held"


# --- one arm in two conditions: paired by seed ---


def test_paired_t_matches_the_hand_formula() -> None:
    d = np.array([0.5, 1.0, 0.5, 1.0, 1.0])  # A − B2 below
    mean = sum(d) / 5
    sd = math.sqrt(sum((x - mean) ** 2 for x in d) / 4)
    t_hand = mean / (sd / math.sqrt(5))
    t, df, p = paired_t_test(d, "greater")
    assert (t, df) == (pytest.approx(t_hand), 4.0)
    assert p == pytest.approx(1 - student_t_cdf_even_df(t_hand, 4))
    assert paired_t_test(d, "less")[2] == pytest.approx(student_t_cdf_even_df(t_hand, 4))


def test_wilcoxon_exact_p_by_counting_sign_flips() -> None:
    d = np.array([1.0, 2.0, 3.0, -0.5, 4.0])  # |d| ranks 2, 3, 4, 1, 5: W+ = 14
    w, p = wilcoxon_signed_rank(d, "greater")
    flips = [
        sum(r for r, s in zip(range(1, 6), signs, strict=True) if s)
        for signs in itertools.product((0, 1), repeat=5)
    ]  # W+ of every sign pattern, equally likely
    assert w == 14.0 and p == pytest.approx(sum(x >= 14 for x in flips) / 32)  # 2/32
    assert wilcoxon_signed_rank(np.zeros(4), "greater") == (0.0, 1.0)


def test_share_improved_counts_runs_and_half_ties() -> None:
    d = np.array([1.0, 0.0, -1.0, 2.0])
    assert share_improved(d, "greater") == 0.625 and share_improved(d, "less") == 0.375


def test_pairing_finds_a_small_shift_the_spread_between_runs_hides() -> None:
    b = np.array([0.0, 10.0, 20.0, 30.0, 40.0, 50.0])  # runs differ a lot
    a = b + np.array([1.0, 1.1, 0.9, 1.0, 1.2, 0.8])  # each run gains about 1
    paired, unpaired = (compare(a, b, "greater", paired=p) for p in (True, False))
    assert paired.paired and paired.tests == ("paired t", "Wilcoxon signed-rank")
    assert unpaired.tests == ("Welch", "Mann–Whitney")
    assert paired.p < 1e-5 < 0.4 < unpaired.p
    assert paired.prob_improvement == 1.0 and paired.difference == pytest.approx(1.0)
    assert paired.hedges_g == unpaired.hedges_g  # g reads the same way in both
    # d: sd √0.02, se √0.02/√6 ≈ 0.0577, t(0.975, 5) ≈ 2.571: [0.852, 1.148]
    iv = interval(ClaimData(a, b, "greater", True, None), 0.05)
    assert 0.85 < iv.low < 1.0 < iv.high < 1.15
    assert one_verdict(a, b, paired=True) == "held" != one_verdict(a, b)
    assert (paired.t, paired.df) == paired_t_test(a - b, "greater")[:2]


def test_a_run_missing_on_either_side_is_dropped_from_both() -> None:
    a = np.array([1.0, math.nan, 3.0, 4.0])
    b = np.array([0.0, 1.0, math.nan, 2.0])
    stats = compare(a, b, "greater", paired=True)
    assert (stats.a.n, stats.b.n, stats.a.dropped, stats.b.dropped) == (2, 2, 2, 2)
    assert stats.difference == pytest.approx(1.5) and stats.df == 1.0
    with pytest.raises(ValueError, match="one per run"):
        compare(a, b[:3], "greater", paired=True)


def test_constant_differences_take_the_zero_variance_limit() -> None:
    stats = compare(A + 2.0, A, "greater", paired=True)
    assert (stats.t, stats.p, stats.p_opposite) == (math.inf, 0.0, 1.0)
    iv = interval(ClaimData(A + 2.0, A, "greater", True, None), 0.05)
    assert (iv.low, iv.high, iv.sd) == (2.0, 2.0, 0.0)
    assert any("constant differences" in note for note in stats.notes)
    same = compare(A, A, "greater", paired=True)
    assert (same.t, same.p, same.rank_p, same.prob_improvement) == (0.0, 1.0, 1.0, 0.5)


paired_values = st.lists(
    st.tuples(st.integers(-5, 5).map(float), st.integers(-5, 5).map(float)), min_size=1, max_size=8
)


@given(paired_values)
def test_paired_compare_never_fails_and_its_p_values_are_probabilities(
    pairs: list[tuple[float, float]],
) -> None:
    a, b = (np.array(side) for side in zip(*pairs, strict=True))
    stats = compare(a, b, "greater", paired=True)
    assert one_verdict(a, b, paired=True) in VERDICTS
    for p in (stats.p, stats.p_opposite, stats.rank_p):
        assert (0.0 <= p <= 1.0) if len(pairs) >= 2 else math.isnan(p)
    assert 0.0 <= stats.prob_improvement <= 1.0
