""" "The thesis, reproduced": one page that answers the thesis's questions from the reports.

The page is `docs/experiments/README.md`. Its tables are written from the committed reports
(`docs/experiments/NAME-SCALE/report.json`, from `gnp-lab experiment report --out`), the shipped
specs and the headline questions (`questions.toml`), each between the two marker lines of its
section (`<!-- reproduced: NAME -->` ... `<!-- reproduced: end NAME -->`); everything outside
the markers (what the numbers mean, the discussion) is written by hand and kept as it is.
`gnp-lab experiment reproduced` rewrites the tables; a test checks the committed page agrees
with the committed reports.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from app.experiments import planning
from app.experiments.questions import answers_table, ran, runs_text, tally, verdict_words
from app.experiments.results import FAULT_EFFECTS
from app.experiments.spec import SCALES, ExperimentError, ExperimentSpec
from app.experiments.spec_loading import load_shipped, shipped_names
from app.settings.user_files import loads_json, read_text

PAGE = "README.md"
TITLE = "# The thesis, reproduced\n"
Reports = dict[tuple[str, str], dict[str, Any]]


def begin(section: str) -> str:
    return f"<!-- reproduced: {section} -->"


def end(section: str) -> str:
    return f"<!-- reproduced: end {section} -->"


def load_reports(folder: Path) -> dict[tuple[str, str], dict[str, Any]]:
    """(experiment, scale) -> its report.json, for every `NAME-SCALE/` folder in `folder`."""
    reports = {}
    for path in sorted(folder.glob("*/report.json")):
        try:
            report = loads_json(
                read_text(path, ExperimentError, "report"), ExperimentError, str(path)
            )
            key = (str(report["experiment"]), str(report["scale"]))
        except (ExperimentError, KeyError, TypeError) as error:
            raise ExperimentError(f"{path} is not an experiment report: {error}") from None
        if path.parent.name != f"{key[0]}-{key[1]}":
            raise ExperimentError(f"{path} holds {key[0]} at {key[1]} scale: rename its folder")
        if not (path.parent / "values.csv").is_file():
            raise ExperimentError(f"{path.parent} has no values.csv: publish the whole report")
        reports[key] = report
    return reports


def _number(value: float | None) -> str:
    return "—" if value is None else f"{value:.3f}"


def thesis_text(comparison: dict[str, Any]) -> str:
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


def _ours(comparison: dict[str, Any], decisive: bool = False) -> str:
    """Our means and Δ [interval]; in a decisive design's table Δ corrected for stopping and on
    all the data; for a fault's cost its reading against each side's no-fault level."""
    a, b, interval = comparison["a"], comparison["b"], comparison["interval"]
    if a["mean"] is None or b["mean"] is None:
        return "not run"
    text = f"{a['mean']:.3f} vs {b['mean']:.3f}, Δ {comparison['difference']:+.3f}"
    if interval["low"] is not None:
        text += f" [{interval['low']:+.3f}, {interval['high']:+.3f}]"
    stopping = comparison.get("stopping")
    if decisive and stopping and stopping["median_unbiased"] is not None:
        text += (
            f"; corrected for stopping at look {stopping['look']}: "
            f"{stopping['median_unbiased']:+.3f} (median-unbiased), "
            f"{stopping['conditional']:+.3f} (given the look)"
        )
        if stopping["all_data"]:
            more = stopping["all_data"]
            text += f"; all {more['seeds']} seeds per arm: Δ {more['difference']:+.3f}"
    relative = comparison.get("relative_reading")
    if relative and relative["low"] is not None:
        text += (
            f"; against each side's no-fault level (exploratory): "
            f"{100 * relative['difference']:+.2f} pp [{100 * relative['low']:+.2f}, "
            f"{100 * relative['high']:+.2f}]"
        )
    return text


def _verdict(comparison: dict[str, Any]) -> str:
    """The verdict with the runs behind it, and for an undecided claim the seeds it would need."""
    if not ran(comparison):
        return f"**{comparison['verdict']}** (not run)"
    used = runs_text(comparison)
    need = comparison.get("need")
    if comparison["verdict"] == "undecided" and need:
        seeds = need["seeds_per_arm_at_thesis_effect"]
        if seeds is not None:
            used += f"; 80% power at {_margin_words(comparison)}: {seeds:.0f} seeds per arm"
    return f"{verdict_words(comparison)} ({used})"


def _margin_words(comparison: dict[str, Any]) -> str:
    """What the claim's margin is: the thesis's printed effect or a declared one."""
    margin = comparison.get("margin") or {}
    if margin.get("basis") == "thesis":
        return "the thesis's printed effect"
    if "smallest effect" in (margin.get("source") or ""):
        return "the smallest effect of interest"
    return "the declared margin"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


Keep = Callable[[dict[str, Any], dict[str, Any]], bool]  # (claim, its report)


def claims_tables(
    reports: Reports, keep: Keep, experiments: str = "thesis", names: tuple[str, ...] = ()
) -> str:
    """A table per shipped experiment of `experiments` kind ("thesis" or "beyond"), or of the
    experiments `names`, of its claims that `keep` picks: a row per claim, our numbers and
    verdict per scale run."""
    out = []
    for name in names or shipped_names():
        scales = [s for s in SCALES if (name, s) in reports and s != "smoke"]
        spec = load_shipped(name)
        if not names and spec.kind != experiments:
            continue
        if not scales:
            out.append(f"### {name}\n\nNot run yet at `small` or `thesis` scale.\n")
            continue
        # a claim per row, matched by name: a report written before a claim was added lacks it
        by_scale = [
            {c["name"]: c for c in reports[name, s]["comparisons"] if keep(c, reports[name, s])}
            for s in scales
        ]
        claims = {c: None for found in by_scale for c in found}  # first seen first, no repeats
        if not claims:
            continue
        links = ", ".join(f"[{s}]({name}-{s}/index.html)" for s in scales)
        tallies = "; ".join(f"{s}: {tally(list(found.values()))}" for s, found in zip(
            scales, by_scale, strict=True))  # fmt: skip
        out.append(f"### {name}\n\n{spec.description}. Source: {spec.source}.\n")
        out.append(f"Reports: {links}. Verdicts: {tallies}.\n")
        head = ["claim", "thesis"]
        for scale in scales:
            head += [f"ours, {scale}: a vs b, Δ [interval]", f"verdict, {scale}"]
        out.append("| " + " | ".join(head) + " |")
        out.append("|" + "---|" * len(head))
        for claim in claims:
            comparison = next(found[claim] for found in by_scale if claim in found)
            row = [comparison["claim"], thesis_text(comparison)]
            for found, scale in zip(by_scale, scales, strict=True):
                same = found.get(claim)
                missing = ["—", f"not in the {scale} report"]
                row += [_ours(same, spec.design is not None), _verdict(same)] if same else missing
            out.append("| " + " | ".join(_cell(c) for c in row) + " |")
        out.append("")
    return "\n".join(out) + ("\n" if out else "")


def short_count(n: float) -> str:
    """6000000000 -> '6G'."""
    for unit, size in (("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if n >= size:
            return f"{n / size:.3g}{unit}"
    return f"{n:g}"


def cost_table() -> str:
    """Every shipped experiment's work per scale (its default seeds) and what it measured on
    this machine, then the thesis's experiments at `thesis` scale in all."""
    out = [
        "| experiment | scale | runs (default seeds) | robot-steps (training) "
        "| trial-steps (implementation) | measured or estimated |",
        "|---|---|---|---|---|---|",
    ]
    total = [0, 0, 0]
    for name in shipped_names():
        spec = load_shipped(name)
        for scale, sizes in spec.scales.items():
            cost = planning.work(spec, scale)
            out.append(
                f"| {name} | {scale} | {cost.runs} | {short_count(cost.robot_steps)} "
                f"| {short_count(cost.trial_steps)} | {_cell(sizes.measured or '—')} |"
            )
            if scale == "thesis" and spec.kind == "thesis":
                total = [
                    total[0] + cost.runs,
                    total[1] + cost.robot_steps,
                    total[2] + cost.trial_steps,
                ]
    runs, robot, trials = total
    out.append(
        f"\nThe thesis's experiments at `thesis` scale, default seeds: {runs} runs, "
        f"{short_count(robot)} robot-steps of training and {short_count(trials)} trial-steps "
        f"of implementation ({short_count(robot + trials)} simulated steps)."
    )
    return "\n".join(out) + "\n"


