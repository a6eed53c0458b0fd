"""An experiment's report: every claim's statistics, as a typed object, JSON and a static page.

`analyse` computes the statistics of every comparison of an `ExperimentResults` (Holm across
the experiment's comparisons), `to_json` gives them as a JSON-ready dict, and `write_report`
writes a self-contained `index.html` with PNG figures, the per-run values (`values.csv`) every
statistic was computed from, and the JSON (`report.json`), all in one folder.
"""

from __future__ import annotations

import csv
import html
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from app.experiments.figures import FigureFile, SavedFigures, remove_figures, save_figures
from app.experiments.results import (
    METRICS,
    Arm,
    Comparison,
    Condition,
    ExperimentResults,
    Metric,
    ThesisValue,
)
from app.experiments.stats import (
    ALPHA,
    BOOTSTRAP_RESAMPLES,
    CI_LEVEL,
    ArmSummary,
    ClaimStats,
    PairStats,
    compare,
    judge_claims,
    summarise,
)

REPORT_SEED = 0  # the bootstrap's seed when `write_report` is given no generator
VALUES_COLUMNS = ("arm", "seed", "condition", "metric", "value")
_DIRECTION_WORDS = {"greater": "higher", "less": "lower"}


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
    resamples: int


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


def analyse(
    results: ExperimentResults,
    rng: np.random.Generator,
    resamples: int = BOOTSTRAP_RESAMPLES,
    alpha: float = ALPHA,
) -> ExperimentReport:
    """Every comparison's statistics, Holm-adjusted across the experiment's comparisons.

    Args:
        results: the experiment's per-run values.
        rng: the bootstraps' only source of randomness (used in comparison order).
        resamples: bootstrap resamples per comparison.
        alpha: significance level of the verdicts.

    Returns:
        The report; a comparison whose values are missing counts as all runs unfinished.
    """
    arms = {arm.name: arm for arm in results.arms}
    conditions = {c.name: c for c in results.conditions}
    missing = np.full(len(results.seeds), np.nan)
    pairs = []
    for c in results.comparisons:
        named = [c.condition, c.condition_b]
        if c.a not in arms or c.b not in arms or any(n and n not in conditions for n in named):
            raise ValueError(f"comparison {c.name!r} names an arm or condition not in the results")
        key_a, key_b = c.keys()
        pairs.append(
            compare(
                results.scalars.get(key_a, missing),
                results.scalars.get(key_b, missing),
                c.direction,
                rng,
                resamples,
                names=c.side_names(),
                paired=c.paired,
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
            for c, claim in zip(results.comparisons, judge_claims(pairs, alpha), strict=True)
        ),
        alpha=alpha,
        resamples=resamples,
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


def _comparison_json(report: ComparisonReport) -> dict[str, Any]:
    s, claim = report.stats, report.claim
    return {
        "name": report.comparison.name,
        "claim": report.sentence,
        "source": report.comparison.source,
        "metric": report.metric.name,
        "metric_label": report.metric.label,
        "condition": report.comparison.condition,
        "condition_b": report.comparison.condition_b,
        "metric_b": report.comparison.metric_b,
        "sides": list(report.comparison.side_names()),
        "direction": report.comparison.direction,
        "a": _arm_json(report.arm_a, s.a, report.thesis_a),
        "b": _arm_json(report.arm_b, s.b, report.thesis_b),
        "difference": json_number(s.difference),
        "ci": [json_number(s.ci_low), json_number(s.ci_high)],
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
        "holm_p_opposite": json_number(claim.holm_p_opposite),
        "prob_improvement": json_number(s.prob_improvement),
        "hedges_g": json_number(s.hedges_g),
        "verdict": claim.verdict,
        "notes": list(s.notes),
    }


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
        "ci_level": CI_LEVEL,
        "bootstrap_resamples": report.resamples,
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


def write_values_csv(results: ExperimentResults, path: Path) -> None:
    """Every per-run scalar value (NaN for unfinished runs), one row per run and metric."""
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(VALUES_COLUMNS)
        for (metric, arm, condition), values in results.scalars.items():
            for seed, value in zip(results.seeds, np.asarray(values, dtype=float), strict=True):
                writer.writerow([arm, seed, condition, metric, repr(float(value))])


_CSS = """
body { font: 15px/1.45 system-ui, sans-serif; max-width: 1100px; margin: 2em auto;
       padding: 0 1em; color: #222; }
h1 { margin-bottom: 0.2em; } h2 { margin-top: 2em; border-bottom: 1px solid #ddd; }
table { border-collapse: collapse; margin: 0.6em 0 1em; }
th, td { border: 1px solid #ddd; padding: 0.3em 0.6em; text-align: left; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
th { background: #f4f4f4; }
.facts td:first-child { font-weight: 600; }
.verdict { white-space: nowrap; font-weight: 700; padding: 0.1em 0.5em; border-radius: 4px; }
.held { background: #d8f3dc; color: #1b5e20; }
.reversed { background: #fde2e1; color: #9b1c1c; }
.not-shown { background: #eee; color: #555; }
.comparison { display: flex; gap: 1.5em; align-items: flex-start; flex-wrap: wrap; }
.comparison figure { margin: 0.6em 0; flex: 1 1 320px; max-width: 440px; }
figure { margin: 1em 0; } figcaption { color: #555; font-size: 0.9em; max-width: 780px; }
img { max-width: 100%; }
.note { color: #8a5300; }
"""


def _e(text: object) -> str:
    return html.escape(str(text))


def _arm_name(arm: Arm) -> str:
    return arm.label if arm.name in arm.label else f"{arm.label} ({arm.name})"


def _verdict_html(verdict: str) -> str:
    return f'<span class="verdict {verdict.replace(" ", "-")}">{_e(verdict)}</span>'


def _row(*cells: str, header: bool = False) -> str:
    tag = "th" if header else "td"
    return "<tr>" + "".join(f"<{tag}>{cell}</{tag}>" for cell in cells) + "</tr>"


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
    ci = f"[{format_number(s.ci_low)}, {format_number(s.ci_high)}]"
    t_test, rank_test = s.tests
    rows = [
        ("difference of means (a − b)", f"{format_number(s.difference)} {ci}"),
        (f"{t_test} t (df)", f"{format_number(s.t)} ({format_number(s.df)})"),
        (f"{t_test} p, one-tailed", format_number(s.p)),
        (f"{rank_test} {'W+' if s.paired else 'U'} (p, one-tailed)",
         f"{format_number(s.rank_statistic)} ({format_number(s.rank_p)})"),
        (f"Holm-adjusted {t_test} p", format_number(claim.holm_p)),
        (f"Holm-adjusted {t_test} p, other direction", format_number(claim.holm_p_opposite)),
        ("P(improvement)", format_number(s.prob_improvement)),
        ("Hedges' g", format_number(s.hedges_g)),
    ]  # fmt: skip
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
    summary = "".join(
        _row(_e(c.comparison.name), _e(c.sentence), _e(c.comparison.source),
             _e(format_number(c.claim.holm_p)), _verdict_html(c.claim.verdict))
        for c in report.comparisons
    )  # fmt: skip
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
    level = f"{CI_LEVEL:.0%}"
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>{_e(results.name)} ({_e(results.scale)})</title>
<style>{_CSS}</style></head><body>
<h1>{_e(results.name)}</h1>
<p>{_e(results.description)}</p>
<table class="facts">{facts}</table>
<p>Each arm is run with the same {len(results.seeds)} seeds; the unit of analysis is the run,
so n counts runs, never trials. As in the thesis, arms are compared as independent samples.
Per comparison: mean ± sd (ddof = 1) per arm; the difference of means with a {level}
percentile-bootstrap CI ({report.resamples:,} resamples, each arm resampled independently);
Welch's one-tailed t-test and a one-tailed Mann–Whitney U test in the claimed direction;
P(improvement) = P(X<sub>a</sub> &gt; X<sub>b</sub>) + ½ P(X<sub>a</sub> = X<sub>b</sub>)
over all pairs of runs (rliable), oriented so that above 0.5 favours the claim; Hedges' g
(pooled sd, exact small-sample correction), oriented so that above 0 favours the claim.
One arm compared across two conditions has the same runs on both sides: its tests are paired
by seed (the one-tailed paired t-test and Wilcoxon's signed-rank test on the runs'
differences, the bootstrap resampling runs, P(improvement) the share of runs that improve).
The t-tests' p-values are Holm-adjusted across this experiment's {len(report.comparisons)}
comparison(s). Verdict: <i>held</i> if the adjusted p in the claimed direction is below
{report.alpha:g}, <i>reversed</i> if the adjusted p in the other direction is, else
<i>not shown</i>. Unfinished runs (NaN) are left out and counted.</p>
<h2>Verdicts</h2>
<table>{_row("comparison", "claim", "claimed in", "Holm p", "verdict", header=True)}{summary}
</table>
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


def write_report(
    results: ExperimentResults, out_dir: Path, rng: np.random.Generator | None = None
) -> Path:
    """Write `index.html`, its PNG figures, `values.csv` and `report.json` into `out_dir`.

    Args:
        results: the experiment's per-run values.
        out_dir: the report's folder, created if needed.
        rng: the bootstraps' generator; by default seeded with REPORT_SEED, so a report of
            the same results is the same.

    Returns:
        The path of `index.html`.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    report = analyse(results, rng if rng is not None else np.random.default_rng(REPORT_SEED))
    remove_figures(out_dir)  # an earlier report's: its claims may have been others
    figures = save_figures(results, out_dir)
    write_values_csv(results, out_dir / "values.csv")
    (out_dir / "report.json").write_text(json.dumps(to_json(report), indent=2, allow_nan=False))
    index = out_dir / "index.html"
    index.write_text(_page(report, figures), encoding="utf-8")
    return index
