"""Seeds spent adaptively: an experiment run in stages until its claims are decided.

Stage k runs the first n_k seeds of the arms that some claim still open needs (all arms at the
first stage), then judges every claim over the looks made so far (`sequential.judge`, which
keeps the family-wise error over all claims and stages at α). A claim decided at a look keeps
its verdict; when none is open, or at the last planned look, the run stops. Everything is a
function of the run files, so a rerun resumes where a stage was cut and decides the same.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.experiments.cluster import connect
from app.experiments.harvest import collect
from app.experiments.layout import keep_definition, summary_path
from app.experiments.planning import inspect, plan
from app.experiments.results import ExperimentResults
from app.experiments.runner import RunOptions
from app.experiments.spec import ExperimentError, ExperimentSpec
from app.experiments.summary import write_summary

if TYPE_CHECKING:
    from app.experiments.sequential import Design

DEFAULT_STAGE_SEEDS = 10
DEFAULT_MAX_SEEDS = 30


@dataclass(frozen=True)
class Stage:
    """One look of an adaptive run: the runs it asked for and what stayed open after it."""

    seeds: int  # per arm, counted from seed 0
    arms: tuple[str, ...]  # the arms run up to `seeds` (the others stopped earlier)
    open_claims: tuple[str, ...]  # claims still undecided after this look


def stages_of(spec: ExperimentSpec, stage_seeds: int | None, max_seeds: int | None) -> Design:
    """The looks of an adaptive run: the spec's pre-registered ones, else stages of seeds."""
    from app.experiments.sequential import Design

    if spec.design is not None:
        if stage_seeds or max_seeds:
            raise ExperimentError(
                f"{spec.name} pre-registers its looks ({', '.join(map(str, spec.design.looks))} "
                "seeds per arm): other stage sizes (--stage-seeds, --max-seeds) are refused"
            )
        return Design(spec.design.looks)
    try:
        return Design.staged(stage_seeds or DEFAULT_STAGE_SEEDS, max_seeds or DEFAULT_MAX_SEEDS)
    except ValueError as error:
        raise ExperimentError(str(error)) from None


def needed_arms(spec: ExperimentSpec, open_claims: list[str]) -> tuple[str, ...]:
    """The arms the open claims compare, in the spec's order."""
    wanted = {arm for c in spec.comparisons if c.name in open_claims for arm in (c.a, c.b)}
    return tuple(a.name for a in spec.arms if a.name in wanted)


def run_adaptive(
    spec: ExperimentSpec,
    scale: str,
    runs_dir: str | Path,
    *,
    stage_seeds: int | None = None,
    max_seeds: int | None = None,
    options: RunOptions | None = None,
) -> tuple[ExperimentResults, tuple[Stage, ...]]:
    """Run an experiment in stages of seeds until every claim is decided or `max_seeds`.

    After each stage the claims are judged (`sequential.judge`: family-wise error over every
    claim and stage); the next stage runs only the arms an undecided claim compares. The
    stages are a function of the run files, so a rerun resumes where it was cut and makes the
    same decisions; the summary holds the seeds up to the last look made. `options` as for
    `run_experiment`. A spec with a pre-registered `design` runs its looks, and refuses other
    stage sizes; else stages of `stage_seeds` (default 10) up to `max_seeds` (default 30).

    Raises:
        ExperimentError: as `run_experiment`, or stage sizes that cannot be used.
    """
    from app.experiments.report import analyse

    design = stages_of(spec, stage_seeds, max_seeds)
    max_seeds = design.looks[-1]
    options = options or RunOptions()
    client = options.client
    spec.scale(scale)
    if options.definition is not None:
        for task in plan(spec, scale, runs_dir, max_seeds):  # refuse a foreign file first
            if Path(task.path).exists():
                inspect(task)
        keep_definition(runs_dir, spec.name, options.definition)
    say = options.echo or (lambda line: None if options.quiet else print(line, flush=True))
    arms = tuple(a.name for a in spec.arms)
    stages: list[Stage] = []
    errors: list[str] = []
    own: Any = None
    with contextlib.ExitStack() as stack:
        for look, n in enumerate(design.looks):
            tasks = [t for t in plan(spec, scale, runs_dir, n) if t.arm in arms]
            todo = options.pending(tasks)
            if todo:
                if client is None and own is None:
                    own = stack.enter_context(connect(options.scheduler, options.workers))
                # The seeds this stage adds (the earlier ones ran at earlier stages, or came
                # with a ledger): what it runs, less any a cut run finished.
                first = spec.first_seed + (design.looks[look - 1] if look else 0)
                last = spec.first_seed + n - 1
                say(f"stage {look + 1}: seeds {first}-{last} of {', '.join(arms)}")
                errors += options.execute(tasks, client or own)
            results = collect(spec, scale, runs_dir, n, design.looks, ledger=options.ledger)
            # After every look, so that `report` and `status` see the looks made so far.
            write_summary(results, summary_path(runs_dir, spec.name, scale))
            if errors:
                break
            report = analyse(results)
            open_claims = [
                c.comparison.name
                for c in report.comparisons
                if c.claim.verdict == "undecided" and c.comparison.family == "primary"
            ]
            stages.append(Stage(n, arms, tuple(open_claims)))
            decided = len(report.of_family("primary")) - len(open_claims)
            say(f"after {n} seeds per arm: {decided} claim(s) decided, {len(open_claims)} open")
            arms = needed_arms(spec, open_claims)
            if not arms:
                break
    if errors:
        raise ExperimentError(f"{len(errors)} run(s) failed; the first: {errors[0]}")
    return results, tuple(stages)
