"""An experiment's report as a static page: `index.html` with its PNG figures, beside the
per-run values (`values.csv`) and the statistics as JSON (`report.json`), in one folder.

The statistics are `app.experiments.report`'s (in JSON `report_json`'s, in words
`report_text`'s); this module only writes them out.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

from app.experiments.figures import DeltaBar, FigureFile, SavedFigures, save_figures
from app.experiments.report import (
    ClaimStats,
    ComparisonReport,
    ExperimentReport,
    analyse,
    tally,
    thesis_beside_ours,
)
from app.experiments.report_json import stages_json, to_json
from app.experiments.report_text import (
    arm_cost_rows,
    estimate_rows,
    format_number,
    interval_level,
    interval_text,
    looks_text,
    margin_text,
    need_text,
    provenance_text,
    seeds_text,
    sensitivity_text,
    stopping_text,
)
from app.experiments.results import METRICS, VERDICT_COLOURS, VERDICTS, Arm, ExperimentResults
from app.experiments.values import VALUES_COLUMNS, write_values_csv

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


def _declared_cell(claim: ClaimStats) -> str:
    if claim.post_hoc is None:
        return "–"
    return "post hoc" if claim.post_hoc else "pre-registered"


def tally_text(report: ExperimentReport) -> str:
    """'pre-registered: 3 held, 2 undecided; post hoc: 1 ruled out; 4 exploratory'."""
    parts = []
    for group, counts in tally(report).items():
        if counts:
            words = ", ".join(f"{counts[v]} {v}" for v in VERDICTS if v in counts)
            parts.append(f"{group}: {words}")
    explored = len(report.of_family("exploratory"))
    return "; ".join(parts + ([f"{explored} exploratory"] if explored else [])) or "none"


def _comparison_html(report: ComparisonReport, figure: FigureFile | None, sequential: bool) -> str:
    s, claim, c = report.stats, report.claim, report.comparison
    sides = [_arm_name(report.arm_a), _arm_name(report.arm_b)]
    if c.within_arm:  # one arm: each side says its metric or condition
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
        ("declared (commits)", provenance_text(claim)),
        ("the other analysis, same level", sensitivity_text(claim)),
        ("runs (a, b); look", f"{claim.runs[0]}, {claim.runs[1]}; {claim.judged.look + 1}"),
        *estimate_rows(claim),
        (f"{t_test} t (df)", f"{format_number(s.t)} ({format_number(s.df)})"),
    ]  # fmt: skip
    if sequential:  # judged over looks: no fixed-sample p beside the verdict
        rows.append((f"{rank_test} {'W+' if s.paired else 'U'}", format_number(s.rank_statistic)))
    else:
        rows += [
            (f"{t_test} p, one-tailed (other direction), fixed-sample",
             f"{format_number(s.p)} ({format_number(s.p_opposite)})"),
            (f"{rank_test} {'W+' if s.paired else 'U'} (p, one-tailed, fixed-sample)",
             f"{format_number(s.rank_statistic)} ({format_number(s.rank_p)})"),
            (f"Holm-adjusted two-sided {t_test} p, fixed-sample", format_number(claim.holm_p)),
        ]  # fmt: skip
    rows += [
        ("P(improvement)", format_number(s.prob_improvement)),
        ("Hedges' g", format_number(s.hedges_g)),
    ]
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
<h3>{_e(c.name)} {_verdict_html(claim.verdict)}{" post hoc" if claim.post_hoc else ""}</h3>
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
            ("seeds", seeds_text(results)),
            ("looks", looks_text(report)),
            ("verdicts (primary claims)", tally_text(report)),
            ("arms", "; ".join(f"{a.name}: {a.label}" for a in results.arms)),
            ("unit of analysis", "the run (seed): a run's value is its mean over trials"),
        )
    )

    def verdict_rows(claims: tuple[ComparisonReport, ...]) -> str:
        return "".join(
            _row(_e(c.comparison.name), _e(c.sentence), _e(c.comparison.source),
                 _e(f"{format_number(c.stats.difference)} {interval_text(c.claim)}"),
                 _e(f"{c.claim.runs[0]}, {c.claim.runs[1]}"), _verdict_html(c.claim.verdict),
                 _e(_declared_cell(c.claim)), _e(sensitivity_text(c.claim)))
            for c in claims
        )  # fmt: skip

    verdict_head = _row("comparison", "claim", "claimed in", "Δ [interval]", "runs (a, b)",
                        "verdict", "declared", "the other analysis", header=True)  # fmt: skip
    primary = [c for c in report.comparisons if c.comparison.family == "primary"]
    questions = verdict_rows(tuple(c for c in primary if c.comparison.kind == "question"))
    sanity = verdict_rows(tuple(c for c in primary if c.comparison.kind == "sanity"))
    exploratory = verdict_rows(report.of_family("exploratory"))
    summary = (
        f"<h3>The thesis's questions</h3><table>{verdict_head}{questions}</table>"
        if questions
        else ""
    ) + (f"<h3>Within one arm (sanity)</h3><table>{verdict_head}{sanity}</table>" if sanity else "")
    summary += (
        "<h3>Exploratory (unadjusted 95% intervals; not verdicts, never counted)</h3>"
        f"<table>{verdict_head}{exploratory}</table>"
        if exploratory
        else ""
    )
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
        for v, ours in thesis_beside_ours(results)
    )  # fmt: skip
    thesis_header = _row(
        "arm", "metric", "condition", "thesis", "ours: mean ± sd over runs", header=True
    )
    cost_rows = "".join(_row(*map(_e, row)) for row in arm_cost_rows(results))
    cost_section = (
        "<h2>Arms: test return and env-steps</h2><p>Each arm's runs, mean ± sd: the test "
        "return of its final elite and the env-steps its training spent (every episode of "
        "every generation; validation and test episodes not counted).</p><table>"
        + _row("arm", "test return", "env-steps in training", header=True)
        + cost_rows
        + "</table>"
        if cost_rows
        else ""
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
    sequential = bool(results.looks)
    comparisons = "".join(
        _comparison_html(c, f, sequential)
        for c, f in zip(report.comparisons, figures.runs, strict=True)
    )
    corrected = "".join(
        _row(_e(c.comparison.name), _e(stopping_text(c.claim)))
        for c in report.of_family("primary")
        if c.claim.stopping is not None
    )
    if corrected:
        stages += (
            "<h3>Estimates corrected for stopping</h3><p>Δ at the look that decided each "
            "primary claim is biased away from 0 (a claim stops when its data happen to show "
            "a large Δ). Beside it: the median-unbiased estimate under the stagewise ordering "
            "(Jennison &amp; Turnbull 2000, §8.4), the one given the look it stopped at "
            "(conditional; Troendle &amp; Yu 1999), both from the claim's own boundaries under "
            "the normal approximation, and Δ on every seed both sides ran where the design ran "
            "more (descriptive). None of them changes a verdict.</p><table>"
            + _row("claim", "Δ at the stopping look; corrected; all the data", header=True)
            + corrected
            + "</table>"
        )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>{_e(results.name)} ({_e(results.scale)})</title>
<style>{_CSS}</style></head><body>
<h1>{_e(results.name)}</h1>
<p>{_e(results.description)}</p>
<table class="facts">{facts}</table>
<p>Each arm is run with the same seeds; the unit of analysis is the run, so n counts runs,
never trials. Arms are compared as independent samples (Welch) unless the experiment declares a
claim paired by seed; one arm compared across two conditions or metrics has the same runs on
both sides and is tested paired (paired t). Each claim's verdict rests on an interval of
Δ = mean(a) − mean(b): <i>held</i> when it lies on the claimed side of 0 (an equivalence claim:
inside ±margin), <i>reversed</i> when it lies on the other side, <i>ruled out</i> when it
excludes the effect named in the claim's "effect ruled out" row, else <i>undecided</i>, with the
seeds per arm that 80% power would need at that effect and at ours, and their cost in
core-hours. Where the thesis prints both sides' values, that effect is the thesis's own, read
absolute and relative to the baseline, and a claim is ruled out only if its interval excludes
both (a reading no run could reach is dropped; printed values pointing the other way leave
nothing to rule out); where it prints none, it is the smallest effect of interest declared in
the experiment's file, and says so. The intervals are two-sided t-intervals at level α/r
(α = {report.alpha:g}, r the primary claims holding a share: Holm over the primary claims,
both directions in one family; a claim held or reversed hands its share on, one ruled out keeps
it) widened, for an adaptive run, by the Lan–DeMets O'Brien–Fleming boundary of the look, so
under the normal approximation the chance of any wrong held or reversed among this
experiment's primary claims, over all its looks, is at most α (per experiment, not across
experiments). Exploratory claims show an unadjusted 95% interval and no verdict. A verdict
whose claim or margin was declared after data of both its sides had been committed is
labelled <i>post hoc</i> and counted apart. "The other analysis" is the same claim paired by
seed when it is declared unpaired (and unpaired when paired), at the verdict's level: a
sensitivity check, not a verdict. Mann–Whitney U (Wilcoxon signed-rank when paired),
P(improvement) = P(X<sub>a</sub> &gt; X<sub>b</sub>) + ½ P(X<sub>a</sub> = X<sub>b</sub>)
(rliable) and Hedges' g describe each claim too; a report judged over looks shows no
fixed-sample p (its boundaries would contradict it), a one-look report labels its p-values
fixed-sample. A claim on a fault's cost is also read against each side's own no-fault level
(relative_fault_effect, exploratory, an unadjusted 95% interval). Unfinished runs (NaN) are
left out and counted.</p>
<h2>Verdicts</h2>
{summary}
{stages}
{thesis_section}
{cost_section}
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
