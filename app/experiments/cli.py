"""`gnp-lab experiment run|report|status|list`: the experiment subcommands.

`add_parser` registers them into `app.cli`'s parser and `main` runs them; a mistake raises
`ExperimentError`, which `app.cli` prints as one line.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from app.experiments.adaptive import DEFAULT_MAX_SEEDS, DEFAULT_STAGE_SEEDS
from app.experiments.lock import experiment_lock
from app.experiments.results import CORE_STEPS_PER_SECOND, ExperimentResults
from app.experiments.spec import SCALES, ExperimentError, ExperimentSpec
from app.experiments.spec_loading import load_file, load_shipped, shipped_names
from app.experiments.spec_tables import check_name
from app.phases.generations import Interrupted
from app.settings.cli_options import add_quiet, add_runs_dir
from app.settings.user_files import loads_json, read_text
from app.system.exit_codes import EXIT_INTERRUPTED
from app.system.signals import interrupted_by_signals

DEFAULT_SCALE = "small"


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {text!r}")
    return value


def add_parser(commands: Any) -> None:
    """Add `experiment` and its subcommands to `gnp-lab`'s subparsers."""
    experiment = commands.add_parser(
        "experiment",
        help="compare methods over seeds and sensor faults, on Dask, with statistics",
        description="An experiment is arms × seeds × implementation conditions: shipped ones "
        "by NAME (see `experiment list`), your own with --file. Its folder is "
        "RUNS_DIR/experiments/NAME/.",
    )
    verbs = experiment.add_subparsers(dest="verb", required=True, parser_class=type(experiment))

    def common(verb: argparse.ArgumentParser, scale: bool = True) -> None:
        verb.add_argument("name", nargs="?", metavar="NAME", help="a shipped experiment")
        verb.add_argument("--file", metavar="FILE", help="an experiment TOML file instead")
        add_runs_dir(verb)
        if scale:
            verb.add_argument(
                "--scale", choices=SCALES, default=DEFAULT_SCALE, help="size of the runs"
            )
            verb.add_argument(
                "--seeds", type=_positive, metavar="N", help="seeds 0..N-1 (default: the scale's)"
            )
            verb.add_argument(
                "--ledger",
                metavar="DIR",
                help="a committed report folder whose ledger.json counts its runs as finished "
                "(default: this checkout's docs/experiments/NAME-SCALE when it has one; 'none': "
                "no ledger)",
            )

    run = verbs.add_parser("run", help="run (or finish) an experiment, then write its report")
    common(run)
    run.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="an existing Dask scheduler, e.g. tcp://10.0.0.5:8786 (the runs dir must be on a "
        "file system its workers share); default: a local cluster on 127.0.0.1",
    )
    run.add_argument(
        "--workers",
        type=_positive,
        metavar="W",
        help="worker processes of the local cluster (default: one per core)",
    )
    add_quiet(run)
    run.add_argument(
        "--adaptive",
        action="store_true",
        help="run seeds in stages, judging the claims after each, and give more seeds only to "
        "the arms an undecided claim needs (family-wise error over claims and stages)",
    )
    run.add_argument(
        "--max-seeds",
        type=_positive,
        metavar="N",
        help=f"--adaptive: at most N seeds per arm (default {DEFAULT_MAX_SEEDS})",
    )
    run.add_argument(
        "--stage-seeds",
        type=_positive,
        metavar="n",
        help=f"--adaptive: seeds per arm added at each stage (default {DEFAULT_STAGE_SEEDS})",
    )
    report = verbs.add_parser("report", help="statistics and figures from the run files")
    common(report)
    report.add_argument("--format", choices=("html", "json"), default="html")
    report.add_argument("--out", metavar="DIR", help="report folder (default: in the experiment's)")
    report.add_argument(
        "--from-values",
        metavar="CSV",
        help="write the report from a report's values.csv instead of the run files (e.g. a "
        "committed report, again, after the verdict rules changed); its curve figures are "
        "kept from the --out folder",
    )
    status = verbs.add_parser("status", help="what the experiment's folder holds so far")
    common(status)
    listing = verbs.add_parser("list", help="the shipped experiments and their cost per scale")
    add_runs_dir(listing)
    page = verbs.add_parser(
        "reproduced",
        help="rewrite the tables of the 'thesis, reproduced' page from the committed reports",
        description="Reads DOCS/NAME-SCALE/report.json (written there by `experiment report "
        "NAME --scale SCALE --out DOCS/NAME-SCALE`) and rewrites the tables of DOCS/README.md "
        "between its marker lines; the text around them is kept.",
    )
    page.add_argument("--docs", default="docs/experiments", help="folder of the reports")
    verbs.add_parser(
        "provenance",
        help="rewrite app/experiments/provenance.json from this checkout's git history",
        description="For every shipped experiment: the commit that declared each claim and its "
        "margin, and the first commit that published data of both its sides per report folder. "
        "Run it at the root of a full (not shallow) clone after committing a spec or a report.",
    )


