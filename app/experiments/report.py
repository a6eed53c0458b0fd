"""An experiment's report: every claim's statistics and verdict, as a typed object.

`analyse` computes the statistics and the verdict of every comparison of an
`ExperimentResults` (`sequential.judge` over the looks of an adaptive run, Holm across the
experiment's comparisons); `app.experiments.report_json` gives them as a JSON-ready dict,
`app.experiments.report_text` in words, and the page, its figures and files are
`app.experiments.report_page.write_report`'s.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from app.experiments.estimates import Stopping, all_data, relative_reading, stopping
from app.experiments.margins import Margin, margin_of
from app.experiments.provenance import Declared, declared
from app.experiments.results import (
    CORE_STEPS_PER_SECOND,
    METRICS,
    Arm,
    Comparison,
    Condition,
    ExperimentResults,
    Metric,
    ThesisValue,
    Verdict,
)
from app.experiments.sequential import (
    ALPHA,
    ClaimData,
    ClaimVerdict,
    Design,
    Interval,
    decide,
    interval,
    judge,
    seeds_for_power,
)
from app.experiments.stats import ArmSummary, PairStats, compare, holm, summarise

_DIRECTION_WORDS = {"greater": "higher", "less": "lower", "equivalent": "about the same"}


@dataclass(frozen=True)
class Need:
    """What an undecided claim would need: seeds per arm for 80% power at its level, at the
    thesis's effect (its margin) and at ours (the observed difference), and their cost."""

    seeds_at_thesis: float  # NaN: no margin declared; inf: no effect to find
    seeds_at_ours: float
    core_hours_at_thesis: float
    core_hours_at_ours: float


@dataclass(frozen=True)
class ClaimStats:
    """A claim's descriptive statistics, its verdict and, undecided, what it would need."""

    stats: PairStats
    # Two-sided p, Holm-adjusted over the primary claims of a one-look report (for the reader);
    # NaN for an exploratory claim and for every claim of a sequential report, whose verdicts
    # rest on the looks' boundaries, which a fixed-sample p would contradict.
    holm_p: float
    judged: ClaimVerdict
    margin: float | None  # the effect the verdict rules out, in the metric's units
    need: Need | None
    margin_rule: Margin  # how `margin` was reached
    # When the claim and its margin were declared (None: a claim the history does not know),
    # and whether its verdict was judged on data seen before them.
    provenance: Declared | None = None
    post_hoc: bool | None = None
    # The same claim analysed the other way (paired by seed if declared unpaired, and back),
    # at the verdict's level: a sensitivity check beside the verdict. None within one arm.
    other_pairing: tuple[Interval, Verdict] | None = None
    # A primary claim judged over looks: its Δ corrected for stopping (estimates.py), and its
    # Δ on every seed both sides ran with their count, where that is more than it was judged on.
    stopping: Stopping | None = None
    all_data: tuple[float, int] | None = None
    # A fault-effect claim read against each side's own no-fault level (relative_fault_effect):
    # an unadjusted interval at level α on every judged seed, exploratory.
    relative: Interval | None = None

    @property
    def verdict(self) -> str:
        return self.judged.verdict

    @property
    def runs(self) -> tuple[int, int]:
        """Runs used on each side by the look that decided the claim (or the last look)."""
        return self.judged.interval.n_a, self.judged.interval.n_b


@dataclass(frozen=True)
class ComparisonReport:
    """One comparison with its arms, metric, condition, statistics and the thesis's numbers."""

    comparison: Comparison
    metric: Metric
    condition: Condition | None
    condition_b: Condition | None  # b's condition when it is not a's (paired: one arm)
    metric_b: Metric | None  # b's metric when it is not a's (paired: one arm)
    arm_a: Arm
    arm_b: Arm
    claim: ClaimStats
    thesis_a: ThesisValue | None  # the thesis's value for arm a, when it gives one
    thesis_b: ThesisValue | None

    @property
    def stats(self) -> PairStats:
        return self.claim.stats

    @property
    def sentence(self) -> str:
        """The claim in words."""
        where = f" in {self.condition.label}" if self.condition else ""
        higher = _DIRECTION_WORDS[self.comparison.direction]
        if self.comparison.direction == "equivalent":
            b_side = self.arm_b.label if not self.comparison.within_arm else "its other side"
            return f"{self.arm_a.label} has {higher} {self.metric.label}{where} as {b_side}"
        if self.comparison.within_arm:  # one arm against itself on another metric or condition
            other = [self.metric_b.label] if self.metric_b else []
            other += [f"in {self.condition_b.label}"] if self.condition_b else []
            return f"{self.arm_a.label} has a {higher} {self.metric.label}{where} than " + (
                " ".join(other)
            )
        return (
            f"{self.arm_a.label} has a {higher} {self.metric.label} than {self.arm_b.label}{where}"
        )


