"""A pre-registered design's results between its looks: judged, and carried.

A decisive experiment (`[design]` in its spec) is judged only at its planned looks: at 25 seeds
per arm, then 50, and so on. Its runs finish one by one in between, on whatever machine runs
them, and run files stay on that machine. So a report of such an experiment has two parts:

- the *judged* results: every seed up to the last look made (the run's summary says which),
  from which the verdicts, the tables and the figures come; none before the first look;
- the *carried* results: every finished run, those of a stage still running included, written
  to `values.csv` and the ledger so that a fresh clone continues the stage without rerunning them.

`report --from-values` judges the same seeds again: those up to the last look in the
`report.json` beside the values.
"""

from __future__ import annotations

import dataclasses
import html
from pathlib import Path

from app.experiments import harvest, layout, ledger
from app.experiments.ledger import Ledger
from app.experiments.results import ExperimentResults
from app.experiments.spec import ExperimentError, ExperimentSpec
from app.experiments.summary import SummaryError, read_summary
from app.experiments.values import write_values_csv
from app.settings.user_files import loads_json, read_text


def first_seeds(results: ExperimentResults, n: int) -> ExperimentResults:
    """`results` over its first `n` seeds."""
    return dataclasses.replace(
        results,
        seeds=results.seeds[:n],
        scalars={k: v[:n] for k, v in results.scalars.items()},
        curves={k: v[:n] for k, v in results.curves.items()},
    )


def last_look_made(spec: ExperimentSpec, scale: str, runs_dir: str | Path) -> int:
    """Seeds per arm at the design's last look made in `runs_dir` (0: none yet), from the
    summary an adaptive run writes after each look."""
    assert spec.design is not None
    try:
        summary = read_summary(layout.summary_path(runs_dir, spec.name, scale))
    except SummaryError:
        return 0
    made = len(summary.seeds)
    return made if summary.looks == spec.design.looks and made in spec.design.looks else 0


def carried_and_judged(
    spec: ExperimentSpec, scale: str, runs_dir: str | Path, held: Ledger | None
) -> tuple[ExperimentResults, ExperimentResults | None]:
    """(carried, judged) results of a design's runs in `runs_dir` (and `held`'s): every
    finished run, and the seeds of the looks made (None before the first look)."""
    assert spec.design is not None
    looks = spec.design.looks
    every = harvest.collect(spec, scale, runs_dir, looks[-1], looks, held)
    made = last_look_made(spec, scale, runs_dir)
    done = [t.seed for t in ledger.finished(spec, scale, every)]
    last = max(done, default=spec.first_seed - 1) - spec.first_seed + 1
    carried = first_seeds(every, max(last, made))
    return carried, (first_seeds(carried, made) if made else None)


def judged_from_values(results: ExperimentResults, values: Path) -> ExperimentResults | None:
    """The seeds of `results` (read from `values`) that the report beside them judged: up to
    its last look made; None when it made none."""
    path = values.parent / "report.json"
    try:
        report = loads_json(read_text(path, ExperimentError, "report"), ExperimentError, str(path))
        made = report.get("looks_made") or []
    except (ExperimentError, AttributeError):
        return None
    return first_seeds(results, int(made[-1])) if made else None


def write_before_first_look(
    spec: ExperimentSpec, scale: str, carried: ExperimentResults, out: Path
) -> Path:
    """The report folder of a design before its first look: no verdict, the finished runs
    (values.csv and ledger.json, so they travel) and a page that says so."""
    assert spec.design is not None
    out.mkdir(parents=True, exist_ok=True)
    (out / "report.json").unlink(missing_ok=True)  # a look made later writes it
    write_values_csv(carried, out / "values.csv")
    ledger.write(spec, scale, carried, out)
    done = ledger.finished(spec, scale, carried)
    first = spec.design.looks[0]
    arms = [a.name for a in spec.arms]
    stage = first * len(arms)
    seeds = f"{spec.first_seed}-{spec.first_seed + first - 1}"
    names = ", ".join(t.name for t in done) or "none yet"
    index = out / "index.html"
    index.write_text(
        "<!doctype html><meta charset='utf-8'>"
        f"<title>{html.escape(spec.name)} at {scale}: before its first look</title>"
        f"<h1>{html.escape(spec.name)} at {scale}</h1>"
        f"<p>{html.escape(spec.description)}</p>"
        f"<p><b>No look made yet, so no verdict.</b> The design judges its claims first at "
        f"{first} seeds per arm (seeds {seeds} of {', '.join(arms)}: {stage} runs), then at "
        f"{', '.join(map(str, spec.design.looks[1:]))}. Finished so far: {len(done)} of "
        f"{stage} runs. Their values are in <a href='values.csv'>values.csv</a> and their "
        "fingerprints in <a href='ledger.json'>ledger.json</a>, so the stage continues on "
        "any machine without rerunning them.</p>"
        f"<p>Finished runs: {html.escape(names)}.</p>\n",
        encoding="utf-8",
    )
    return index
