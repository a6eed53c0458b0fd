"""Verdicts that say what the data rule out, over one look or over stages of seeds.

A claim compares two sides (two arms, or one arm in two conditions or on two metrics) on the
difference Δ = mean(a) − mean(b) of its runs' values. Its verdict comes from an interval of Δ:

- `held`: the interval lies on the claimed side of 0 (for an equivalence claim: inside
  ±margin);
- `reversed`: it lies on the other side of 0;
- `ruled out`: it excludes the thesis's effect (the claim's margin: its upper bound in the
  claimed direction lies below the margin; for an equivalence claim: it lies outside ±margin);
- `undecided`: none of these.

Family-wise error over all claims and all stages (Holm with group-sequential boundaries, the
sequentially rejective procedure of Maurer & Bretz 2013): at each look, every claim not yet
decided gets the interval at two-sided level α/r, r the number of claims still holding a share
(all but those held or reversed so far, at any look), widened by the Lan–DeMets O'Brien–Fleming
boundary of that level at the look's information fraction. Claims whose interval decides them
are decided at that level; r drops and the others are looked at again at the new level. Only
`held` and `reversed` free a share (Holm with directional decisions): a claim `ruled out` keeps
its verdict and its share, since with Δ = 0 it is decided rightly about half the time while its
interval still carries its share of wrong `held`/`reversed` verdicts, and handing that share on
lifted the family-wise error of two such claims to 0.061 and of three to 0.070 at α = 0.05
(20000 simulated experiments). A wrong verdict of a claim needs its interval to miss the true
Δ, which its repeated confidence interval (Jennison & Turnbull 1989) allows with probability at
most its level over all looks; with Holm's stepping, the chance of any wrong `held` or
`reversed` over the experiment is at most α whatever the number of claims and looks (under the
normal approximation; the null simulations of tests/app/experiments/test_null_error.py measure
0.02–0.045).
One look (no stages) is plain Holm with two-sided t-intervals. The boundary is on the normal
scale; each look's nominal level is turned into a t-interval (Welch, or paired t) for the runs
at hand. `judge` takes the claims of one family: `report.analyse` passes the primary ones.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import optimize
from scipy import stats as scipy_stats
from statsmodels.stats.power import normal_sample_size_one_tail

from app.experiments.results import Direction, Verdict

ALPHA = 0.05
POWER = 0.8
_GRID = 801  # points of the numerical integration of the boundaries (accurate to ~1e-5)


# --- the group-sequential boundaries ----------------------------------------------------------


def obrien_fleming_spent(t: float, alpha: float) -> float:
    """Lan–DeMets O'Brien–Fleming-type spending: the two-sided α spent by information t."""
    if t <= 0:
        return 0.0
    return float(2 * (1 - scipy_stats.norm.cdf(scipy_stats.norm.ppf(1 - alpha / 2) / math.sqrt(t))))


@lru_cache(maxsize=512)
def boundaries(fractions: tuple[float, ...], alpha: float) -> tuple[float, ...]:
    """Two-sided critical values c_k of |Z_k| at the looks' information fractions t_k.

    Z_k is the standardised statistic of the data up to look k (Brownian motion: corr(Z_i,
    Z_j) = √(t_i / t_j)). c_k makes the chance of first crossing at look k, under Δ = 0, equal
    to the α spent between t_{k−1} and t_k. The crossing chances come from the exact recursion
    over the score's density on a grid (Jennison & Turnbull 2000, ch. 19).

    Args:
        fractions: increasing information fractions in (0, 1]; the last look need not be 1.
        alpha: the two-sided level over all looks (at t = 1).
    """
    t = np.asarray(fractions, dtype=float)
    if t.size == 0 or np.any(np.diff(t) <= 0) or t[0] <= 0 or t[-1] > 1 + 1e-12:
        raise ValueError(f"information fractions must increase within (0, 1]: {fractions}")
    spent = [obrien_fleming_spent(float(x), alpha) for x in t]
    bounds: list[float] = []
    # The score S = Z √t on the continuation region of the looks so far, and its density.
    grid, density = np.zeros(1), np.ones(1)  # before the first look: S = 0 surely
    previous_t = 0.0
    for k, tk in enumerate(t):
        step = math.sqrt(tk - previous_t)
        target = spent[k] - (spent[k - 1] if k else 0.0)

        args = (float(tk), step, target, grid, density)
        c = float(optimize.brentq(_excess, 1e-6, 40.0, args=args, xtol=1e-10))
        bounds.append(c)
        edge = c * math.sqrt(tk)
        new_grid = np.linspace(-edge, edge, _GRID)
        kernel = scipy_stats.norm.pdf((new_grid[:, None] - grid[None, :]) / step) / step
        density = _mass(grid, density[None, :] * kernel, axis=1)
        grid, previous_t = new_grid, float(tk)
    return tuple(bounds)


