"""An experiment's report as a JSON-ready dict (`report.json`): NaN and infinities become null."""

from __future__ import annotations

import math
from dataclasses import asdict
from typing import Any

from app.experiments.report import (
    ClaimStats,
    ComparisonReport,
    ExperimentReport,
    Need,
    tally,
    thesis_beside_ours,
)
from app.experiments.results import Arm, ThesisValue
from app.experiments.sequential import POWER
from app.experiments.stats import ArmSummary, PairStats

#: What the p-values of a report are: a report judged over looks shows none.
P_VALUES = {
    True: "none: judged over looks (group-sequential); a fixed-sample p would contradict them",
    False: "fixed-sample (one look): one-tailed t and rank tests, Holm-adjusted two-sided t",
}
STOPPING_METHOD = (
    "median-unbiased under the stagewise ordering (Jennison & Turnbull 2000, §8.4), and "
    "conditional on the stopping look (Troendle & Yu 1999), normal approximation"
)


def json_number(x: float) -> float | None:
    """A float for JSON: None where it is NaN or infinite (JSON has neither)."""
    return float(x) if math.isfinite(x) else None


def _arm_json(arm: Arm, summary: ArmSummary, thesis: ThesisValue | None) -> dict[str, Any]:
    return {
        "name": arm.name,
        "label": arm.label,
        "n": summary.n,
        "dropped": summary.dropped,
        "mean": json_number(summary.mean),
        "sd": json_number(summary.sd),
        "thesis": None if thesis is None else {"value": thesis.value, "source": thesis.source},
    }


def _need_json(need: Need | None) -> dict[str, Any] | None:
    if need is None:
        return None
    return {
        "power": POWER,
        "seeds_per_arm_at_thesis_effect": json_number(need.seeds_at_thesis),
        "seeds_per_arm_at_our_effect": json_number(need.seeds_at_ours),
        "core_hours_at_thesis_effect": json_number(need.core_hours_at_thesis),
        "core_hours_at_our_effect": json_number(need.core_hours_at_ours),
    }


def _stopping_json(claim: ClaimStats) -> dict[str, Any] | None:
    """Δ at the stopping look, corrected for stopping, and on all the data (estimates.py)."""
    found = claim.stopping
    if found is None:
        return None
    more = claim.all_data
    return {
        "look": found.look + 1,
        "stopped": found.stopped,
        "at_look": json_number(found.at_look),
        "median_unbiased": json_number(found.median_unbiased),
        "conditional": json_number(found.conditional),
        "method": STOPPING_METHOD,
        "all_data": None
        if more is None
        else {"difference": json_number(more[0]), "seeds": more[1]},
    }


def _relative_json(claim: ClaimStats, alpha: float) -> dict[str, Any] | None:
    iv = claim.relative
    if iv is None:
        return None
    return {
        "metric": "relative_fault_effect",
        "difference": json_number(iv.difference),
        "low": json_number(iv.low),
        "high": json_number(iv.high),
        "level": 1 - alpha,
        "runs": [iv.n_a, iv.n_b],
        "family": "exploratory",
    }


def _tests_json(s: PairStats, sequential: bool) -> dict[str, Any]:
    """The t and rank tests; their fixed-sample p-values only in a one-look report (a report
    judged over looks rests on its boundaries, which a fixed-sample p would contradict)."""
    t_test: dict[str, Any] = {"test": s.tests[0], "t": json_number(s.t), "df": json_number(s.df)}
    rank_test: dict[str, Any] = {"test": s.tests[1], "statistic": json_number(s.rank_statistic)}
    if not sequential:
        t_test |= {"p": json_number(s.p), "p_opposite": json_number(s.p_opposite)}
        rank_test |= {"p": json_number(s.rank_p)}
    return {"t_test": t_test, "rank_test": rank_test}