def spent(folder: Path, spec: ExperimentSpec, scale: str) -> tuple[int, int, int]:
    """(runs, robot-steps, trial-steps) behind a committed report: the runs and the conditions
    its `values.csv` holds values of, at the spec's sizes (a condition never run is not paid)."""
    runs: set[tuple[str, int]] = set()
    conditions: set[tuple[str, int, str]] = set()
    with (folder / "values.csv").open(newline="") as handle:
        for arm, seed, condition, _, value in list(csv.reader(handle))[1:]:
            if math.isfinite(float(value)):
                runs.add((arm, int(seed)))
                if condition:
                    conditions.add((arm, int(seed), condition))
    by_name = {c.name: c for c in spec.conditions}
    robot = sum(planning.training_steps(spec.run_config(a, scale, s)) for a, s in runs)
    trials = sum(
        planning.trial_steps(
            spec.condition_settings(by_name[c], spec.run_config(a, scale, s), scale)
        )
        for a, s, c in conditions
    )
    return len(runs), robot, trials


def spent_table(reports: Reports, folder: Path) -> str:
    """What each committed report cost: looks, runs, simulated steps, measured time."""
    out = [
        "| report | looks (seeds per arm) | runs | robot-steps | trial-steps | measured |",
        "|---|---|---|---|---|---|",
    ]
    for (name, scale), report in sorted(reports.items()):
        spec = load_shipped(name)
        if scale not in spec.scales:
            continue
        runs, robot, trials = spent(folder / f"{name}-{scale}", spec, scale)
        looks = ", ".join(str(s) for s in report["looks_made"])
        out.append(
            f"| [{name}-{scale}]({name}-{scale}/index.html) | {looks} | {runs} "
            f"| {short_count(robot)} | {short_count(trials)} "
            f"| {_cell(spec.scales[scale].measured or '—')} |"
        )
    return "\n".join(out) + "\n"