@dataclass(frozen=True)
class ExperimentReport:
    """The statistics of every comparison of one experiment."""

    results: ExperimentResults
    comparisons: tuple[ComparisonReport, ...]
    alpha: float
    design: Design  # the planned looks (one look at every seed when not adaptive)
    looks: tuple[int, ...]  # seeds per arm at each look made

    def of_family(self, family: str) -> tuple[ComparisonReport, ...]:
        """The primary claims (judged with family-wise error control) or the exploratory ones."""
        return tuple(c for c in self.comparisons if c.comparison.family == family)

    def of_kind(self, kind: str) -> tuple[ComparisonReport, ...]:
        """The thesis's questions ("question") or the within-arm sanity claims ("sanity")."""
        return tuple(c for c in self.comparisons if c.comparison.kind == kind)


def _thesis_value(results: ExperimentResults, key: tuple[str, str, str]) -> ThesisValue | None:
    """The thesis's number for the values at `key` (metric, arm, condition), if it gives one."""
    return next((v for v in results.thesis if (v.metric, v.arm, v.condition or "") == key), None)


def thesis_beside_ours(results: ExperimentResults) -> list[tuple[ThesisValue, ArmSummary]]:
    """Each of the thesis's numbers with our summary of the same arm, metric and condition."""
    missing = np.full(len(results.seeds), np.nan)
    return [
        (v, summarise(results.scalars.get((v.metric, v.arm, v.condition or ""), missing)))
        for v in results.thesis
    ]


def looks_made(results: ExperimentResults) -> tuple[Design, tuple[int, ...]]:
    """The design of the results' looks and the seed counts of the looks made so far."""
    n = len(results.seeds)
    if not results.looks:
        return Design((n,)), (n,)
    design = Design(results.looks)
    made = tuple(k for k in design.looks if k <= n)
    return design, made or (n,)


def _need(c: Comparison, judged: ClaimVerdict, margin: float | None, steps: float) -> Need:
    iv = judged.interval
    sides = 1 if c.paired else 2
    ours = abs(iv.difference)
    if c.direction == "equivalent" and margin is not None:
        ours = abs(margin - ours)
    at_thesis = (
        seeds_for_power(iv.sd, margin, c.paired, judged.family_level)
        if margin is not None
        else math.nan
    )
    at_ours = seeds_for_power(iv.sd, ours, c.paired, judged.family_level)

    def hours(seeds: float) -> float:
        return seeds * sides * steps / CORE_STEPS_PER_SECOND / 3600 if steps else math.nan

    return Need(at_thesis, at_ours, hours(at_thesis), hours(at_ours))


def post_hoc(
    c: Comparison, judged: ClaimVerdict, origin: Declared | None, declared_margin: float | None
) -> bool | None:
    """Whether a verdict rests on a claim or margin declared after the data it is judged on.

    A held or reversed rests on the claim alone; a ruled out (and an equivalence verdict) on
    its margin too, which is pre-registered only if it was declared before the data and the
    declared margin alone gives the same verdict: `declared_margin` is what the margin rule of
    `app.experiments.margins` makes of the declared margin without the thesis's values (None
    where no run could reach it), since that rule came after every report before issue #30 and
    a verdict resting on the thesis's difference rests on it. None: unknown
    (a claim the history does not know) or not a verdict (exploratory).
    """
    if origin is None or judged.verdict == "exploratory":
        return None
    if not origin.claim_first:
        return True
    if judged.verdict == "ruled out" or (
        c.direction == "equivalent" and judged.verdict != "undecided"
    ):
        if not origin.margin_first:
            return True
        return decide(judged.interval, c.direction, declared_margin) != judged.verdict
    return False


def _judge_families(
    comparisons: tuple[Comparison, ...],
    looks: list[list[ClaimData]],
    design: Design,
    alpha: float,
) -> list[ClaimVerdict]:
    """The primary claims judged together over the looks (family-wise error α); each
    exploratory claim's unadjusted two-sided interval at level α at the last look, its verdict
    `exploratory`."""
    primary = [i for i, c in enumerate(comparisons) if c.family == "primary"]
    judged_primary = judge([[look[i] for i in primary] for look in looks], design, alpha)
    out: dict[int, ClaimVerdict] = dict(zip(primary, judged_primary, strict=True))
    last = len(looks) - 1
    for i in range(len(comparisons)):
        if i not in out:
            iv = interval(looks[last][i], alpha)
            out[i] = ClaimVerdict("exploratory", iv, alpha, last, alpha)
    return [out[i] for i in range(len(comparisons))]


