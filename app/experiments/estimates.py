"""Estimates beside a verdict: corrected for stopping, on all the data, and relative to the
no-fault level.

**Corrected for stopping.** A claim judged over looks stops at the first look whose interval
decides it, so the difference at that look (Δ̂ₖ) is biased away from zero: among the
experiments that could have gone on, those whose early data happened to show a large Δ stop
first. The *median-unbiased estimate* under the stagewise ordering of the sample space
(Jennison & Turnbull 2000, §8.4; Emerson & Fleming 1990) removes that: outcomes are ordered by
the look they stop at (stopping earlier across the upper boundary is more extreme than any
later outcome, earlier across the lower one less extreme), then by Δ̂ within a look; the
estimate is the Δ under which the observed outcome is the median, P_Δ(outcome ≥ observed) = ½.
That probability depends only on the boundaries of the looks up to the stopping one, so a look
never made does not matter, and at the first look the estimate is Δ̂ itself. With
O'Brien–Fleming boundaries the first looks' are so wide that stopping there is rare, and the
stagewise estimate moves Δ̂ little. Given that the claim stopped at the look it did, Δ̂ is
biased more (conditional bias); the *conditional* median-unbiased estimate (Troendle & Yu 1999;
Fan, DeMets & Lan 2004) is the Δ under which Δ̂ is the median of its distribution given that
stop, the look's stopping region. Both are reported; the conditional one varies more.

The boundaries are the claim's own, as `sequential.judge` applied them: at each look the
two-sided level of its interval (its Holm share then; `ClaimVerdict.look_levels`) turned into
the t-quantile of its runs, on the scale of Z = Δ̂/se. For a claim that Δ > 0 the upper region
is `held` (Z ≥ c) and the lower one `reversed` or `ruled out` (Z ≤ m − c, m = margin/se, or
Z ≤ −c without a margin); for Δ < 0 mirrored. The standard errors of the looks come from the
stopping look's variances and each look's runs; the score S = Δ̂·I (I = 1/se²) is a Brownian
motion with drift Δ in information time, whose sub-densities over the looks' continuation
regions come from the same recursive integration as the boundaries (`sequential.boundaries`),
once under Δ = 0 and then for any Δ by the likelihood ratio exp(ΔS − Δ²I/2).

**On all the data.** A design runs on for its other claims after one is decided; the claim's Δ
on every seed that both its sides ran is shown beside it where there are more such seeds than
at its stopping look (descriptive: it is not what stopped).

**Relative to the no-fault level.** A fault's cost (`fault_effect`) read against each arm's own
no-fault reward over the same steps (`relative_fault_effect`); where a report's values predate
that metric, it is derived from the same runs' values: the control's reward over the fault's
steps is the condition's reward after the fault less its fault effect.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize, special
from scipy import stats as scipy_stats

from app.experiments.results import Comparison, ExperimentResults
from app.experiments.sequential import (
    _GRID,
    ClaimData,
    ClaimVerdict,
    Interval,
    _finite,
    _mass,
    interval,
)

__all__ = [
    "Stopping",
    "all_data",
    "median_unbiased",
    "relative_reading",
    "stopping",
]


@dataclass(frozen=True)
class Stopping:
    """A sequentially judged claim's Δ at its stopping look and that Δ corrected for stopping."""

    at_look: float  # Δ̂ at the look that decided it (or its last look)
    median_unbiased: float  # the stagewise median-unbiased estimate
    conditional: float  # median-unbiased given the look it stopped at
    look: int  # 0-based stopping look
    stopped: bool  # decided at that look (False: at the design's last look, undecided)