def _comparison_json(report: ComparisonReport, sequential: bool, alpha: float) -> dict[str, Any]:
    s, claim, c = report.stats, report.claim, report.comparison
    iv = claim.judged.interval
    return {
        "name": c.name,
        "claim": report.sentence,
        "kind": c.kind,
        "family": c.family,
        "source": c.source,
        "metric": report.metric.name,
        "metric_label": report.metric.label,
        "condition": c.condition,
        "condition_b": c.condition_b,
        "metric_b": c.metric_b,
        "sides": list(c.side_names()),
        "direction": c.direction,
        "a": _arm_json(report.arm_a, s.a, report.thesis_a),
        "b": _arm_json(report.arm_b, s.b, report.thesis_b),
        "difference": json_number(s.difference),
        "verdict": claim.verdict,
        "interval": {
            "low": json_number(iv.low),
            "high": json_number(iv.high),
            "level": json_number(1 - claim.judged.level),
            "family_share": json_number(claim.judged.family_level),
        },
        "runs": list(claim.runs),
        "look": claim.judged.look + 1,
        "margin": None
        if c.margin is None and claim.margin_rule.basis == "none"
        else {
            "value": c.margin,
            "form": c.margin_form,
            "source": c.margin_source,
            "in_units": json_number(claim.margin if claim.margin is not None else math.nan),
            "basis": claim.margin_rule.basis,
            "rule": claim.margin_rule.text,
        },
        "need": _need_json(claim.need),
        "post_hoc": claim.post_hoc,
        "provenance": None if claim.provenance is None else asdict(claim.provenance),
        "other_pairing": None
        if claim.other_pairing is None
        else {
            "paired": not c.paired,
            "low": json_number(claim.other_pairing[0].low),
            "high": json_number(claim.other_pairing[0].high),
            "verdict": claim.other_pairing[1],
        },
        "paired": s.paired,
        **_tests_json(s, sequential),
        **({} if sequential else {"holm_p": json_number(claim.holm_p)}),
        "stopping": _stopping_json(claim),
        "relative_reading": _relative_json(claim, alpha),
        "prob_improvement": json_number(s.prob_improvement),
        "hedges_g": json_number(s.hedges_g),
        "notes": list(s.notes),
    }


def stages_json(report: ExperimentReport) -> list[dict[str, Any]]:
    """Per look: seeds per arm, the runs each arm had, and the claims it decided."""
    results = report.results
    out = []
    for k, n in enumerate(report.looks):
        runs = {arm.name: int(results.finished(arm.name)[:n].sum()) for arm in results.arms}
        primary = report.of_family("primary")
        decided = [
            {"name": c.comparison.name, "verdict": c.claim.verdict}
            for c in primary
            if c.claim.verdict != "undecided" and c.claim.judged.look == k
        ]
        still_open = sum(c.claim.verdict == "undecided" or c.claim.judged.look > k for c in primary)
        out.append({"look": k + 1, "seeds_per_arm": n, "runs": runs, "decided": decided,
                    "open_after": still_open})  # fmt: skip
    return out


def to_json(report: ExperimentReport) -> dict[str, Any]:
    """The report as a JSON-ready dict (NaN and infinities become null)."""
    results = report.results
    sequential = bool(results.looks)
    return {
        "experiment": results.name,
        "description": results.description,
        "source": results.source,
        "scale": results.scale,
        "seeds": list(results.seeds),
        "unit_of_analysis": "run (seed): a run's value is its mean over trials",
        "alpha": report.alpha,
        "looks_planned": list(report.design.looks),
        "looks_made": list(report.looks),
        "stages": stages_json(report),
        "control": results.control,
        "arms": [{"name": a.name, "label": a.label} for a in results.arms],
        "conditions": [
            {
                "name": c.name,
                "label": c.label,
                "steps": c.steps,
                "fault_step": c.fault_step,
                "broken_count": c.broken_count,
                "noise_sigma": c.noise_sigma,
            }
            for c in results.conditions
        ],
        "tally": tally(report),
        "p_values": P_VALUES[sequential],
        "comparisons": [_comparison_json(c, sequential, report.alpha) for c in report.comparisons],
        "thesis": [
            {
                "arm": v.arm,
                "metric": v.metric,
                "condition": v.condition,
                "value": v.value,
                "source": v.source,
                "ours": {"mean": json_number(ours.mean), "sd": json_number(ours.sd), "n": ours.n},
            }
            for v, ours in thesis_beside_ours(results)
        ],
    }