def analyse(results: ExperimentResults, alpha: float = ALPHA) -> ExperimentReport:
    """Every comparison's statistics and verdict (the looks of an adaptive run, Holm across
    the experiment's primary comparisons; exploratory ones with unadjusted intervals).

    Args:
        results: the experiment's per-run values.
        alpha: family-wise error rate of the verdicts.

    Returns:
        The report; a comparison whose values are missing counts as all runs unfinished.
    """
    arms = {arm.name: arm for arm in results.arms}
    conditions = {c.name: c for c in results.conditions}
    missing = np.full(len(results.seeds), np.nan)
    for c in results.comparisons:
        named = [c.condition, c.condition_b]
        if c.a not in arms or c.b not in arms or any(n and n not in conditions for n in named):
            raise ValueError(f"comparison {c.name!r} names an arm or condition not in the results")
    values = []
    for c in results.comparisons:
        key_a, key_b = c.keys()
        values.append((results.scalars.get(key_a, missing), results.scalars.get(key_b, missing)))
    design, made = looks_made(results)
    margins: list[list[Margin]] = [[] for _ in results.comparisons]
    declared_margins: list[list[float | None]] = [[] for _ in results.comparisons]
    looks = []
    for n in made:
        claims = []
        for i, (c, (a, b)) in enumerate(zip(results.comparisons, values, strict=True)):
            b_look = b[:n]
            mean_b = float(np.nanmean(b_look)) if np.isfinite(b_look).any() else math.nan
            key_a, key_b = c.keys()
            thesis_a, thesis_b = _thesis_value(results, key_a), _thesis_value(results, key_b)
            margin = margin_of(c, METRICS[c.metric], thesis_a, thesis_b, mean_b)
            margins[i].append(margin)
            # The declared margin alone, through the same rule (reachability included).
            declared_margins[i].append(margin_of(c, METRICS[c.metric], None, None, mean_b).value)
            claims.append(ClaimData(a[:n], b_look, c.direction, c.paired, margin.value))
        looks.append(claims)
    judged = _judge_families(results.comparisons, looks, design, alpha)
    pairs = [
        compare(a[: made[j.look]], b[: made[j.look]], c.direction, names=c.side_names(),
                paired=c.paired)
        for c, (a, b), j in zip(results.comparisons, values, judged, strict=True)
    ]  # fmt: skip
    adjusted = np.full(len(pairs), np.nan)
    primary = [i for i, c in enumerate(results.comparisons) if c.family == "primary"]
    if primary and not results.looks:
        two_sided = [min(1.0, 2 * min(pairs[i].p, pairs[i].p_opposite)) for i in primary]
        adjusted[primary] = holm(two_sided)
    claims_out = []
    for i, (c, j) in enumerate(zip(results.comparisons, judged, strict=True)):
        margin = margins[i][j.look]
        undecided = j.verdict == "undecided"
        need = _need(c, j, margin.value, results.steps_per_run) if undecided else None
        origin = declared(results.name, results.scale, c.name)
        late = post_hoc(c, j, origin, declared_margins[i][j.look])
        other = None
        if not c.within_arm and j.verdict != "exploratory":
            # The deciding look's data, analysed the other way at the same level.
            data = dataclasses.replace(looks[j.look][i], paired=not c.paired)
            iv = interval(data, j.level)
            other = (iv, decide(iv, c.direction, margin.value))
        sequential = bool(results.looks) and c.family == "primary"
        last_planned = len(made) == len(design.looks)
        claim_looks = [look[i] for look in looks]
        claims_out.append(
            ClaimStats(
                pairs[i],
                float(adjusted[i]),
                j,
                margin.value,
                need,
                margin,
                origin,
                late,
                other,
                stopping(claim_looks, j, last_planned) if sequential else None,
                all_data(*values[i], (j.interval.n_a, j.interval.n_b)) if sequential else None,
                relative_reading(results, c, alpha),
            )
        )
    return ExperimentReport(
        results=results,
        comparisons=tuple(
            ComparisonReport(
                comparison=c,
                metric=METRICS[c.metric],
                condition=conditions[c.condition] if c.condition else None,
                condition_b=conditions[c.condition_b] if c.condition_b else None,
                metric_b=METRICS[c.metric_b] if c.metric_b else None,
                arm_a=arms[c.a],
                arm_b=arms[c.b],
                claim=claim,
                thesis_a=_thesis_value(results, c.keys()[0]),
                thesis_b=_thesis_value(results, c.keys()[1]),
            )
            for c, claim in zip(results.comparisons, claims_out, strict=True)
        ),
        alpha=alpha,
        design=design,
        looks=made,
    )


def tally(report: ExperimentReport) -> dict[str, dict[str, int]]:
    """Verdict counts: pre-registered (or unrecorded) and post hoc, primary claims only."""
    out: dict[str, dict[str, int]] = {"pre-registered": {}, "post hoc": {}}
    for c in report.of_family("primary"):
        group = out["post hoc" if c.claim.post_hoc else "pre-registered"]
        group[c.claim.verdict] = group.get(c.claim.verdict, 0) + 1
    return out