def median_unbiased(
    estimate: float,
    se: Sequence[float],
    lower: Sequence[float],
    upper: Sequence[float],
    grid: int = _GRID,
) -> tuple[float, float]:
    """The median-unbiased estimates of Δ: under the stagewise ordering, and given the look.

    Args:
        estimate: Δ̂ at the stopping look K (the last of `se`).
        se: the standard error of Δ̂ at looks 0..K (decreasing).
        lower, upper: the Z = Δ̂/se bounds of the continuation region at looks 0..K−1 (the
            claim stopped below `lower` or above `upper`; it went on between them), and at K
            its stopping region for the conditional estimate (none: K is the design's last
            look, where every outcome stops).
        grid: points of the numerical integration per look.

    Returns:
        (stagewise, conditional): the Δ under which the observed outcome is the median of the
        stagewise ordering, and of Δ̂'s distribution given that the claim stops at look K.
    """
    info = 1.0 / np.asarray(se, dtype=float) ** 2
    stop = len(info) - 1
    if stop < 0 or len(lower) < stop or len(upper) < stop or np.any(np.diff(info) <= 0):
        raise ValueError("need increasing information up to the stopping look and its bounds")
    observed = estimate * info[stop]
    # Under Δ = 0: the score's sub-density over each continuation region.
    grids: list[np.ndarray] = []
    densities: list[np.ndarray] = []
    for k in range(stop):
        sd = math.sqrt(info[k])
        if not lower[k] < upper[k]:
            raise ValueError(f"look {k + 1}: no continuation region, yet the claim went on")
        points = np.linspace(lower[k] * sd, upper[k] * sd, grid)
        if k == 0:
            density = np.exp(-0.5 * (points / sd) ** 2) / (math.sqrt(2 * math.pi) * sd)
        else:
            step = math.sqrt(info[k] - info[k - 1])
            x = (points[:, None] - grids[-1][None, :]) / step
            kernel = np.exp(-0.5 * x * x) / (math.sqrt(2 * math.pi) * step)
            density = _mass(grids[-1], densities[-1][None, :] * kernel, axis=1)
        grids.append(points)
        densities.append(density)

    def beyond(k: int, edge: float, delta: float) -> float:
        """P_Δ(the claim reaches look k and its score there is at least `edge`)."""
        if k == 0:
            return float(special.ndtr((delta * info[0] - edge) / math.sqrt(info[0])))
        step = math.sqrt(info[k] - info[k - 1])
        s = grids[k - 1]
        # The sub-density under Δ, density × likelihood ratio, in logs: far out a density that
        # underflowed to 0 meets a ratio that overflows, and 0 × inf would be NaN.
        with np.errstate(divide="ignore"):
            log_density = np.log(densities[k - 1])
        exponent = np.minimum(log_density + delta * s - delta**2 * info[k - 1] / 2, 700.0)
        reach = special.ndtr((s + delta * (info[k] - info[k - 1]) - edge) / step)
        return float(_mass(s, np.exp(exponent) * reach))

    def stagewise(delta: float) -> float:
        """P_Δ(an outcome at least as high as the observed one, stagewise) − ½."""
        earlier = sum(beyond(k, upper[k] * math.sqrt(info[k]), delta) for k in range(stop))
        return earlier + beyond(stop, observed, delta) - 0.5

    def given_the_look(delta: float) -> float:
        """P_Δ(a score at least the observed one | the claim stops at look K) − ½."""
        if len(lower) <= stop or lower[stop] >= upper[stop]:  # every outcome stops there
            return beyond(stop, observed, delta) / beyond(stop, -math.inf, delta) - 0.5
        low, high = lower[stop] * math.sqrt(info[stop]), upper[stop] * math.sqrt(info[stop])
        at_low = beyond(stop, low, delta)
        stops = beyond(stop, high, delta) + beyond(stop, -math.inf, delta) - at_low
        above = beyond(stop, max(observed, high), delta)
        if observed < low:
            above += beyond(stop, observed, delta) - at_low
        return above / stops - 0.5

    width = 1.0 / math.sqrt(info[stop])

    def root(tail: Callable[[float], float]) -> float:
        low, high = estimate - 4 * width, estimate + 4 * width
        for _ in range(20):  # widen until the root is bracketed (the tail increases with Δ)
            if tail(low) < 0 < tail(high):
                break
            low, high = low - 4 * width, high + 4 * width
        return float(optimize.brentq(tail, low, high, xtol=1e-10 * width))

    return root(stagewise), root(given_the_look)


def _bounds(direction: str, z: float, margin: float | None, se: float) -> tuple[float, float]:
    """(lower, upper) Z bounds of a claim's continuation region at one look, from the
    critical value z of its interval there (see the module docstring)."""
    m = margin / se if margin is not None else None
    if direction == "less":
        return -z, (z - m if m is not None else z)
    return (m - z if m is not None else -z), z


