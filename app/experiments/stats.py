"""Statistics of one experiment's claims: is arm a `direction` than arm b on a scalar metric?

The unit of analysis is the run (seed). Two arms are compared, as the thesis does, as
independent samples: `compare` gives mean ± sd per arm, the difference of means, Welch's
one-tailed t-test and a one-tailed Mann–Whitney U test in the claimed direction, rliable's
probability of improvement and Hedges' g. One arm compared with itself, in two conditions or
on two metrics (`paired=True`), has the same runs on both sides, so the tests are paired by
seed: the one-tailed paired t-test and Wilcoxon's signed-rank test on the runs' differences,
and the share of runs that improve; Hedges' g is still standardised by the runs' spread, so
every row's g reads the same way. An equivalence claim is described as "greater" (its
p-values test both directions anyway). The verdicts, and the interval they rest on, are
`app.experiments.sequential`'s; `holm` adjusts the two-sided p-values of one experiment's
claims as one family, for the reader.

Degenerate input gives a defined outcome, never an exception:

- NaN values (unfinished runs) are dropped; `ArmSummary.dropped` counts them (paired: a run
  missing on either side is dropped from both).
- An arm with fewer than 2 finite values: every p-value, the CI and the effect size are NaN,
  the verdict is `not shown`, and a note says why.
- Both arms constant (zero variance; paired: constant differences): the t statistic is the
  limit of vanishing variance. Equal constants give t = 0 and p = 1 both ways (no evidence);
  different constants give t = ±inf, p = 0 in the direction of the difference and p = 1
  against it. Hedges' g is 0 or ±inf in the same way, and the rank test's p of all-tied values
  (paired: all differences 0) is 1. A note says so.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as scipy_stats
from statsmodels.stats.multitest import multipletests

from app.experiments.results import Direction

_OPPOSITE: dict[Direction, Direction] = {"greater": "less", "less": "greater"}


@dataclass(frozen=True)
class ArmSummary:
    """The finite values of one arm in one claim, summarised."""

    n: int  # finite values (finished runs)
    dropped: int  # NaN values dropped (unfinished runs)
    mean: float  # NaN when n = 0
    sd: float  # sample sd (ddof = 1), NaN when n < 2


@dataclass(frozen=True)
class PairStats:
    """One claim's statistics before the multiplicity correction.

    Every p-value is one-tailed; `p` and `rank_p` test the claimed direction,
    `p_opposite` the other one. `prob_improvement` and `hedges_g` are oriented with the
    claim: above 0.5 and above 0 favour it.
    """

    direction: Direction
    a: ArmSummary
    b: ArmSummary
    difference: float  # mean(a) − mean(b)
    prob_improvement: float
    notes: tuple[str, ...] = ()
    # NaN when an arm has fewer than 2 finite values (no test):
    t: float = math.nan  # t of mean(a) − mean(b), not oriented
    df: float = math.nan  # Welch–Satterthwaite (paired: runs − 1) degrees of freedom
    p: float = math.nan
    p_opposite: float = math.nan
    # Mann–Whitney's U of arm a: pairs with a > b, ties counted ½ (paired: Wilcoxon's W+, the
    # rank sum of the runs whose difference is positive)
    rank_statistic: float = math.nan
    rank_p: float = math.nan
    hedges_g: float = math.nan
    paired: bool = False  # one arm against itself (two conditions or metrics): paired by seed

    @property
    def tests(self) -> tuple[str, str]:
        """The names of the t-test and the rank test used."""
        return ("paired t", "Wilcoxon signed-rank") if self.paired else ("Welch", "Mann–Whitney")


def finite_values(values: np.ndarray) -> tuple[np.ndarray, int]:
    """The finite values of `values` and how many NaN (or ±inf) values were dropped."""
    values = np.asarray(values, dtype=float).ravel()
    kept = values[np.isfinite(values)]
    return kept, values.size - kept.size


def summarise(values: np.ndarray) -> ArmSummary:
    """Mean and sample sd (ddof = 1) of the finite values, with n and the count dropped."""
    kept, dropped = finite_values(values)
    mean = float(kept.mean()) if kept.size else math.nan
    sd = float(kept.std(ddof=1)) if kept.size >= 2 else math.nan
    return ArmSummary(n=int(kept.size), dropped=dropped, mean=mean, sd=sd)


def _zero_variance_limit(difference: float, direction: Direction) -> tuple[float, float]:
    """(t, p) when the variance vanishes: t = ±inf or 0, p = 0 only for a shift the claimed way."""
    t = math.copysign(math.inf, difference) if difference else 0.0
    shown = (t > 0) if direction == "greater" else (t < 0)
    return t, 0.0 if shown else 1.0


def welch_test(a: np.ndarray, b: np.ndarray, direction: Direction) -> tuple[float, float, float]:
    """Welch's one-tailed t-test that mean(a) is `direction` than mean(b).

    Needs at least 2 values per arm. Two constant arms get the zero-variance limit described
    in the module docstring (df is then NaN).

    Returns:
        (t, df, p) with t of mean(a) − mean(b).
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if np.ptp(a) == 0 and np.ptp(b) == 0:
        t, p = _zero_variance_limit(a[0] - b[0], direction)
        return t, math.nan, p
    with warnings.catch_warnings():  # scipy warns of "precision loss" for one constant arm
        warnings.filterwarnings("ignore", "Precision loss", RuntimeWarning)
        result = scipy_stats.ttest_ind(a, b, equal_var=False, alternative=direction)
    return float(result.statistic), float(result.df), float(result.pvalue)


