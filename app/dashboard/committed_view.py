"""What the Experiments tab shows of the committed reports, without viser: the reports with
their verdict tallies, the thesis's answers, one report's claims, a claim's runs as a picture,
and the small read-only server of the reports' pages.

The tallies and the answers are `app.experiments.questions`' (the same words as
docs/experiments/README.md); the claims' cells are `experiment_verdicts`' (the same badges and
layout as the local runs' verdicts, narrow enough for the side panel).
"""

from __future__ import annotations

import functools
import html
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import numpy as np

from app.dashboard.committed import EXPLORATORY, Claim, CommittedReport, Shelf
from app.dashboard.experiment_verdicts import CLAIM_HEADER, KINDS, badge, whole
from app.experiments.questions import answer_rows, tally
from app.experiments.report_text import format_number

NO_REPORTS = "(no committed reports)"
NO_CLAIMS = "(no claims)"
ANSWER_COLUMNS = ("question", "small", "thesis", "decisive")


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _tip(text: str) -> str:
    return html.escape(text).replace("|", "&#124;")


def key(report: CommittedReport) -> str:
    """A report as the Report dropdown names it: NAME-SCALE, its folder."""
    return report.name


def reports_table(shelf: Shelf, pages: str = "") -> str:
    """Every committed report with its verdict tally (pre-registered, post hoc apart,
    exploratory counted), and a ⚠ row per folder that could not be read.

    `pages`: the URL the report folders are served under ('' for none)."""
    if shelf.missing:
        return shelf.missing
    rows = ["| report | verdicts |", "|---|---|"]
    for report in shelf.reports:
        name = whole(f"{report.report.experiment} · {report.report.scale}")
        if pages:
            name = f'<a href="{pages}{report.name}/index.html" target="_blank">{name}</a>'
        comparisons = report.raw.get("comparisons", [])
        rows.append(f"| {name} | {_cell(tally(comparisons))} |")
    rows += [f"| ⚠ {folder} | {_cell(problem)} |" for folder, problem in shelf.problems]
    if not shelf.reports and not shelf.problems:
        return "No committed reports in docs/experiments."
    return "\n".join(rows)


def answers_table(shelf: Shelf) -> str:
    """The thesis's questions: a row per question, its answer at small and thesis scale and in
    its decisive experiment (docs/experiments/README.md's first table, in four columns)."""
    if shelf.missing:
        return ""
    rows = ["| " + " | ".join(ANSWER_COLUMNS) + " |", "|---" * len(ANSWER_COLUMNS) + "|"]
    for row in answer_rows(shelf.by_key()):
        tip = f"{row.claim.replace('`', '')}; small: {row.delta}; other claims: {row.others}"
        question = f'<span title="{_tip(tip)}">{html.escape(row.question)}</span>'
        cells = [question, row.small, row.thesis, row.decisive]
        rows.append("| " + " | ".join(f"<small>{_cell(c)}</small>" for c in cells) + " |")
    return "\n".join(rows)


def _runs(report: CommittedReport) -> str:
    """Each arm's runs in values.csv (a run counted when it has any finite value)."""
    runs: dict[str, set[int]] = {arm.name: set() for arm in report.report.arms}
    for (arm, _, _), by_seed in report.values.items():
        runs.setdefault(arm, set()).update(s for s, v in by_seed.items() if v == v)
    counts = {arm: len(seeds) for arm, seeds in runs.items()}
    if len(set(counts.values())) == 1:
        return f"{next(iter(counts.values()))} runs per arm"
    return "runs: " + ", ".join(f"{arm} {n}" for arm, n in counts.items())


def header(report: CommittedReport, page: str) -> str:
    """What the report is: experiment, scale, description, source, looks, runs, its page."""
    r = report.report
    looks = ", ".join(str(n) for n in r.looks_made) or "–"
    planned = ", ".join(str(n) for n in r.looks_planned)
    looks_text = f"looks at {looks} seeds per arm" + (
        f" (planned {planned})" if planned and r.looks_planned != r.looks_made else ""
    )
    link = f'<a href="{page}" target="_blank">report page</a> · ' if page else ""
    where = f"docs/experiments/{report.name}/index.html"
    return (
        f"**{html.escape(r.experiment)}** at {r.scale} scale (committed report): "
        f"{html.escape(r.description)}  \n{html.escape(r.source)}; {looks_text}; {_runs(report)}"
        f"  \n{link}`{where}`"
    )


def thesis_cell(claim: Claim) -> str:
    """The thesis's own values of the claim's sides, or the ordering its figure shows."""
    names = claim.side_names()
    values = [side.thesis.value if side.thesis else None for side in (claim.a, claim.b)]
    if all(v is None for v in values):
        sign = {"greater": ">", "less": "<", "equivalent": "≈"}.get(claim.direction, "vs")
        return f"thesis: {names[0]} {sign} {names[1]}"
    shown = [f"{n} {format_number(v)}" for n, v in zip(names, values, strict=True)]
    return "thesis: " + ", ".join(shown)


