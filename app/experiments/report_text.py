"""An experiment's report in words: its numbers, intervals, looks, margins, needs and
provenance as the report's page and the dashboard print them."""

from __future__ import annotations

import math

import numpy as np

from app.experiments.report import ClaimStats, ComparisonReport, ExperimentReport, Need
from app.experiments.results import ENV_STEPS_METRIC, ExperimentResults
from app.experiments.stats import summarise


def format_number(x: float | None) -> str:
    """How the report prints a number: 4 significant digits, "–" for a missing one."""
    if x is None or math.isnan(x):
        return "–"
    if math.isinf(x):
        return "∞" if x > 0 else "−∞"
    return f"{x:.4g}"


def mean_sd_text(values: object) -> str:
    """A per-run value over an arm's runs: mean ± sd (n = finished runs)."""
    s = summarise(np.asarray(values, dtype=float))
    return f"{format_number(s.mean)} ± {format_number(s.sd)} (n = {s.n})"


def arm_cost_rows(results: ExperimentResults) -> list[tuple[str, str, str]]:
    """A task experiment's arms beside what their training cost: (arm, test return, env-steps
    in training), each mean ± sd over its runs; none when no run holds its env-steps (a task
    experiment run before #45, or the robot's)."""
    if not any(key[0] == ENV_STEPS_METRIC for key in results.scalars):
        return []
    missing = np.full(len(results.seeds), np.nan)
    return [
        (
            f"{arm.name}: {arm.label}",
            mean_sd_text(results.scalars.get(("test_return", arm.name, ""), missing)),
            mean_sd_text(results.scalars.get((ENV_STEPS_METRIC, arm.name, ""), missing)),
        )
        for arm in results.arms
    ]


def seeds_text(results: ExperimentResults) -> str:
    """The seeds and the runs each arm finished: an arm an adaptive run stopped early has fewer."""
    runs = {arm.name: int(results.finished(arm.name).sum()) for arm in results.arms}
    counts = (
        f"{next(iter(runs.values()))} runs per arm"
        if len(set(runs.values())) == 1
        else "runs: " + ", ".join(f"{name} {n}" for name, n in runs.items())
    )
    return ", ".join(map(str, results.seeds)) + f" ({counts})"


def looks_text(report: ExperimentReport) -> str:
    """The looks a report made, in words: for the report's page and the dashboard's Stages line."""
    if not report.results.looks:
        return f"one look at {len(report.results.seeds)} seeds per arm (not adaptive)"
    planned = ", ".join(map(str, report.design.looks))
    return (
        f"adaptive: {len(report.looks)} of {len(report.design.looks)} looks made; "
        f"planned at {planned} seeds per arm"
    )


def interval_level(claim: ClaimStats) -> str:
    """The interval's coverage, e.g. '99.6%'."""
    return f"{100 * (1 - claim.judged.level):.3g}%"


def interval_text(claim: ClaimStats) -> str:
    iv = claim.judged.interval
    return f"[{format_number(iv.low)}, {format_number(iv.high)}]"


def provenance_text(claim: ClaimStats) -> str:
    """When the claim and its margin were declared, against its data, in words."""
    d = claim.provenance
    if d is None:
        return "not recorded (not a shipped experiment's claim)"
    words = f"claim {d.claim_commit}, margin {d.margin_commit}; "
    words += f"first data {d.data_commit}" if d.data_commit else "no data committed yet"
    if claim.post_hoc is None:
        return words
    if not claim.post_hoc:
        return words + ": pre-registered"
    if not d.claim_first:
        return words + ": post hoc (the claim came after its data)"
    if not d.margin_first:
        return words + ": post hoc (the margin came after the data)"
    return words + ": post hoc (the declared margin alone gives another verdict)"


def sensitivity_text(claim: ClaimStats) -> str:
    """The claim analysed the other way (paired or unpaired), at the verdict's level."""
    if claim.other_pairing is None:
        return "–"
    iv, verdict = claim.other_pairing
    how = "unpaired" if claim.stats.paired else "paired by seed"
    return f"{how}: [{format_number(iv.low)}, {format_number(iv.high)}] {verdict}"


def margin_text(report: ComparisonReport) -> str:
    rule = report.claim.margin_rule
    if rule.value is None:
        return rule.text
    sign = "±" if report.comparison.direction == "equivalent" else ""
    return f"{sign}{format_number(rule.value)} ({rule.text})"


def need_text(need: Need) -> str:
    def one(seeds: float, hours: float) -> str:
        if not math.isfinite(seeds):
            return "–" if math.isnan(seeds) else "∞"
        return f"{seeds:.0f} ({hours:.3g} core-h)"

    return (
        f"{one(need.seeds_at_thesis, need.core_hours_at_thesis)}, "
        f"{one(need.seeds_at_ours, need.core_hours_at_ours)}"
    )


def stopping_text(claim: ClaimStats) -> str:
    """'+0.0873 at look 3; corrected: +0.0842 (stagewise), +0.07 (given look 3); all the data
    (100 seeds): +0.0760'."""
    found = claim.stopping
    if found is None:
        return "–"
    given = f"given look {found.look + 1}" if found.stopped else "given the last look"
    text = (
        f"{format_number(found.at_look)} at look {found.look + 1}; corrected: "
        f"{format_number(found.median_unbiased)} (stagewise median-unbiased), "
        f"{format_number(found.conditional)} ({given})"
    )
    if claim.all_data is not None:
        difference, seeds = claim.all_data
        text += f"; all the data ({seeds} seeds both sides ran): {format_number(difference)}"
    return text


def relative_text(claim: ClaimStats) -> str:
    """'+1.94 percentage points [+0.25, +3.64] (100, 100 runs)': a fault's cost relative to
    each side's own no-fault level, a minus its b."""
    iv = claim.relative
    if iv is None:
        return "–"
    return (
        f"{100 * iv.difference:+.2f} percentage points [{100 * iv.low:+.2f}, "
        f"{100 * iv.high:+.2f}] ({iv.n_a}, {iv.n_b} runs)"
    )


def estimate_rows(claim: ClaimStats) -> list[tuple[str, str]]:
    """The page's rows of a claim's estimates beside its verdict's Δ (where it has them)."""
    rows = []
    if claim.stopping is not None:
        rows.append(("Δ corrected for stopping (its look; all the data)", stopping_text(claim)))
    if claim.relative is not None:
        rows.append(
            ("against each side's no-fault level (exploratory, unadjusted 95%)",
             relative_text(claim))
        )  # fmt: skip
    return rows