def _excess(
    c: float, tk: float, step: float, target: float, grid: np.ndarray, density: np.ndarray
) -> float:
    """The chance of first crossing ±c at information tk, less the α this look may spend."""
    return float(_mass(grid, density * _outside(c * math.sqrt(tk), grid, step))) - target


def _outside(edge: float, grid: np.ndarray, step: float) -> np.ndarray:
    """P(|S_next| ≥ edge | S = grid) for a normal increment of sd `step`."""
    return scipy_stats.norm.cdf((-edge - grid) / step) + scipy_stats.norm.sf((edge - grid) / step)


def _mass(grid: np.ndarray, values: np.ndarray, axis: int = -1) -> np.ndarray:
    """∫ values d(grid) by the trapezoid rule; a one-point grid is a point mass."""
    if grid.size == 1:
        return np.take(values, 0, axis=axis)
    return np.trapezoid(values, grid, axis=axis)


def nominal_level(fractions: tuple[float, ...], look: int, alpha: float) -> float:
    """The two-sided nominal level of look `look` (0-based): 2·(1 − Φ(c_look))."""
    c = boundaries(fractions, alpha)[look]
    return float(2 * scipy_stats.norm.sf(c))


@dataclass(frozen=True)
class Design:
    """The looks of an experiment: seeds per arm at each look (the last is the maximum)."""

    looks: tuple[int, ...]

    def __post_init__(self) -> None:
        if not self.looks or any(b <= a for a, b in zip(self.looks, self.looks[1:], strict=False)):
            raise ValueError(f"looks must be increasing seed counts: {self.looks}")

    @classmethod
    def staged(cls, stage_seeds: int, max_seeds: int) -> Design:
        """Stages of `stage_seeds` up to `max_seeds` (the last stage may be smaller)."""
        if stage_seeds < 2 or max_seeds < stage_seeds:
            raise ValueError(
                f"stages need at least 2 seeds each and at most --max-seeds "
                f"({stage_seeds} per stage, {max_seeds} at most)"
            )
        looks = list(range(stage_seeds, max_seeds + 1, stage_seeds))
        if looks[-1] != max_seeds:
            looks.append(max_seeds)
        return cls(tuple(looks))

    @property
    def fractions(self) -> tuple[float, ...]:
        return tuple(n / self.looks[-1] for n in self.looks)


# --- one claim at one look --------------------------------------------------------------------


@dataclass(frozen=True)
class ClaimData:
    """What the verdict of one claim needs: its two sides' per-run values (aligned by seed)."""

    a: np.ndarray
    b: np.ndarray
    direction: Direction
    paired: bool
    margin: float | None  # the thesis's effect (> 0), absolute, in the claim's units


@dataclass(frozen=True)
class Interval:
    difference: float  # mean(a) − mean(b) (paired: mean of the runs' differences)
    low: float
    high: float
    n_a: int
    n_b: int
    sd: float  # pooled sd of the runs (paired: sd of the differences)

    @property
    def tested(self) -> bool:
        return math.isfinite(self.low)


def _finite(a: np.ndarray, b: np.ndarray, paired: bool) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if paired:
        keep = np.isfinite(a) & np.isfinite(b)
        return a[keep], b[keep]
    return a[np.isfinite(a)], b[np.isfinite(b)]


def interval(data: ClaimData, level: float) -> Interval:
    """The two-sided t-interval of Δ at nominal level `level` (Welch, or paired t).

    Fewer than 2 runs on a side gives an untested (NaN) interval; zero variance gives the
    point [Δ, Δ].
    """
    a, b = _finite(data.a, data.b, data.paired)
    nan = math.nan
    if a.size < 2 or b.size < 2:
        diff = float(a.mean() - b.mean()) if a.size and b.size else nan
        return Interval(diff, nan, nan, a.size, b.size, nan)
    if data.paired:
        d = a - b
        diff, sd = float(d.mean()), float(d.std(ddof=1))
        se, df = sd / math.sqrt(d.size), d.size - 1.0
    else:
        va, vb = a.var(ddof=1), b.var(ddof=1)
        diff = float(a.mean() - b.mean())
        sd = math.sqrt(((a.size - 1) * va + (b.size - 1) * vb) / (a.size + b.size - 2))
        wa, wb = va / a.size, vb / b.size
        se = math.sqrt(wa + wb)
        df = (wa + wb) ** 2 / (wa**2 / (a.size - 1) + wb**2 / (b.size - 1)) if se else 1.0
    half = float(scipy_stats.t.ppf(1 - level / 2, df)) * se if se else 0.0
    return Interval(diff, diff - half, diff + half, a.size, b.size, sd)


