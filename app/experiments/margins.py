"""What a "ruled out" rules out: one rule for every claim's margin (issue #30).

A claim is `ruled out` when its interval excludes an effect. Which effect:

- **The thesis's own**, where it prints the values of both sides (the experiment's `[[thesis]]`
  numbers of a's and b's metric and condition): Δ_t = a_t − b_t, read two ways, absolute (Δ_t in
  the metric's units) and relative to the baseline (Δ_t / b_t times our mean of b). The claim is
  ruled out only if its interval excludes both readings, so the margin is the smaller of them;
  a reading that no run could reach (our b plus it leaves the metric's range) is dropped, and
  with none left nothing is ruled out. Where the printed values point against the claim, the
  thesis has no effect in the claimed direction to rule out: nothing is.
- **Else the spec's declared margin**, absolute or relative to our b (the smallest effect of
  interest where the thesis prints no number), also dropped where no run could reach it.

Equivalence claims keep their declared margin (the band), which is not the thesis's effect.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from app.experiments.results import Comparison, Metric, ThesisValue

MarginBasis = Literal["thesis", "declared", "none"]


@dataclass(frozen=True)
class Margin:
    """The effect a claim's `ruled out` excludes, in the metric's units (None: nothing)."""

    value: float | None
    basis: MarginBasis  # the thesis's printed values, the spec's declared margin, or none
    text: str  # how it was reached, for the page


def reachable(metric: Metric, mean_b: float, effect: float, direction: str) -> bool:
    """Whether a run could show `effect` (> 0) in `direction` from our baseline `mean_b`."""
    low, high = metric.bounds
    target = mean_b + effect if direction != "less" else mean_b - effect
    return low <= target <= high


def _thesis_margin(
    c: Comparison, metric: Metric, a: ThesisValue, b: ThesisValue, mean_b: float
) -> Margin:
    delta = a.value - b.value
    printed = f"{a.source}: {a.value:g} against {b.value:g}"
    claimed_way = delta > 0 if c.direction == "greater" else delta < 0
    if not claimed_way:
        return Margin(None, "none", f"{printed}, the other way: no thesis effect to rule out")
    readings = {"absolute": abs(delta)}
    if b.value != 0 and math.isfinite(mean_b):
        readings["relative"] = abs(delta / b.value * mean_b)
    kept = {k: v for k, v in readings.items() if reachable(metric, mean_b, v, c.direction)}
    shown = ", ".join(f"{k} {v:.4g}" for k, v in readings.items())
    if not kept:
        return Margin(None, "none", f"{printed}; {shown}: no run could reach either")
    form, value = min(kept.items(), key=lambda kv: kv[1])
    dropped = sorted(set(readings) - set(kept))
    note = f"; {', '.join(dropped)} out of reach" if dropped else ""
    return Margin(value, "thesis", f"{printed}; {shown}: the {form} reading{note}")


def margin_of(
    c: Comparison,
    metric: Metric,
    thesis_a: ThesisValue | None,
    thesis_b: ThesisValue | None,
    mean_b: float,
) -> Margin:
    """The effect claim `c`'s `ruled out` excludes at our mean of b (see the module docstring)."""
    if c.direction != "equivalent" and thesis_a is not None and thesis_b is not None:
        return _thesis_margin(c, metric, thesis_a, thesis_b, mean_b)
    value = c.margin_for(mean_b)
    if value is None:
        return Margin(None, "none", "none declared")
    form = f"{c.margin:g} of b's mean" if c.margin_form == "relative" else f"{c.margin:g}"
    text = f"{form}; {c.margin_source}"
    if c.direction != "equivalent" and not reachable(metric, mean_b, value, c.direction):
        return Margin(None, "none", f"{text}: no run could reach it from our b")
    return Margin(value, "declared", text)