def _spec(args: argparse.Namespace) -> ExperimentSpec:
    """The experiment asked for: --file, a shipped NAME, or a NAME whose file the runs dir keeps
    (a `run --file` keeps it in the experiment's folder)."""
    from app.experiments import layout

    if args.file:
        spec = load_file(args.file)
        if args.name and args.name != spec.name:
            raise ExperimentError(
                f"{args.file} defines experiment {spec.name!r}, not {args.name!r}"
            )
        if spec.name in shipped_names():
            raise ExperimentError(
                f"{args.file} names its experiment {spec.name!r}, as a shipped experiment is "
                "named: its runs would share that one's folder; give it a name of its own"
            )
        return spec
    if not args.name:
        raise ExperimentError("give an experiment NAME (see `gnp-lab experiment list`) or --file")
    if args.name in shipped_names():
        return load_shipped(args.name)
    try:
        check_name(args.name)
    except ValueError:  # not a name a folder of the runs dir can have
        saved = None
    else:
        saved = layout.saved_spec(args.runs_dir, args.name)
    if saved is None:
        raise ExperimentError(
            f"no shipped experiment named {args.name!r}, and {args.runs_dir} keeps no file of "
            f"one (a `run --file` keeps it); choose one of {', '.join(shipped_names())} "
            "or give --file"
        )
    return saved


def main(args: argparse.Namespace) -> int:
    """Run `gnp-lab experiment VERB`."""
    if args.verb == "list":
        return cmd_list()
    if args.verb == "reproduced":
        from app.experiments.reproduced import write_page

        print(f"wrote {write_page(args.docs)}")
        return 0
    if args.verb == "provenance":
        from app.experiments.provenance import ProvenanceError, write_file

        try:
            print(f"wrote {write_file('.', shipped_names())}")
        except ProvenanceError as error:
            raise ExperimentError(str(error)) from None
        return 0
    spec = _spec(args)
    spec.scale(args.scale)
    handlers = {"run": cmd_run, "report": cmd_report, "status": cmd_status}
    try:
        with interrupted_by_signals():
            return handlers[args.verb](spec, args)
    except (KeyboardInterrupt, Interrupted):  # Interrupted: training in this process (numba's
        # warm-up, an in-process cluster's runs) stopped by the same Ctrl-C or SIGTERM
        sys.stderr.write(
            "gnp-lab: interrupted; finished runs are kept: run the same command to resume\n"
        )
        return EXIT_INTERRUPTED