def stopping(
    looks: Sequence[ClaimData], judged: ClaimVerdict, last_planned: bool
) -> Stopping | None:
    """A sequentially judged claim's stopping-corrected estimate; None for an equivalence
    claim, one without levels or runs, or one still open at a look that is not the design's
    last (it has not stopped)."""
    if judged.verdict == "exploratory" or len(looks) < 1 or not judged.look_levels:
        return None
    k_stop = judged.look
    data = looks[k_stop]
    if data.direction == "equivalent" or not judged.interval.tested:
        return None
    stopped = judged.verdict != "undecided"
    if not stopped and not last_planned:
        return None
    a, b = _finite(data.a, data.b, data.paired)
    va = float(np.var(a - b if data.paired else a, ddof=1))
    vb = 0.0 if data.paired else float(np.var(b, ddof=1))
    if not va + vb > 0:  # no spread: the interval is a point, nothing to correct
        return None
    # At the design's last look every outcome stops: the conditional estimate is given that
    # the claim reached it; at an earlier look, given that it stopped there.
    final = last_planned and k_stop == len(looks) - 1
    se, lower, upper = [], [], []
    for k in range(k_stop + 1):
        ak, bk = _finite(looks[k].a, looks[k].b, data.paired)
        if ak.size < 2 or bk.size < 2:
            return None  # a look without a test: no region to integrate over
        wa, wb = va / ak.size, vb / bk.size
        se_k = math.sqrt(wa + wb)
        df = (
            ak.size - 1.0
            if data.paired
            else (wa + wb) ** 2 / (wa**2 / (ak.size - 1) + wb**2 / (bk.size - 1))
        )
        z = float(scipy_stats.t.isf(judged.look_levels[k] / 2, df))
        se.append(se_k)
        if k < k_stop or not final:
            low, high = _bounds(data.direction, z, looks[k].margin, se_k)
            lower.append(low)
            upper.append(high)
    if not all(x > 0 for x in se) or any(y <= x for x, y in zip(se[1:], se, strict=False)):
        return None
    estimate = judged.interval.difference
    try:
        corrected, given = median_unbiased(estimate, se, lower, upper)
    except ValueError:  # no root in reach (e.g. a handful of runs, degenerate bounds)
        return None  # the report shows no corrected estimate rather than a wrong one
    return Stopping(estimate, corrected, given, k_stop, stopped)


def all_data(a: np.ndarray, b: np.ndarray, used: tuple[int, int]) -> tuple[float, int] | None:
    """(Δ, seeds) on every seed both sides ran, where that is more seeds than the claim's
    deciding look used (`used`: its runs on each side); None otherwise."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    both = np.isfinite(a) & np.isfinite(b)
    n = int(both.sum())
    if n < 2 or n <= min(used):
        return None
    return float(a[both].mean() - b[both].mean()), n


def _relative(results: ExperimentResults, arm: str, condition: str) -> np.ndarray | None:
    """relative_fault_effect of an arm in a condition: recorded, or derived from its
    fault_effect and reward after the fault (the control's level is their difference)."""
    recorded = results.scalars.get(("relative_fault_effect", arm, condition))
    if recorded is not None and np.isfinite(recorded).any():
        return np.asarray(recorded, dtype=float)
    effect = results.scalars.get(("fault_effect", arm, condition))
    after = results.scalars.get(("mean_reward_after_fault", arm, condition))
    if effect is None or after is None:
        return None
    level = np.asarray(after, dtype=float) - np.asarray(effect, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(level > 0, np.asarray(effect, dtype=float) / level, np.nan)


def relative_reading(results: ExperimentResults, c: Comparison, alpha: float) -> Interval | None:
    """A fault-effect claim read against each side's own no-fault level: the same sides on
    relative_fault_effect, every judged seed, an unadjusted (1 − α) interval (exploratory).
    None for a claim on another metric."""
    if c.metric != "fault_effect" or (c.metric_b or c.metric) != "fault_effect":
        return None
    a = _relative(results, c.a, c.condition or "")
    b = _relative(results, c.b, c.condition_b or c.condition or "")
    if a is None or b is None:
        return None
    iv = interval(ClaimData(a, b, c.direction, c.paired, None), alpha)
    return iv if math.isfinite(iv.difference) else None
