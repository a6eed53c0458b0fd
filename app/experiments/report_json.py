"""An experiment's report as a JSON-ready dict (`report.json`): NaN and infinities become null."""

from __future__ import annotations

import math
from dataclasses import asdict
from typing import Any

from app.experiments.report import (
    ComparisonReport,
    ExperimentReport,
    Need,
    tally,
    thesis_beside_ours,
)
from app.experiments.results import Arm, ThesisValue
from app.experiments.sequential import POWER
from app.experiments.stats import ArmSummary


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


def _comparison_json(report: ComparisonReport) -> dict[str, Any]:
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
        "t_test": {
            "test": s.tests[0],
            "t": json_number(s.t),
            "df": json_number(s.df),
            "p": json_number(s.p),
            "p_opposite": json_number(s.p_opposite),
        },
        "rank_test": {
            "test": s.tests[1],
            "statistic": json_number(s.rank_statistic),
            "p": json_number(s.rank_p),
        },
        "holm_p": json_number(claim.holm_p),
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
        "comparisons": [_comparison_json(c) for c in report.comparisons],
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