def _write_report(
    spec: ExperimentSpec,
    scale: str,
    results: ExperimentResults,
    out: Path,
    curves: bool = False,
    carried: ExperimentResults | None = None,
) -> str:
    """Write the report folder `out` of `results` and the ledger of its finished runs beside
    it; `carried` (a design's every finished run, beyond the looks judged) goes to values.csv
    and the ledger instead when given."""
    from app.experiments import ledger
    from app.experiments.report_page import write_report
    from app.experiments.values import write_values_csv

    index = write_report(results, out, keep_curves=curves)
    if carried is not None:
        write_values_csv(carried, out / "values.csv")
    ledger.write(spec, scale, carried or results, out)
    return f"report: {index}"


def _ledger(spec: ExperimentSpec, args: argparse.Namespace) -> Any:
    """The ledger asked for (`--ledger DIR`, 'none'), else this checkout's committed one."""
    from app.experiments import ledger

    if hasattr(args, "held_ledger"):  # loaded once per command
        return args.held_ledger
    args.held_ledger = None
    if args.ledger == "none":
        return None
    folder = Path(args.ledger) if args.ledger else ledger.default_folder(spec, args.scale)
    if folder is None:
        return None
    held = ledger.load(spec, args.scale, folder)
    if not getattr(args, "quiet", False):
        print(f"ledger: {len(held.runs)} finished run(s) from {folder}", file=sys.stderr)
    args.held_ledger = held
    return held


def cmd_run(spec: ExperimentSpec, args: argparse.Namespace) -> int:
    from app.experiments import layout
    from app.experiments.runner import RunOptions, run_experiment

    if args.scheduler and args.workers:
        raise ExperimentError("--workers sizes the local cluster; drop it with --scheduler")
    definition = Path(args.file).read_text(encoding="utf-8") if args.file else None
    if args.adaptive and args.seeds:
        raise ExperimentError("--seeds fixes the seed count; --adaptive takes --max-seeds")
    if not args.adaptive and (args.max_seeds or args.stage_seeds):
        raise ExperimentError("--max-seeds and --stage-seeds go with --adaptive")
    folder = layout.experiment_dir(args.runs_dir, spec.name)
    with experiment_lock(folder, args.scale), _scheduler_client(args.scheduler) as client:
        options = RunOptions(
            client=client,
            workers=args.workers,
            quiet=args.quiet,
            definition=definition,
            ledger=_ledger(spec, args),
        )
        if args.adaptive:
            from app.experiments.adaptive import run_adaptive

            results, _ = run_adaptive(
                spec,
                args.scale,
                args.runs_dir,
                stage_seeds=args.stage_seeds,
                max_seeds=args.max_seeds,
                options=options,
            )
        else:
            results = run_experiment(
                spec, args.scale, args.runs_dir, seeds=args.seeds, options=options
            )
    print(f"summary: {layout.summary_path(args.runs_dir, spec.name, args.scale)}")
    print(_write_report(spec, args.scale, results, folder / f"report-{args.scale}"))
    return 0


def _planned_looks(values: Path) -> tuple[int, ...]:
    """The looks an adaptive report planned, from the report.json beside its values.csv (none:
    one look): a report written again from its values judges them over the same looks."""
    path = values.parent / "report.json"
    try:
        report = loads_json(read_text(path, ExperimentError, "report"), ExperimentError, str(path))
        looks = tuple(int(n) for n in report.get("looks_planned") or ())
    except (ExperimentError, ValueError, TypeError, AttributeError):
        return ()
    return looks if len(looks) > 1 else ()  # one planned look: a plain, one-look report


