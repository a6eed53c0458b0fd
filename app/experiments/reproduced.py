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

from app.experiments import runner
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
        sign = ">" if comparison["direction"] == "greater" else "<"
        return f"{names[0]} {sign} {names[1]} ({comparison['source']})"
    return (
        f"{names[0]} {_number(a['thesis'] and a['thesis']['value'])}, "
        f"{names[1]} {_number(b['thesis'] and b['thesis']['value'])} ({comparison['source']})"
    )


def _ours(comparison: dict[str, Any]) -> str:
    a, b = comparison["a"], comparison["b"]
    low, high = comparison["ci"]
    return (
        f"{a['mean']:.3f} vs {b['mean']:.3f}, Δ {comparison['difference']:+.3f} "
        f"[{low:+.3f}, {high:+.3f}]"
    )


def _verdict(comparison: dict[str, Any]) -> str:
    p = comparison["holm_p"] if comparison["verdict"] != "reversed" else None
    q = comparison["holm_p_opposite"]
    shown = f"p = {p:.3g}" if p is not None else f"p(other way) = {q:.3g}"
    return f"**{comparison['verdict']}** ({shown})"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def claims_tables(reports: dict[tuple[str, str], dict[str, Any]]) -> str:
    """A table per shipped experiment: a row per claim, our numbers and verdict per scale run."""
    out = []
    for name in shipped_names():
        scales = [s for s in SCALES if (name, s) in reports and s != "smoke"]
        spec = load_shipped(name)
        out.append(f"### {name}\n\n{spec.description}. Source: {spec.source}.\n")
        if not scales:
            out.append("Not run yet at `small` or `thesis` scale.\n")
            continue
        links = ", ".join(f"[{s}]({name}-{s}/index.html)" for s in scales)
        seeds = ", ".join(f"{len(reports[name, s]['seeds'])} seeds at {s}" for s in scales)
        out.append(f"Reports: {links} ({seeds}).\n")
        head = ["claim", "thesis"]
        for scale in scales:
            head += [f"ours, {scale}: a vs b, Δ [95% CI]", f"verdict, {scale}"]
        out.append("| " + " | ".join(head) + " |")
        out.append("|" + "---|" * len(head))
        # a claim per row, matched by name: a report written before a claim was added lacks it
        by_scale = [{c["name"]: c for c in reports[name, s]["comparisons"]} for s in scales]
        claims = {c: None for found in by_scale for c in found}  # first seen first, no repeats
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
            cost = runner.work(spec, scale)
            out.append(
                f"| {name} | {scale} | {cost.runs} | {short_count(cost.robot_steps)} "
                f"| {short_count(cost.trial_steps)} | {_cell(sizes.measured or '—')} |"
            )
    return "\n".join(out) + "\n"


def tables(folder: Path) -> str:
    """The written part of the page."""
    reports = load_reports(folder)
    return (
        "## Every claim, the thesis beside us\n\n"
        "Each claim is one-sided (a is claimed better than b, or the reverse where the thesis "
        "says so); Δ = mean(a) − mean(b) over runs with its bootstrap 95% CI; p is Welch's "
        "one-sided test (paired by seed for one arm against itself), Holm-adjusted over the "
        "experiment's claims. `held`: significant in "
        "the claimed direction; `reversed`: significant the other way; `not shown`: neither.\n\n"
        + claims_tables(reports)
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
