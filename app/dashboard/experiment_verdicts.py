"""The Experiments tab's verdicts and stages, as markdown for viser (no viser here).

The verdict tables are the report's own numbers (`report.analyse`): the thesis's questions,
then the sanity claims, each claim with Δ and its interval, the runs on each side at the look
that decided it, its verdict marked in the report's colours, and for an undecided claim the
seeds per arm it would need at the thesis's effect. Three columns, the claim's name over its Δ
in the first, none broken inside a word or number, so that the table reads in the 370 px side
panel (a claim's name in a column of its own was broken at every hyphen); the claim's sentence
and its arms' means are in the claim's tooltip.
The stages table is `report.stages_json`: per look the seeds per arm, the runs each arm had,
what that look decided and how many claims stayed open.
"""

from __future__ import annotations

import html
import math
from collections import Counter
from dataclasses import dataclass
from typing import Any

from pydantic import ValidationError

from app.dashboard.controls import DashboardInputError
from app.experiments.adaptive import DEFAULT_MAX_SEEDS, DEFAULT_STAGE_SEEDS
from app.experiments.report import ComparisonReport, ExperimentReport, tally
from app.experiments.report_json import stages_json
from app.experiments.report_text import format_number, interval_level, looks_text
from app.experiments.results import VERDICT_COLOURS, VERDICTS
from app.experiments.sequential import POWER, Design
from app.experiments.spec_tables import ScaleSpec
from app.settings.loading import describe_problems

KINDS = (("question", "The thesis's questions"), ("sanity", "Within one arm (sanity)"))
CLAIM_HEADER = "claim: Δ [interval]"
NOWRAP = "white-space:nowrap"


@dataclass(frozen=True)
class AdaptiveRequest:
    """What the Start control asks for: adaptive or not, with its stage sizes as typed."""

    adaptive: bool = False
    stage_seeds: float = DEFAULT_STAGE_SEEDS
    max_seeds: float = DEFAULT_MAX_SEEDS

    def design(self) -> Design | None:
        """The looks of the adaptive run (None: not adaptive), checked as `run_adaptive` does.

        Raises:
            DashboardInputError: a field is not a seed count an experiment takes (a scale's
                `seeds`), or the stages cannot be used (`Design.staged`).
        """
        if not self.adaptive:
            return None
        stage = seed_count(self.stage_seeds, "stage seeds")
        most = seed_count(self.max_seeds, "max seeds")
        try:
            return Design.staged(stage, most)
        except ValueError as error:
            raise DashboardInputError(f"adaptive: {error}") from None


def seed_count(value: float, label: str) -> int:
    """`value` as a seed count, checked by building the model that holds one (`ScaleSpec`)."""
    try:
        seeds = ScaleSpec(seeds=value).seeds  # type: ignore[arg-type]  # pydantic checks it
    except ValidationError as error:
        problem = describe_problems(error).removeprefix("seeds: ")
        raise DashboardInputError(f"{label}: {problem}") from None
    assert seeds is not None
    return seeds


def badge(verdict: str) -> str:
    """A verdict as a coloured label, in the report's colours."""
    background, colour = VERDICT_COLOURS[verdict] if verdict in VERDICTS else ("#fff", "#000")
    style = (
        f"background:{background};color:{colour};font-weight:700;padding:0 4px;"
        "border-radius:3px;white-space:nowrap"
    )
    return f'<span style="{style}">{html.escape(verdict)}</span>'


def _attribute(text: str) -> str:
    """Text for an HTML attribute inside a markdown table cell."""
    return html.escape(text).replace("|", "&#124;")


def _seeds(seeds: float) -> str:
    if math.isnan(seeds):
        return "–"  # no effect declared to power for
    return "∞" if math.isinf(seeds) else f"{seeds:.0f}"


def _claim_cell(c: ComparisonReport) -> str:
    names = list(c.comparison.side_names())
    if c.comparison.within_arm:
        names = [f"{c.arm_a.name} ({name})" for name in names]
    sides = ", ".join(
        f"{name} {format_number(s.mean)} ± {format_number(s.sd)}"
        for name, s in zip(names, (c.stats.a, c.stats.b), strict=True)
    )
    tip = f"{c.sentence} ({c.comparison.source}); mean ± sd: {sides}"
    name = html.escape(c.comparison.name)
    return f'<span title="{_attribute(tip)}" style="{NOWRAP}">{name}</span>'