def mann_whitney(a: np.ndarray, b: np.ndarray, direction: Direction) -> tuple[float, float]:
    """One-tailed Mann–Whitney U test that a tends to be `direction` than b.

    scipy's default method: exact for small samples without ties, else the normal
    approximation with tie and continuity corrections. All-tied values give p = 1.

    Returns:
        (U of arm a, p).
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if np.ptp(np.concatenate([a, b])) == 0:
        return a.size * b.size / 2, 1.0
    result = scipy_stats.mannwhitneyu(a, b, alternative=direction)
    return float(result.statistic), float(result.pvalue)


def paired_t_test(d: np.ndarray, direction: Direction) -> tuple[float, float, float]:
    """One-tailed paired t-test that mean(a) is `direction` than mean(b), from the runs'
    differences d = a − b (at least 2). Constant differences take the zero-variance limit.

    Returns:
        (t, df, p) with t of mean(d) and df = runs − 1.
    """
    d = np.asarray(d, dtype=float)
    if np.ptp(d) == 0:
        t, p = _zero_variance_limit(d[0], direction)
        return t, d.size - 1.0, p
    result = scipy_stats.ttest_1samp(d, 0.0, alternative=direction)
    return float(result.statistic), float(result.df), float(result.pvalue)


def wilcoxon_signed_rank(d: np.ndarray, direction: Direction) -> tuple[float, float]:
    """One-tailed Wilcoxon signed-rank test that the runs' differences d = a − b tend to be
    `direction` than 0. Zero differences are dropped (Wilcoxon's own method); all zero gives
    p = 1. scipy's default method: exact for small samples without ties, else normal.

    Returns:
        (W+, the rank sum of the positive differences; p).
    """
    d = np.asarray(d, dtype=float)
    nonzero = d[d != 0]
    if nonzero.size == 0:
        return 0.0, 1.0
    result = scipy_stats.wilcoxon(nonzero, alternative=direction)
    return float(result.statistic), float(result.pvalue)


def share_improved(d: np.ndarray, direction: Direction) -> float:
    """The paired probability of improvement: the share of runs whose difference d = a − b
    favours the claim, ties counted ½."""
    d = np.asarray(d, dtype=float)
    if direction == "less":
        d = -d
    return float(((d > 0).sum() + 0.5 * (d == 0).sum()) / d.size)


def probability_of_improvement(a: np.ndarray, b: np.ndarray, direction: Direction) -> float:
    """rliable's probability of improvement, oriented with the claim.

    P(X_a > X_b) + ½ P(X_a = X_b) over all pairs of one value of each arm for "greater"
    (P(X_a < X_b) + ½ P(X_a = X_b) for "less"), so above 0.5 favours the claim.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if direction == "less":
        a, b = -a, -b
    pairs = a[:, None] - b[None, :]
    return float(((pairs > 0).sum() + 0.5 * (pairs == 0).sum()) / pairs.size)


def hedges_g(a: np.ndarray, b: np.ndarray, direction: Direction) -> float:
    """Hedges' g, oriented with the claim (above 0 favours it).

    Cohen's d with the pooled sd, times the exact small-sample correction
    J(ν) = Γ(ν/2) / (√(ν/2) Γ((ν−1)/2)) with ν = n_a + n_b − 2. Needs at least 2 values per
    arm; a zero pooled sd gives 0 for equal means and ±inf otherwise.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    dof = a.size + b.size - 2
    pooled_var = ((a.size - 1) * a.var(ddof=1) + (b.size - 1) * b.var(ddof=1)) / dof
    difference = a.mean() - b.mean()
    if direction == "less":
        difference = -difference
    if pooled_var == 0:
        return math.copysign(math.inf, difference) if difference else 0.0
    correction = math.exp(math.lgamma(dof / 2) - math.lgamma((dof - 1) / 2)) / math.sqrt(dof / 2)
    return float(correction * difference / math.sqrt(pooled_var))


def compare(
    a_values: np.ndarray,
    b_values: np.ndarray,
    direction: Direction,
    names: tuple[str, str] = ("arm a", "arm b"),
    paired: bool = False,
) -> PairStats:
    """Every descriptive statistic of the claim "a is `direction` than b", one value per run.

    Args:
        a_values: arm a's value of each run; NaN (unfinished runs) are dropped.
        b_values: arm b's value of each run, the same way.
        direction: "greater", "less" or "equivalent" (described as "greater").
        names: the arms' names, for the notes.
        paired: a and b are the same runs (aligned by seed) in two conditions or on two
            metrics: paired tests, and a run missing on either side is dropped from both.

    Returns:
        The claim's statistics, with notes on anything dropped or degenerate.
    """
    if direction == "equivalent":
        direction = "greater"
    if paired:
        a_values, b_values = np.asarray(a_values, dtype=float), np.asarray(b_values, dtype=float)
        if a_values.shape != b_values.shape:
            raise ValueError(f"paired values need one per run on both sides: {names}")
        unpaired = ~(np.isfinite(a_values) & np.isfinite(b_values))
        a_values = np.where(unpaired, np.nan, a_values)
        b_values = np.where(unpaired, np.nan, b_values)
    a, dropped_a = finite_values(a_values)
    b, dropped_b = finite_values(b_values)
    summary_a, summary_b = summarise(a_values), summarise(b_values)
    notes = [
        f"{dropped} unfinished run(s) of {arm} dropped"
        for arm, dropped in zip(names, (dropped_a, dropped_b), strict=True)
        if dropped
    ]
    difference = summary_a.mean - summary_b.mean  # NaN when an arm has no value
    d = a - b if paired else None
    if not (a.size and b.size):
        prob = math.nan
    else:
        prob = (
            share_improved(d, direction)
            if d is not None
            else (probability_of_improvement(a, b, direction))
        )
    if a.size < 2 or b.size < 2:
        notes.append(
            f"fewer than 2 finite values in an arm ({names[0]}: {a.size}, {names[1]}: {b.size}): "
            "no test"
        )
        return PairStats(
            direction, summary_a, summary_b, difference, prob, tuple(notes), paired=paired
        )
    if d is not None:
        if np.ptp(d) == 0:
            notes.append("constant differences: the t-test at its zero-variance limit")
        t, df, p = paired_t_test(d, direction)
        _, _, p_opposite = paired_t_test(d, _OPPOSITE[direction])
        rank_statistic, rank_p = wilcoxon_signed_rank(d, direction)
    else:
        if np.ptp(a) == 0 and np.ptp(b) == 0:
            notes.append("both arms constant: t-test and effect size at their zero-variance limit")
        t, df, p = welch_test(a, b, direction)
        _, _, p_opposite = welch_test(a, b, _OPPOSITE[direction])
        rank_statistic, rank_p = mann_whitney(a, b, direction)
    return PairStats(
        direction=direction,
        a=summary_a,
        b=summary_b,
        difference=difference,
        t=t,
        df=df,
        p=p,
        p_opposite=p_opposite,
        rank_statistic=rank_statistic,
        rank_p=rank_p,
        prob_improvement=prob,
        hedges_g=hedges_g(a, b, direction),
        notes=tuple(notes),
        paired=paired,
    )


def holm(p_values: Sequence[float]) -> np.ndarray:
    """Holm–Bonferroni adjusted p-values, in the order given (statsmodels' `multipletests`).

    Step-down: the i-th smallest of m p-values is multiplied by m − i + 1 (i from 1), then
    made monotone by a running maximum in rank order and capped at 1. NaN p-values (claims
    not tested) stay NaN and do not count in m.
    """
    p = np.asarray(p_values, dtype=float)
    adjusted = np.full(p.shape, np.nan)
    tested = ~np.isnan(p)
    if tested.any():
        adjusted[tested] = multipletests(p[tested], method="holm")[1]
    return adjusted
