""" "The thesis, reproduced": one page with a row per claim, the thesis beside us at every scale.

The page is `docs/experiments/README.md`. Its tables are written from the committed reports
(`docs/experiments/NAME-SCALE/report.json`, from `gnp-lab experiment report --out`) and
the shipped specs, between two marker lines; everything outside the markers (the discussion of
each claim) is written by hand and kept as it is. `gnp-lab experiment reproduced` rewrites the
tables; a test checks the committed page agrees with the committed reports.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from app.experiments import planning
from app.experiments.results import VERDICTS
from app.experiments.spec import SCALES, ExperimentError, load_shipped, shipped_names

PAGE = "README.md"
BEGIN = "<!-- reproduced: tables written by `gnp-lab experiment reproduced`; edit outside -->"
END = "<!-- reproduced: end of the written tables -->"
TITLE = "# The thesis, reproduced\n"


def load_reports(folder: Path) -> dict[tuple[str, str], dict[str, Any]]:
    """(experiment, scale) -> its report.json, for every `NAME-SCALE/` folder in `folder`."""
    reports = {}
    for path in sorted(folder.glob("*/report.json")):
        try:
            report = json.loads(path.read_text())
            key = (str(report["experiment"]), str(report["scale"]))
        except (OSError, ValueError, KeyError, TypeError) as error:
            raise ExperimentError(f"{path} is not an experiment report: {error}") from None
        if path.parent.name != f"{key[0]}-{key[1]}":
            raise ExperimentError(f"{path} holds {key[0]} at {key[1]} scale: rename its folder")
        reports[key] = report
    return reports


def _number(value: float | None) -> str:
    return "—" if value is None else f"{value:.3f}"


def _thesis(comparison: dict[str, Any]) -> str:
    """The thesis's own numbers for a claim, or its figure's ordering when it gives none."""
    a, b = comparison["a"], comparison["b"]
    names = comparison.get("sides") or (a["name"], b["name"])  # paired: conditions or metrics
    if a["thesis"] is None and b["thesis"] is None:
        sign = {"greater": ">", "less": "<", "equivalent": "≈"}[comparison["direction"]]
        return f"{names[0]} {sign} {names[1]} ({comparison['source']})"
    return (
        f"{names[0]} {_number(a['thesis'] and a['thesis']['value'])}, "
        f"{names[1]} {_number(b['thesis'] and b['thesis']['value'])} ({comparison['source']})"
    )


def _ours(comparison: dict[str, Any]) -> str:
    a, b, interval = comparison["a"], comparison["b"], comparison["interval"]
    if a["mean"] is None or b["mean"] is None:
        return "not run"
    if interval["low"] is None:
        return f"{a['mean']:.3f} vs {b['mean']:.3f}, Δ {comparison['difference']:+.3f}"
    return (
        f"{a['mean']:.3f} vs {b['mean']:.3f}, Δ {comparison['difference']:+.3f} "
        f"[{interval['low']:+.3f}, {interval['high']:+.3f}]"
    )


def _verdict(comparison: dict[str, Any]) -> str:
    runs = comparison["runs"]
    if not (runs[0] and runs[1]):
        return f"**{comparison['verdict']}** (not run)"
    used = (
        f"{runs[0]} + {runs[1]} runs"
        if runs[0] != runs[1] or not comparison["paired"]
        else (f"{runs[0]} runs")
    )
    need = comparison.get("need")
    if comparison["verdict"] == "undecided" and need:
        seeds = need["seeds_per_arm_at_thesis_effect"]
        if seeds is not None:
            used += f"; 80% power at the thesis's effect: {seeds:.0f} seeds per arm"
    return f"**{comparison['verdict']}** ({used})"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _tally(comparisons: list[dict[str, Any]]) -> str:
    counts = {v: 0 for v in VERDICTS}
    for c in comparisons:
        counts[c["verdict"]] += 1
    return ", ".join(f"{n} {v}" for v, n in counts.items() if n)


def claims_tables(
    reports: dict[tuple[str, str], dict[str, Any]], kind: str, experiments: str = "thesis"
) -> str:
    """A table per shipped experiment of `experiments` kind ("thesis" or "beyond") of its
    claims of one kind ("question" or "sanity"): a row per claim, our numbers and verdict per
    scale run."""
    out = []
    for name in shipped_names():
        scales = [s for s in SCALES if (name, s) in reports and s != "smoke"]
        spec = load_shipped(name)
        if spec.kind != experiments:
            continue
        if kind == "question":
            out.append(f"### {name}\n\n{spec.description}. Source: {spec.source}.\n")
        if not scales:
            if kind == "question":
                out.append("Not run yet at `small` or `thesis` scale.\n")
            continue
        # a claim per row, matched by name: a report written before a claim was added lacks it
        by_scale = [
            {c["name"]: c for c in reports[name, s]["comparisons"] if c.get("kind") == kind}
            for s in scales
        ]
        claims = {c: None for found in by_scale for c in found}  # first seen first, no repeats
        if not claims:
            continue
        if kind == "sanity":
            out.append(f"### {name}\n")
        links = ", ".join(f"[{s}]({name}-{s}/index.html)" for s in scales)
        tallies = "; ".join(f"{s}: {_tally(list(found.values()))}" for s, found in zip(
            scales, by_scale, strict=True))  # fmt: skip
        out.append(f"Reports: {links}. Verdicts: {tallies}.\n")
        head = ["claim", "thesis"]
        for scale in scales:
            head += [f"ours, {scale}: a vs b, Δ [interval]", f"verdict, {scale}"]
        out.append("| " + " | ".join(head) + " |")
        out.append("|" + "---|" * len(head))
        for claim in claims:
            comparison = next(found[claim] for found in by_scale if claim in found)
            row = [comparison["claim"], _thesis(comparison)]
            for found, scale in zip(by_scale, scales, strict=True):
                same = found.get(claim)
                missing = ["—", f"not in the {scale} report"]
                row += [_ours(same), _verdict(same)] if same else missing
            out.append("| " + " | ".join(_cell(c) for c in row) + " |")
        out.append("")
    return "\n".join(out)


def short_count(n: float) -> str:
    """6000000000 -> '6G'."""
    for unit, size in (("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if n >= size:
            return f"{n / size:.3g}{unit}"
    return f"{n:g}"


def cost_table() -> str:
    """Every shipped experiment's work per scale and what it measured on this machine."""
    out = [
        "| experiment | scale | runs | robot-steps (training) | trial-steps (implementation) "
        "| measured |",
        "|---|---|---|---|---|---|",
    ]
    for name in shipped_names():
        spec = load_shipped(name)
        for scale, sizes in spec.scales.items():
            cost = planning.work(spec, scale)
            out.append(
                f"| {name} | {scale} | {cost.runs} | {short_count(cost.robot_steps)} "
                f"| {short_count(cost.trial_steps)} | {_cell(sizes.measured or '—')} |"
            )
    return "\n".join(out) + "\n"