def whole(text: str) -> str:
    """`text` kept on one line (escaped)."""
    return f'<span style="{NOWRAP}">{html.escape(text)}</span>'


def claim_row(c: ComparisonReport) -> list[str]:
    """One claim's cells: the claim over its Δ [interval], runs (a, b), verdict (and what it
    needs)."""
    iv = c.claim.judged.interval
    delta = f"{format_number(iv.difference)} [{format_number(iv.low)}, {format_number(iv.high)}]"
    verdict = badge(c.claim.verdict)
    if c.claim.post_hoc:
        verdict += f"<br><small>{whole('post hoc')}</small>"
    if c.claim.verdict == "undecided" and c.claim.need is not None:
        verdict += f"<br><small>{whole(f'need {_seeds(c.claim.need.seeds_at_thesis)}')}</small>"
    runs = whole(f"{c.claim.runs[0]}, {c.claim.runs[1]}")
    return [f"{_claim_cell(c)}<br><small>{whole(delta)}</small>", runs, verdict]


def verdict_tables(report: ExperimentReport) -> str:
    """The questions' and the sanity claims' tables, with a key under them."""
    if not report.comparisons:
        return "This experiment makes no comparisons."
    parts = []
    groups = [
        (title, tuple(c for c in report.of_kind(kind) if c.comparison.family == "primary"))
        for kind, title in KINDS
    ]
    groups.append(
        ("Exploratory: unadjusted 95% intervals, not verdicts", report.of_family("exploratory"))
    )
    for title, claims in groups:
        if not claims:
            continue
        rows = [f"| {CLAIM_HEADER} | runs | verdict |", "|---|---|---|"]
        rows += ["| " + " | ".join(claim_row(c)) + " |" for c in claims]
        parts.append(f"**{title}** ({len(claims)})\n\n" + "\n".join(rows))
    tallies = []
    for group, counts in tally(report).items():
        words = ", ".join(f"{counts[v]} {badge(v)}" for v in VERDICTS if counts.get(v))
        tallies += [f"{group}: {words}"] if words else []
    primary = report.of_family("primary")
    levels = sorted({interval_level(c.claim) for c in primary})
    parts.append(
        f"<small>{'; '.join(tallies) or 'no primary claim'}. Δ = a − b, its interval at the "
        f"level of the look that decided it ({', '.join(levels)}; family-wise α = "
        f"{report.alpha:g} over the primary claims and looks); post hoc: the claim or its "
        "margin was declared after data of both its sides; "
        f"runs: a, b at that look; need: seeds per arm for {100 * POWER:.0f}% power at the "
        "thesis's effect (– none declared). Hover a claim for its sentence.</small>"
    )
    return "\n\n".join(parts)


def _decided_cell(decided: list[dict[str, Any]]) -> str:
    if not decided:
        return "–"
    counts = Counter(d["verdict"] for d in decided)
    names = ", ".join(f"{d['name']} ({d['verdict']})" for d in decided)
    counted = " ".join(f"{counts[v]} {badge(v)}" for v in VERDICTS if counts[v])
    return f'<span title="{_attribute(names)}">{counted}</span>'


def stages_table(report: ExperimentReport) -> str:
    """The looks made: seeds per arm, runs per arm, what each decided, how many stay open."""
    if not report.results.looks:
        return f"**Stages**: {looks_text(report)}."
    rows = ["| look | seeds | runs | decided | open |", "|---|---|---|---|---|"]
    for stage in stages_json(report):
        runs = " · ".join(whole(f"{arm} {n}") for arm, n in stage["runs"].items())
        cells = [str(stage["look"]), str(stage["seeds_per_arm"]), runs]
        cells += [_decided_cell(stage["decided"]), str(stage["open_after"])]
        rows.append("| " + " | ".join(cells) + " |")
    return (
        f"**Stages** ({looks_text(report)})\n\n" + "\n".join(rows) + "\n\n<small>seeds: per "
        "arm, from seed 0; runs: each arm's finished runs; decided: the claims that look "
        "decided (hover for their names); open: claims still undecided after it.</small>"
    )