def decide(iv: Interval, direction: Direction | str, margin: float | None) -> Verdict:
    """The verdict an interval gives (see the module docstring); NaN gives `undecided`."""
    if not iv.tested:
        return "undecided"
    low, high = iv.low, iv.high
    if direction == "equivalent":
        if margin is not None and -margin < low and high < margin:
            return "held"
        if margin is not None and (low > margin or high < -margin):
            return "ruled out"
        return "undecided"
    if direction == "less":  # orient so that "greater" is the claim
        low, high = -high, -low
    if low > 0:
        return "held"
    if high < 0:
        return "reversed"
    if margin is not None and high < margin:
        return "ruled out"
    return "undecided"


# --- every claim over the looks ---------------------------------------------------------------


@dataclass(frozen=True)
class ClaimVerdict:
    verdict: Verdict
    interval: Interval  # at the look and level that decided it (or the last look)
    level: float  # two-sided nominal level of that interval
    look: int  # 0-based look that decided it (or the last look for undecided ones)
    family_level: float  # α / r: the claim's Holm share when it was decided (or at the end)
    # The nominal level of the claim's interval at each look up to `look` (the last one it was
    # judged at, within a look's Holm steps): its stopping boundaries, for estimates.py.
    look_levels: tuple[float, ...] = ()


_FREES: tuple[Verdict, ...] = ("held", "reversed")  # the verdicts that hand their share on


def judge(
    looks: Sequence[Sequence[ClaimData]], design: Design, alpha: float = ALPHA
) -> tuple[ClaimVerdict, ...]:
    """Every claim's verdict over the looks made so far.

    Args:
        looks: per look, every claim's data up to that look (claims in the same order at each
            look; fewer looks than the design has while an experiment is still running).
        design: the planned looks (their information fractions).
        alpha: the family-wise error rate over every claim, direction and look.

    Returns:
        Per claim, its verdict (`undecided` when no look decided it yet).
    """
    if not looks:
        raise ValueError("no look to judge")
    if len(looks) > len(design.looks):
        raise ValueError(f"{len(looks)} looks made, the design plans {len(design.looks)}")
    m = len(looks[0])
    fractions = design.fractions
    decided: dict[int, ClaimVerdict] = {}
    seen: dict[int, list[float]] = {i: [] for i in range(m)}  # per claim, its level per look
    # Claims never testable (a side with fewer than 2 runs at the last look) hold no share.
    testable = {i for i in range(m) if interval(looks[-1][i], alpha).tested}

    def holding() -> int:  # claims that hold a share: all but those held or reversed
        return sum(decided[i].verdict not in _FREES if i in decided else 1 for i in testable)

    for k, claims in enumerate(looks):
        while True:
            open_claims = [i for i in sorted(testable) if i not in decided]
            if not open_claims:
                break
            share = alpha / holding()
            level = nominal_level(fractions[: k + 1], k, share)
            newly = {}
            for i in open_claims:
                seen[i][k:] = [level]
                iv = interval(claims[i], level)
                verdict = decide(iv, claims[i].direction, claims[i].margin)
                if verdict != "undecided":
                    newly[i] = ClaimVerdict(verdict, iv, level, k, share, tuple(seen[i]))
            if not newly:
                break
            decided.update(newly)
    last = len(looks) - 1
    out = []
    share = alpha / max(1, holding())
    level = nominal_level(fractions[: last + 1], last, share)
    for i in range(m):
        if i in decided:
            out.append(decided[i])
        else:
            iv = interval(looks[last][i], level)
            levels = (*seen[i][:last], level) if i in testable else ()
            out.append(ClaimVerdict("undecided", iv, level, last, share, levels))
    return tuple(out)


# --- what an undecided claim would need -------------------------------------------------------


def seeds_for_power(
    sd: float, effect: float, paired: bool, level: float, power: float = POWER
) -> float:
    """Seeds per arm for a two-sided test at `level` to find `effect` with `power` (normal
    approximation, one tail: statsmodels' `normal_sample_size_one_tail` at level/2):
    2·sd²·(z₁₋ₗ/₂ + z_power)²/effect² per arm, without the 2 when paired, rounded up, at
    least 2. inf when the effect is 0; NaN when sd is unknown."""
    if not math.isfinite(sd) or not math.isfinite(effect):
        return math.nan
    if effect == 0:
        return math.inf
    n = (1 if paired else 2) * float(
        normal_sample_size_one_tail(effect, power, level / 2, std_null=sd)
    )
    return float(max(2, math.ceil(n)))