def _from_values(spec: ExperimentSpec, args: argparse.Namespace) -> int:
    import tempfile

    from app.experiments import harvest
    from app.experiments.values import read_values_csv

    with tempfile.TemporaryDirectory(prefix="gnp-lab-empty-") as empty:
        template = harvest.collect(spec, args.scale, empty)  # the shape, every value NaN
    results = read_values_csv(args.from_values, spec, template)
    results = dataclasses.replace(results, looks=_planned_looks(Path(args.from_values)))
    carried = None
    if spec.design is not None:  # judged over the looks its report made, carrying the rest
        from app.experiments import looks_made

        carried = dataclasses.replace(results, looks=spec.design.looks)
        judged = looks_made.judged_from_values(carried, Path(args.from_values))
        if judged is None and args.out:
            index = looks_made.write_before_first_look(spec, args.scale, carried, Path(args.out))
            print(f"report: {index} (no look made yet)")
            return 0
        if judged is None:
            raise ExperimentError(f"{spec.name}: no look made yet, so no report to print")
        results = judged
    if args.format == "json":
        return _print_json(results)
    if not args.out:
        raise ExperimentError("--from-values writes a report folder: give --out")
    print(_write_report(spec, args.scale, results, Path(args.out), curves=True, carried=carried))
    return 0


def _print_json(results: ExperimentResults) -> int:
    from app.experiments.report import analyse
    from app.experiments.report_json import to_json

    json.dump(to_json(analyse(results)), sys.stdout, indent=2, ensure_ascii=False, allow_nan=False)
    sys.stdout.write("\n")
    return 0


@contextmanager
def _scheduler_client(address: str | None) -> Iterator[Any]:
    """A client of the --scheduler asked for (checked and contacted even when every run is
    done, so a wrong address is never silently ignored), or None for a local cluster."""
    from app.experiments import cluster
    from app.system.security import AddressError, check_scheduler_address, plain_tcp_warning

    if address is None:
        yield None
        return
    try:
        check_scheduler_address(address)
    except AddressError as error:
        raise ExperimentError(str(error)) from None
    warning = plain_tcp_warning(address)
    if warning:
        sys.stderr.write(f"gnp-lab: {warning}\n")
    try:
        connection = cluster.connect(address)
        client = connection.__enter__()
    except ExperimentError:
        raise
    except (ValueError, TypeError) as error:  # e.g. tls:// without certificates configured
        raise ExperimentError(
            f"cannot connect to the Dask scheduler {address}: {error} (for tls://, configure "
            "the certificates: see docs/security.md)"
        ) from None
    try:
        yield client
    finally:
        connection.__exit__(None, None, None)


def cmd_report(spec: ExperimentSpec, args: argparse.Namespace) -> int:
    from app.experiments import layout, planning
    from app.experiments.summary import write_summary

    if args.from_values:
        return _from_values(spec, args)
    folder = layout.experiment_dir(args.runs_dir, spec.name)
    planned = planning.plan(spec, args.scale, args.runs_dir)
    if not any(Path(t.path).exists() for t in planned) and _ledger(spec, args) is None:
        raise ExperimentError(
            f"no runs of {spec.name!r} at scale {args.scale!r} in {folder}; "
            f"start them with: gnp-lab experiment run {spec.name} --scale {args.scale}"
        )
    if spec.design is not None and not args.seeds:
        return _design_report(spec, args)
    results = _collected(spec, args)
    write_summary(results, layout.summary_path(args.runs_dir, spec.name, args.scale))
    if args.format == "json":
        return _print_json(results)
    out = Path(args.out) if args.out else folder / f"report-{args.scale}"
    print(_write_report(spec, args.scale, results, out))
    return 0


def _design_report(spec: ExperimentSpec, args: argparse.Namespace) -> int:
    """A pre-registered design's report: judged at the looks made, carrying every finished run
    (`app.experiments.looks_made`); before the first look, only the runs and no verdict."""
    from app.experiments import layout, looks_made

    carried, judged = looks_made.carried_and_judged(
        spec, args.scale, args.runs_dir, _ledger(spec, args)
    )
    if args.format == "json":
        if judged is None:
            raise ExperimentError(f"{spec.name}: no look made yet, so no report to print")
        return _print_json(judged)
    folder = layout.experiment_dir(args.runs_dir, spec.name)
    out = Path(args.out) if args.out else folder / f"report-{args.scale}"
    if judged is None:
        index = looks_made.write_before_first_look(spec, args.scale, carried, out)
        print(f"report: {index} (no look made yet)")
        return 0
    print(_write_report(spec, args.scale, judged, out, carried=carried))
    return 0