def _against_control(c: dict[str, Any], report: dict[str, Any]) -> bool:
    """A claim on what a fault costs: fault_effect, or a fault condition against the control."""
    return c["metric"] in FAULT_EFFECTS or (
        report.get("control") is not None and c.get("condition_b") == report["control"]
    )


def _every(_c: dict[str, Any], _report: dict[str, Any]) -> bool:
    return True


READING = (
    "Each claim compares two sides on Δ = mean(a) − mean(b) over runs (seeds). Its interval "
    "is a two-sided t-interval at level α/r (α = 0.05, r the primary claims holding a share; "
    "Holm over the experiment's primary claims, both directions in one family; widened by the "
    "O'Brien–Fleming boundary of its look in an adaptive run), so under normal theory the "
    "chance of any wrong held or reversed is at most 5% per experiment, not over the page. "
    "`held`: the interval lies on the claimed side of 0; `reversed`: on the other side; "
    "`ruled out`: it excludes the effect the claim names: where the thesis prints both sides' "
    "values, its own Δ under both readings, absolute and relative to its baseline (a reading no "
    "run could reach is dropped; values pointing against the claim leave nothing to rule out); "
    "elsewhere the smallest effect of interest the file declares (none declared: nothing is "
    "ruled out); "
    "`undecided`: none of these, with the seeds per arm that 80% power would need at that "
    "effect (the label says which). `post hoc`: the claim or its margin was declared after "
    "data of both its sides had been committed; such verdicts are counted apart. "
    "`exploratory` (decisive experiments): an unadjusted interval, never a verdict. "
    "`not run`: the claim was added after the report's runs (no values yet).\n"
)


def _kind(kind: str) -> Callable[[Reports, Path], str]:
    """The section of every thesis experiment's claims of one kind, with their tally."""

    def write(reports: Reports, _folder: Path) -> str:
        claims = [
            c
            for (name, scale), report in reports.items()
            if scale == "small" and load_shipped(name).kind == "thesis"
            for c in report["comparisons"]
            if c.get("kind") == kind
        ]
        head = f"{len(claims)} claims at `small`: {tally(claims)}.\n\n"
        return head + claims_tables(reports, lambda c, _: c.get("kind") == kind)

    return write


Section = Callable[[Reports, Path], str]  # (the reports, their folder) -> the section's text

#: The page's written sections, in page order: name -> what writes it from the reports.
SECTIONS: dict[str, Section] = {
    "answers": lambda r, _: READING + "\n" + answers_table(r),
    "reward-source": lambda r, _: claims_tables(r, _every, names=("ch2-reward-source",)),
    "fault-effects": lambda r, _: (
        claims_tables(r, _against_control) + claims_tables(r, _against_control, "beyond")
    ),
    "sanity": _kind("sanity"),
    "questions": _kind("question"),
    "beyond": lambda r, _: claims_tables(r, _every, "beyond"),
    "spent": spent_table,
    "costs": lambda _r, _: cost_table(),
}


def sections(folder: Path) -> dict[str, str]:
    """Each written section of the page, from the reports in `folder`."""
    reports = load_reports(folder)
    return {name: write(reports, folder) for name, write in SECTIONS.items()}


def new_page() -> str:
    """A page with a title and every section's markers, in order."""
    return TITLE + "".join(f"\n{begin(s)}\n{end(s)}\n" for s in SECTIONS)


def written(text: str) -> dict[str, str]:
    """Section -> what stands between its markers in `text`; raises if they are not there once
    each, in the page's order."""
    found, at = {}, 0
    for section in SECTIONS:
        first, last = begin(section), end(section)
        if text.count(first) != 1 or text.count(last) != 1 or text.index(first) < at:
            raise ExperimentError(
                f"the page must hold the marker lines of section {section!r} once each, in "
                f"the order {', '.join(SECTIONS)}"
            )
        start = text.index(first) + len(first)
        at = text.index(last)
        if at < start:
            raise ExperimentError(f"the end marker of section {section!r} comes before its start")
        found[section] = text[start:at]
    return found


def write_page(folder: str | Path) -> Path:
    """Rewrite the sections of `folder`/README.md from the reports in `folder`, keeping the
    hand-written text around them (a new page gets a title and every section)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ExperimentError(f"no folder {folder}")
    page = folder / PAGE
    text = page.read_text() if page.exists() else new_page()
    old = written(text)
    new = sections(folder)
    for section, content in new.items():
        text = text.replace(
            begin(section) + old[section] + end(section),
            f"{begin(section)}\n{content}{end(section)}",
        )
    page.write_text(text)
    return page
