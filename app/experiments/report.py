"""An experiment's report: every claim's statistics, as a typed object, JSON and a static page.

`analyse` computes the statistics and the verdict of every comparison of an
`ExperimentResults` (`sequential.judge` over the looks of an adaptive run, Holm across the
experiment's comparisons), `to_json` gives them as a JSON-ready dict, and `write_report`
writes a self-contained `index.html` with PNG figures, the per-run values (`values.csv`) every
statistic was computed from, and the JSON (`report.json`), all in one folder.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from app.experiments.figures import DeltaBar, FigureFile, SavedFigures, save_figures
from app.experiments.results import (
    CORE_STEPS_PER_SECOND,
    METRICS,
    VERDICT_COLOURS,
    Arm,
    Comparison,
    Condition,
    ExperimentResults,
    Metric,
    ThesisValue,
)
from app.experiments.sequential import (
    ALPHA,
    POWER,
    ClaimData,
    ClaimVerdict,
    Design,
    judge,
    seeds_for_power,
)
from app.experiments.stats import ArmSummary, PairStats, compare, holm, summarise
from app.experiments.values import VALUES_COLUMNS, write_values_csv

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
    holm_p: float  # two-sided p, Holm-adjusted over the experiment's claims (for the reader)
    judged: ClaimVerdict
    margin: float | None  # the effect the verdict rules out, in the metric's units
    need: Need | None

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
            b_side = self.arm_b.label if not self.comparison.paired else "its other side"
            return f"{self.arm_a.label} has {higher} {self.metric.label}{where} as {b_side}"
        if self.comparison.paired:  # one arm against itself on another metric or condition
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

    def of_kind(self, kind: str) -> tuple[ComparisonReport, ...]:
        """The thesis's questions ("question") or the within-arm sanity claims ("sanity")."""
        return tuple(c for c in self.comparisons if c.comparison.kind == kind)


def _thesis_value(results: ExperimentResults, key: tuple[str, str, str]) -> ThesisValue | None:
    """The thesis's number for the values at `key` (metric, arm, condition), if it gives one."""
    return next((v for v in results.thesis if (v.metric, v.arm, v.condition or "") == key), None)


def _thesis_beside_ours(results: ExperimentResults) -> list[tuple[ThesisValue, ArmSummary]]:
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


def analyse(results: ExperimentResults, alpha: float = ALPHA) -> ExperimentReport:
    """Every comparison's statistics and verdict (the looks of an adaptive run, Holm across
    the experiment's comparisons).

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
    margins: list[list[float | None]] = [[] for _ in results.comparisons]
    looks = []
    for n in made:
        claims = []
        for i, (c, (a, b)) in enumerate(zip(results.comparisons, values, strict=True)):
            b_look = b[:n]
            mean_b = float(np.nanmean(b_look)) if np.isfinite(b_look).any() else math.nan
            margin = c.margin_for(mean_b)
            margins[i].append(margin)
            claims.append(ClaimData(a[:n], b_look, c.direction, c.paired, margin))
        looks.append(claims)
    judged = judge(looks, design, alpha) if results.comparisons else ()
    pairs = [
        compare(a[: made[j.look]], b[: made[j.look]], c.direction, names=c.side_names(),
                paired=c.paired)
        for c, (a, b), j in zip(results.comparisons, values, judged, strict=True)
    ]  # fmt: skip
    two_sided = [min(1.0, 2 * min(p.p, p.p_opposite)) for p in pairs]
    adjusted = holm(two_sided) if pairs else np.array([])
    claims_out = []
    for i, (c, j) in enumerate(zip(results.comparisons, judged, strict=True)):
        margin = margins[i][j.look]
        need = _need(c, j, margin, results.steps_per_run) if j.verdict == "undecided" else None
        claims_out.append(ClaimStats(pairs[i], float(adjusted[i]), j, margin, need))
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


def json_number(x: float) -> float | None:
    """A float for JSON: None where it is NaN or infinite (JSON has neither)."""
    return float(x) if math.isfinite(x) else None


def format_number(x: float | None) -> str:
    """How the report prints a number: 4 significant digits, "–" for a missing one."""
    if x is None or math.isnan(x):
        return "–"
    if math.isinf(x):
        return "∞" if x > 0 else "−∞"
    return f"{x:.4g}"


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
        if c.margin is None
        else {
            "value": c.margin,
            "form": c.margin_form,
            "source": c.margin_source,
            "in_units": json_number(claim.margin if claim.margin is not None else math.nan),
        },
        "need": _need_json(claim.need),
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
    missing = np.full(len(results.seeds), np.nan)
    out = []
    for k, n in enumerate(report.looks):
        runs = {
            arm.name: int(
                np.isfinite(
                    results.scalars.get(("final_best_fitness", arm.name, ""), missing)[:n]
                ).sum()
            )
            for arm in results.arms
        }
        decided = [
            {"name": c.comparison.name, "verdict": c.claim.verdict}
            for c in report.comparisons
            if c.claim.verdict != "undecided" and c.claim.judged.look == k
        ]
        still_open = sum(
            c.claim.verdict == "undecided" or c.claim.judged.look > k for c in report.comparisons
        )
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
            for v, ours in _thesis_beside_ours(results)
        ],
    }


_CSS = (
    """