def tallies(reports: dict[tuple[str, str], dict[str, Any]]) -> dict[tuple[str, str], int]:
    """(kind, verdict) -> count over the thesis experiments' committed reports at `small`."""
    counts: dict[tuple[str, str], int] = {}
    thesis = {n for n in shipped_names() if load_shipped(n).kind == "thesis"}
    for (name, scale), report in reports.items():
        if scale != "small" or name not in thesis:
            continue
        for c in report["comparisons"]:
            key = (c.get("kind", "question"), c["verdict"])
            counts[key] = counts.get(key, 0) + 1
    return counts


def tables(folder: Path) -> str:
    """The written part of the page."""
    reports = load_reports(folder)
    counts = tallies(reports)

    def tally(kind: str) -> str:
        found = {v: counts.get((kind, v), 0) for v in VERDICTS}
        total = sum(found.values())
        return f"{total} claims at `small`: " + ", ".join(f"{n} {v}" for v, n in found.items())

    return (
        "## How to read the verdicts\n\n"
        "Each claim compares two sides on Δ = mean(a) − mean(b) over runs (seeds). Its interval "
        "is a two-sided t-interval at level α/r (α = 0.05, r the claims holding a share; Holm "
        "over the experiment's claims, both directions in one family; widened by the "
        "O'Brien–Fleming boundary of its look in an adaptive run). `held`: the interval lies on "
        "the claimed side of 0; `reversed`: on the other side; `ruled out`: it excludes the "
        "thesis's effect (its own Δ relative to its baseline where it prints numbers, else a "
        "smallest effect of interest declared before the runs); `undecided`: none of these, "
        "with the seeds per arm that 80% power would need at the thesis's effect. "
        "`not run`: the claim was added after the report's runs (no values yet).\n\n"
        "## The thesis's questions: method against baseline\n\n"
        f"{tally('question')}.\n\n"
        + claims_tables(reports, "question")
        + "\n## Within one arm: sanity claims\n\n"
        "More broken sensors give less reward, the reward after a fault is below the reward "
        f"before it: claims about one method, apart from the thesis's questions. {tally('sanity')}."
        "\n\n" + claims_tables(reports, "sanity") + "\n## Beyond the thesis\n\n"
        "Our own hypotheses, asked with the same engine: GNP with online RL against neural "
        "controllers evolved by CMA-ES and NEAT, and the analytic physics against pymunk "
        "(equivalence within ±0.02).\n\n"
        + claims_tables(reports, "question", "beyond")
        + claims_tables(reports, "sanity", "beyond")
        + "\n## What each experiment costs\n\n"
        + "Simulated work per scale, and the wall time measured on this machine (2 vCPUs).\n\n"
        + cost_table()
    )


def write_page(folder: str | Path) -> Path:
    """Rewrite the tables of `folder`/README.md from the reports in `folder`, keeping the
    hand-written text around them (a new page gets a title and the tables)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ExperimentError(f"no folder {folder}")
    page = folder / PAGE
    text = page.read_text() if page.exists() else f"{TITLE}\n{BEGIN}\n{END}\n"
    if text.count(BEGIN) != 1 or text.count(END) != 1 or text.index(BEGIN) > text.index(END):
        raise ExperimentError(f"{page} must hold the two marker lines once each, in order")
    head, rest = text.split(BEGIN)
    tail = rest.split(END)[1]
    page.write_text(f"{head}{BEGIN}\n{tables(folder)}{END}{tail}")
    return page