def claim_row(claim: Claim) -> list[str]:
    """One claim's cells: name (sentence in its tooltip) over Δ [interval] and the thesis's
    value; look and runs; verdict with its labels."""
    iv = claim.interval
    delta = f"{format_number(claim.difference)} [{format_number(iv.low)}, {format_number(iv.high)}]"
    tip = f"{claim.claim} ({claim.source})"
    name = f'<span title="{_tip(tip)}" style="white-space:nowrap">{html.escape(claim.name)}</span>'
    first = f"{name}<br><small>{whole(delta)}<br>{whole(thesis_cell(claim))}</small>"
    look = f"look {claim.look}" if claim.look is not None else "–"
    runs = f"{whole(look)}<br>{whole(f'{claim.runs[0]}, {claim.runs[1]}')}"
    if claim.verdict == EXPLORATORY:
        verdict = f"<small>{whole('exploratory')}</small>"
    else:
        verdict = badge(claim.verdict)
    if claim.post_hoc:
        verdict += f"<br><small>{whole('post hoc')}</small>"
    need = claim.need.seeds_per_arm_at_thesis_effect if claim.need else None
    if claim.verdict == "undecided" and need is not None:
        verdict += f"<br><small>{whole(f'need {need:.0f}')}</small>"
    return [first, runs, verdict]


def claims_tables(report: CommittedReport) -> str:
    """The report's claims: the thesis's questions, the sanity claims, then the exploratory
    ones (intervals, no verdicts); a key under them."""
    claims = report.report.comparisons
    if not claims:
        return "This report makes no comparisons."
    groups = [
        (title, [c for c in claims if c.kind == kind and c.family == "primary"])
        for kind, title in KINDS
    ]
    groups.append(
        ("Exploratory: unadjusted 95% intervals, not verdicts", [
            c for c in claims if c.family == EXPLORATORY])
    )  # fmt: skip
    parts = []
    for title, chosen in groups:
        if chosen:
            rows = [f"| {CLAIM_HEADER} | look, runs | verdict |", "|---|---|---|"]
            rows += ["| " + " | ".join(claim_row(c)) + " |" for c in chosen]
            parts.append(f"**{title}** ({len(chosen)})\n\n" + "\n".join(rows))
    parts.append(
        f"<small>Verdicts: {_cell(tally(report.raw.get('comparisons', [])))}. Δ = a − b with its "
        "interval at the level of the look that decided it (family-wise α = "
        f"{report.report.alpha:g} over the primary claims); runs: a, b at that look; post hoc: "
        "declared after data of both its sides; thesis: its printed values, else the ordering "
        "it shows. Hover a claim for its sentence.</small>"
    )
    return "\n\n".join(parts)


def spread_caption(report: CommittedReport, claim: Claim) -> str:
    a, b = report.spread(claim)
    names = claim.side_names()
    seeds = len(report.judged_seeds(claim))
    metric = html.escape(claim.metric_label or claim.metric)
    return (
        f"<small>{html.escape(claim.name)}: each run's {metric}"
        f" from values.csv (the first {seeds} seeds per arm: the runs of look "
        f"{claim.look or 1}); {names[0]} n = {a.size}, {names[1]} n = {b.size}; box: quartiles; "
        "black: mean; dashed: the thesis's value.</small>"
    )


def spread_image(report: CommittedReport, claim: Claim) -> np.ndarray:
    """A claim's runs as an RGBA picture for the side panel: per side a box and its runs (a
    paired claim's two values of a run joined), the mean, the thesis's value if printed."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    a, b = report.spread(claim)
    figure = Figure(figsize=(3.6, 2.4), dpi=200, layout="constrained")
    canvas = FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    colours = ("C0", "C1")
    if claim.paired and a.size == b.size:
        for left, right in zip(a, b, strict=True):
            axes.plot([0, 1], [left, right], color="0.8", linewidth=0.6, zorder=1)
    for position, (values, side, colour) in enumerate(
        zip((a, b), (claim.a, claim.b), colours, strict=True)
    ):
        if values.size:
            axes.boxplot(
                values, positions=[position], widths=0.5, showfliers=False,
                medianprops={"color": colour}, boxprops={"color": "0.5"},
                whiskerprops={"color": "0.5"}, capprops={"color": "0.5"},
            )  # fmt: skip
            jitter = 0.0 if claim.paired else np.linspace(-0.15, 0.15, values.size)
            axes.scatter(position + jitter, values, s=6, color=colour, alpha=0.7, zorder=3)
            axes.plot(position + 0.32, values.mean(), color="black", marker="_", markersize=12)
        if side.thesis is not None and side.thesis.value is not None:
            axes.hlines(side.thesis.value, position - 0.3, position + 0.3, colors="black",
                        linestyles="--", linewidth=1)  # fmt: skip
    names = list(claim.side_names())
    axes.set_xticks([0, 1], [f"{n}\n(n = {v.size})" for n, v in zip(names, (a, b), strict=True)])
    axes.set_xlim(-0.6, 1.6)
    axes.tick_params(labelsize=7)
    axes.set_ylabel(claim.metric_label or claim.metric, fontsize=7)
    axes.set_title(claim.name, fontsize=8)
    axes.grid(alpha=0.3, axis="y")
    canvas.draw()
    return np.asarray(canvas.buffer_rgba()).copy()


class _Quiet(SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: Any) -> None:
        pass


class PageServer:
    """The report folders served read-only on 127.0.0.1 at a free port, so that a report's page
    (index.html with its figures) opens from the tab; viser serves only its own client."""

    def __init__(self, root: Path) -> None:
        handler = functools.partial(_Quiet, directory=str(root))
        self._server = ThreadingHTTPServer(("127.0.0.1", 0), handler)
        self._server.daemon_threads = True
        port = self._server.server_address[1]
        self.url = f"http://127.0.0.1:{port}/"
        self._thread = threading.Thread(
            target=self._server.serve_forever, name="report-pages", daemon=True
        )
        self._thread.start()

    def page(self, report: CommittedReport) -> str:
        return f"{self.url}{report.name}/index.html"

    def close(self) -> None:
        self._server.shutdown()
        self._server.server_close()