body { font: 15px/1.45 system-ui, sans-serif; max-width: 1100px; margin: 2em auto;
       padding: 0 1em; color: #222; }
h1 { margin-bottom: 0.2em; } h2 { margin-top: 2em; border-bottom: 1px solid #ddd; }
table { border-collapse: collapse; margin: 0.6em 0 1em; }
th, td { border: 1px solid #ddd; padding: 0.3em 0.6em; text-align: left; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
th { background: #f4f4f4; }
.facts td:first-child { font-weight: 600; }
.verdict { white-space: nowrap; font-weight: 700; padding: 0.1em 0.5em; border-radius: 4px; }
"""
    + "".join(
        f".{verdict.replace(' ', '-')} {{ background: {background}; color: {text}; }}\n"
        for verdict, (background, text) in VERDICT_COLOURS.items()
    )
    + """.comparison { display: flex; gap: 1.5em; align-items: flex-start; flex-wrap: wrap; }
.comparison figure { margin: 0.6em 0; flex: 1 1 320px; max-width: 440px; }
figure { margin: 1em 0; } figcaption { color: #555; font-size: 0.9em; max-width: 780px; }
img { max-width: 100%; }
.note { color: #8a5300; }
"""
)


def _e(text: object) -> str:
    return html.escape(str(text))


def _arm_name(arm: Arm) -> str:
    return arm.label if arm.name in arm.label else f"{arm.label} ({arm.name})"


def _verdict_html(verdict: str) -> str:
    return f'<span class="verdict {verdict.replace(" ", "-")}">{_e(verdict)}</span>'


def _row(*cells: str, header: bool = False) -> str:
    tag = "th" if header else "td"
    return "<tr>" + "".join(f"<{tag}>{cell}</{tag}>" for cell in cells) + "</tr>"


def interval_level(claim: ClaimStats) -> str:
    """The interval's coverage, e.g. '99.6%'."""
    return f"{100 * (1 - claim.judged.level):.3g}%"


def interval_text(claim: ClaimStats) -> str:
    iv = claim.judged.interval
    return f"[{format_number(iv.low)}, {format_number(iv.high)}]"


def margin_text(report: ComparisonReport) -> str:
    c = report.comparison
    if c.margin is None:
        return "none declared"
    form = f"{c.margin:g} of b's mean" if c.margin_form == "relative" else f"{c.margin:g}"
    sign = "±" if c.direction == "equivalent" else ""
    return f"{sign}{format_number(report.claim.margin)} ({form}; {c.margin_source})"


def need_text(need: Need) -> str:
    def one(seeds: float, hours: float) -> str:
        if not math.isfinite(seeds):
            return "–" if math.isnan(seeds) else "∞"
        return f"{seeds:.0f} ({hours:.3g} core-h)"

    return (
        f"{one(need.seeds_at_thesis, need.core_hours_at_thesis)}, "
        f"{one(need.seeds_at_ours, need.core_hours_at_ours)}"
    )


def _comparison_html(report: ComparisonReport, figure: FigureFile | None) -> str:
    s, claim, c = report.stats, report.claim, report.comparison
    sides = [_arm_name(report.arm_a), _arm_name(report.arm_b)]
    if c.paired:  # one arm: each side says its metric or condition
        parts: list[list[str]] = [[], []]
        if report.metric_b is not None:
            parts[0].append(report.metric.label)
            parts[1].append(report.metric_b.label)
        if report.condition_b is not None and report.condition is not None:
            parts[0].append(report.condition.label)
            parts[1].append(report.condition_b.label)
        sides = [", ".join([side, *part]) for side, part in zip(sides, parts, strict=True)]
    arm_rows = "".join(
        "<tr>"
        f"<td>{_e(side)}</td>"
        f'<td class="num">{summary.n}</td><td class="num">{summary.dropped}</td>'
        f'<td class="num">{_e(format_number(summary.mean))} ± {_e(format_number(summary.sd))}'
        "</td>"
        + (
            f'<td class="num">{_e(format_number(thesis.value))} ({_e(thesis.source)})</td>'
            if thesis
            else "<td>–</td>"
        )
        + "</tr>"
        for side, summary, thesis in (
            (sides[0], s.a, report.thesis_a),
            (sides[1], s.b, report.thesis_b),
        )
    )
    t_test, rank_test = s.tests
    rows = [
        ("difference of means (a − b)", format_number(s.difference)),
        (f"verdict's interval ({interval_level(claim)})", interval_text(claim)),
        ("effect ruled out by 'ruled out'", margin_text(report)),
        ("runs (a, b); look", f"{claim.runs[0]}, {claim.runs[1]}; {claim.judged.look + 1}"),
        (f"{t_test} t (df)", f"{format_number(s.t)} ({format_number(s.df)})"),
        (f"{t_test} p, one-tailed (other direction)",
         f"{format_number(s.p)} ({format_number(s.p_opposite)})"),
        (f"{rank_test} {'W+' if s.paired else 'U'} (p, one-tailed)",
         f"{format_number(s.rank_statistic)} ({format_number(s.rank_p)})"),
        (f"Holm-adjusted two-sided {t_test} p", format_number(claim.holm_p)),
        ("P(improvement)", format_number(s.prob_improvement)),
        ("Hedges' g", format_number(s.hedges_g)),
    ]  # fmt: skip
    if claim.need is not None:
        rows.append(("seeds per arm for 80% power: thesis's effect, ours", need_text(claim.need)))
    stats_rows = "".join(f'<tr><td>{_e(k)}</td><td class="num">{_e(v)}</td></tr>' for k, v in rows)
    notes = "".join(f'<li class="note">{_e(note)}</li>' for note in s.notes)
    image = (
        f'<figure><img src="{_e(figure.file)}" alt="{_e(figure.title)}">'
        f"<figcaption>{_e(figure.caption)}</figcaption></figure>"
        if figure
        else ""
    )
    return f"""
<h3>{_e(c.name)} {_verdict_html(claim.verdict)}</h3>
<p>Claim ({_e(c.source)}): {_e(report.sentence)}. a = {_e(c.a)}, b = {_e(c.b)}.</p>
<div class="comparison"><div>
<table>{_row("arm", "runs (n)", "unfinished", "mean ± sd", "thesis", header=True)}{arm_rows}
</table>
<table>{_row("statistic", "value", header=True)}{stats_rows}
<tr><td>verdict</td><td>{_verdict_html(claim.verdict)}</td></tr></table>
{f"<ul>{notes}</ul>" if notes else ""}
</div>{image}</div>"""


def _page(report: ExperimentReport, figures: SavedFigures) -> str:
    results = report.results
    facts = "".join(
        _row(_e(k), _e(v))
        for k, v in (
            ("source", results.source),
            ("scale", results.scale),
            ("seeds", ", ".join(map(str, results.seeds)) + f" ({len(results.seeds)} runs per arm)"),
            ("arms", "; ".join(f"{a.name}: {a.label}" for a in results.arms)),
            ("unit of analysis", "the run (seed): a run's value is its mean over trials"),
        )
    )

    def verdict_rows(kind: str) -> str:
        return "".join(
            _row(_e(c.comparison.name), _e(c.sentence), _e(c.comparison.source),
                 _e(f"{format_number(c.stats.difference)} {interval_text(c.claim)}"),
                 _e(f"{c.claim.runs[0]}, {c.claim.runs[1]}"), _verdict_html(c.claim.verdict))
            for c in report.of_kind(kind)
        )  # fmt: skip

    verdict_head = _row("comparison", "claim", "claimed in", "Δ [interval]", "runs (a, b)",
                        "verdict", header=True)  # fmt: skip
    questions, sanity = verdict_rows("question"), verdict_rows("sanity")
    summary = (
        f"<h3>The thesis's questions</h3><table>{verdict_head}{questions}</table>"
        if questions
        else ""
    ) + (f"<h3>Within one arm (sanity)</h3><table>{verdict_head}{sanity}</table>" if sanity else "")
    stage_rows = "".join(
        _row(str(st["look"]), str(st["seeds_per_arm"]),
             _e(", ".join(f"{arm} {n}" for arm, n in st["runs"].items())),
             _e(", ".join(f"{d['name']} ({d['verdict']})" for d in st["decided"]) or "–"),
             str(st["open_after"]))
        for st in stages_json(report)
    )  # fmt: skip
    stages = (
        "<h2>Stages</h2><table>"
        + _row("look", "seeds per arm", "runs", "decided", "still open", header=True)
        + stage_rows
        + "</table>"
    )
    thesis_rows = "".join(
        _row(_e(v.arm), _e(METRICS[v.metric].label if v.metric in METRICS else v.metric),
             _e(v.condition or "–"), _e(f"{format_number(v.value)} ({v.source})"),
             _e(f"{format_number(ours.mean)} ± {format_number(ours.sd)} (n = {ours.n})"))
        for v, ours in _thesis_beside_ours(results)
    )  # fmt: skip
    thesis_header = _row(
        "arm", "metric", "condition", "thesis", "ours: mean ± sd over runs", header=True
    )
    thesis_section = (
        f"<h2>The thesis's numbers beside ours</h2><table>{thesis_header}{thesis_rows}</table>"
        if thesis_rows
        else ""
    )
    conditions = "".join(
        _row(_e(c.name), _e(c.label), str(c.steps),
             "–" if c.fault_step is None else str(c.fault_step),
             str(c.broken_count), format_number(c.noise_sigma))
        for c in results.conditions
    )  # fmt: skip
    other_figures = "".join(
        f'<figure><img src="{_e(f.file)}" alt="{_e(f.title)}">'
        f"<figcaption><b>{_e(f.title)}.</b> {_e(f.caption)}</figcaption></figure>"
        for f in figures.overview
    )
    comparisons = "".join(
        _comparison_html(c, f) for c, f in zip(report.comparisons, figures.runs, strict=True)
    )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>{_e(results.name)} ({_e(results.scale)})</title>
<style>{_CSS}</style></head><body>
<h1>{_e(results.name)}</h1>
<p>{_e(results.description)}</p>
<table class="facts">{facts}</table>
<p>Each arm is run with the same seeds; the unit of analysis is the run, so n counts runs,
never trials. As in the thesis, arms are compared as independent samples (Welch); one arm
compared across two conditions or metrics has the same runs on both sides and is tested paired
by seed (paired t). Each claim's verdict rests on an interval of Δ = mean(a) − mean(b):
<i>held</i> when it lies on the claimed side of 0 (an equivalence claim: inside ±margin),
<i>reversed</i> when it lies on the other side, <i>ruled out</i> when it excludes the thesis's
effect (the margin declared in the experiment's file before the runs), else <i>undecided</i>,
with the seeds per arm that 80% power would need at the thesis's effect and at ours, and their
cost in core-hours. The intervals are two-sided t-intervals at level α/r (α = {report.alpha:g},
r the claims holding a share: Holm over all claims, both directions in one family; a claim
held or reversed hands its share on, one ruled out keeps it) widened, for an adaptive run, by
the Lan–DeMets O'Brien–Fleming boundary of the look, so the chance of any wrong held or
reversed over all claims and looks is at most α. Mann–Whitney U (Wilcoxon signed-rank
when paired), P(improvement) = P(X<sub>a</sub> &gt; X<sub>b</sub>) + ½ P(X<sub>a</sub> =
X<sub>b</sub>) (rliable) and Hedges' g describe each claim too. Unfinished runs (NaN) are left
out and counted.</p>
<h2>Verdicts</h2>
{summary}
{stages}
{thesis_section}
<h2>Comparisons</h2>{comparisons}
<h2>Figures</h2>{other_figures or "<p>No curves were recorded.</p>"}
<h2>Conditions</h2>
<table>{_row("name", "label", "steps T", "fault step t'", "broken sensors", "noise σ",
             header=True)}{conditions}</table>
<h2>Data</h2>
<p><a href="values.csv">values.csv</a>: every run's value each statistic was computed from
(columns {", ".join(VALUES_COLUMNS)}; nan for an unfinished run).
<a href="report.json">report.json</a>: these statistics as JSON.</p>
</body></html>
"""  # fmt: skip


def write_report(results: ExperimentResults, out_dir: Path, keep_curves: bool = False) -> Path:
    """Write `index.html`, its PNG figures, `values.csv` and `report.json` into `out_dir`.

    Args:
        results: the experiment's per-run values.
        out_dir: the report's folder, created if needed.
        keep_curves: keep the folder's curve figures (results read back from a values.csv
            have no curves; the verdict rules may change, the curves do not).

    Returns:
        The path of `index.html`.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    report = analyse(results)
    deltas = [
        DeltaBar(
            c.stats.difference,
            c.claim.judged.interval.low,
            c.claim.judged.interval.high,
            c.claim.margin,
            c.comparison.direction,
            interval_level(c.claim),
        )
        for c in report.comparisons
    ]
    figures = save_figures(results, out_dir, deltas, keep_curves=keep_curves)
    write_values_csv(results, out_dir / "values.csv")
    (out_dir / "report.json").write_text(json.dumps(to_json(report), indent=2, allow_nan=False))
    index = out_dir / "index.html"
    index.write_text(_page(report, figures), encoding="utf-8")
    return index