def _collected(spec: ExperimentSpec, args: argparse.Namespace) -> ExperimentResults:
    """The results to report: of an adaptive run when the summary says it was one (its looks,
    and the seeds up to its last look), else of the asked seeds."""
    from app.experiments import harvest, layout
    from app.experiments.summary import SummaryError, read_summary

    looks: tuple[int, ...] = ()
    seeds = args.seeds
    if not seeds:
        try:
            summary = read_summary(layout.summary_path(args.runs_dir, spec.name, args.scale))
        except SummaryError:
            summary = None
        if summary is not None and summary.looks:
            looks, seeds = summary.looks, len(summary.seeds)
    return harvest.collect(spec, args.scale, args.runs_dir, seeds, looks, _ledger(spec, args))


def cmd_status(spec: ExperimentSpec, args: argparse.Namespace) -> int:
    from app.experiments import layout, planning

    status = planning.scale_status(spec, args.scale, args.runs_dir, args.seeds)
    tasks, states, problems = status.tasks, status.states, status.problems
    generations = sum(s.generations_done for s in states), sum(s.generations for s in states)
    conditions = sum(len(s.conditions) for s in states), sum(len(t.conditions) for t in tasks)
    print(
        f"{spec.name} at scale {args.scale}: {status.done}/{len(tasks)} runs done, "
        f"{generations[0]}/{generations[1]} generations, "
        f"{conditions[0]}/{conditions[1]} conditions"
    )
    for task, state in zip(tasks, states, strict=True):
        if task.key in problems:
            what = f"unreadable: {problems[task.key]}"
        elif not Path(task.path).exists():
            what = "not started"
        else:
            what = "trained" if state.finished else "training or cut"
        print(
            f"  {task.name:16} {state.generations_done:6}/{state.generations} generations  "
            f"conditions {len(state.conditions)}/{len(task.conditions)}  {what}"
        )
    summary = layout.summary_path(args.runs_dir, spec.name, args.scale)
    print(f"summary: {summary if summary.exists() else 'not written yet'}")
    return 0


def _core_time(seconds: float) -> str:
    """Core time in words, to two significant figures: "40 core-seconds", "9.8 core-hours"."""
    for unit, size in (("core-hours", 3600.0), ("core-minutes", 60.0)):
        if seconds >= size:
            return f"{float(f'{seconds / size:.2g}'):g} {unit}"
    return f"{float(f'{seconds:.2g}'):g} core-seconds"


def cmd_list() -> int:
    from app.experiments import planning
    from app.experiments.reproduced import short_count

    for name in shipped_names():
        spec = load_shipped(name)
        print(f"{name}: {spec.description}")
        print(f"  source: {spec.source}")
        arms = ", ".join(f"{a.name} ({a.label})" for a in spec.arms)
        print(f"  arms: {arms}; conditions: {', '.join(c.name for c in spec.conditions)}")
        for scale, sizes in spec.scales.items():
            cost = planning.work(spec, scale)
            t = spec.run_config(spec.arms[0].name, scale, 0).training
            seconds = (cost.robot_steps + cost.trial_steps) / CORE_STEPS_PER_SECOND
            print(
                f"  {scale:6} {cost.runs} runs × {t.generations} generations × {t.population} "
                f"individuals × {t.steps} steps = {short_count(cost.robot_steps)} robot-steps; "
                f"{len(spec.conditions)} conditions per run: {short_count(cost.trial_steps)} "
                f"trial-steps; about {_core_time(seconds)} at "
                f"{CORE_STEPS_PER_SECOND / 1e6:.2g} M steps per core-second"
                + (f"; measured: {sizes.measured}" if sizes.measured else "")
            )
    return 0
