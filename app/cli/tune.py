"""`gnp-lab tune --task ID`: tune a brain's settings on a task with Optuna (`app.tune`), write
a preset (its options: app/cli/tune_options.py)."""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path
from typing import Any

from app.cli.train import Bar
from app.tune.space import FIRST_VALIDATION_SEED, TuneError, run_seeds

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,63}$")
TUNING_DIR = "tuning"
"""Studies and presets live in RUNS_DIR/tuning/: NAME.db (the study), NAME.toml (its preset)."""


def study_name(args: argparse.Namespace) -> str:
    """--study, or TASK-BRAIN[-METHOD]; a name that is a plain file name.

    Raises:
        TuneError: a name that could leave the tuning folder.
    """
    name = args.study
    if name is None:
        name = f"{args.task.replace('/', '_')}-{args.brain}"
        name += f"-{args.method}" if args.method and args.brain == "gnp" else ""
    if not _NAME.match(name):
        raise TuneError(
            f"study name {name!r} must be 1-64 letters, digits, '_', '.' or '-', starting "
            "with a letter or digit"
        )
    return name


class _TrialBar(Bar):
    """Trials finished, and the generation of the trial in flight."""

    def refresh(self) -> None:
        if self._bar is not None:
            self._bar.refresh()


_SIZES = {
    "seed": "--seeds (its tuning seeds)",
    "training.population": "--population",
    "training.generations": "--budget",
    "training.steps": "--steps",
}


def _fixed(args: argparse.Namespace) -> dict[str, Any]:
    """The study's fixed settings: --set's (the task's bounds and episode protocol as task.KEY,
    the bounds also left to `task_settings`) and --method."""
    from app.tasks.common import EpisodeProtocol

    protocol = {f"task.{key}" for key in EpisodeProtocol.model_fields}
    fixed = {}
    for path, value in list(args.assignments):
        key = ".".join(path)
        fixed[key] = value
        if key in protocol:
            args.assignments.remove((path, value))
    for key, option in _SIZES.items():
        if key in fixed:
            raise TuneError(f"--set {key}: the study's {option} sets it")
    if args.method is not None:
        if args.brain != "gnp":
            raise TuneError("--method is GNP's; fracnetics has none")
        fixed["controller.method"] = args.method
    return fixed


def cmd_tune(args: argparse.Namespace) -> int:
    from app.phases.generations import Interrupted
    from app.system.exit_codes import EXIT_INTERRUPTED
    from app.tasks.cli import task_settings
    from app.tune import study as tuning
    from app.tune.publish import write_study_preset

    name = study_name(args)
    if args.trials < 1:
        raise TuneError(f"--trials must be at least 1, got {args.trials}")
    if args.population < 2:
        raise TuneError(f"--population must be at least 2, got {args.population}")
    fixed = _fixed(args)
    task = task_settings(args.task, list(args.assignments))
    # an unusable task: one line, before any file
    discrete = task.adapter().kind == "discrete" if args.brain == "gnp" else True
    declared = tuning.Declared(
        task=args.task,
        brain=args.brain,
        name=name,
        budget=args.budget,
        population=args.population,
        steps=tuning.task_step_cap(args.task, args.steps),
        seeds=args.seeds,
        validation=args.validation,
        sampler_seed=args.sampler_seed,
        fixed=fixed,
        discrete=discrete,
    )
    if args.brain == "gnp":  # the study's settings hold before any file is made
        tuning.gnp_config(declared, task, {}, run_seeds(1)[0]).gnp_config()
    else:
        tuning.fracnetics_settings(declared, {})
    folder = Path(args.runs_dir) / TUNING_DIR
    storage = folder / f"{name}.db"
    out = Path(args.out) if args.out else folder / f"{name}.toml"
    study = tuning.open_study(storage, declared)
    done = len(tuning.finished(study))
    bar = _TrialBar(args.trials, min(done, args.trials), f"tune {name}", "trial", args.quiet)

    best = tuning.best_value(study)
    shown = [0.0]
    steps = declared.seeds * declared.generations

    def each(outcome: tuning.Outcome) -> None:
        nonlocal best
        best = outcome.best
        words = "-" if best is None else f"{best:.4g}"
        bar.update(len(tuning.finished(study)), best=words, last=outcome.state)

    def within(number: int, step: int) -> None:
        """A trial's generations on the bar, at most twice a second."""
        now = time.monotonic()
        if now - shown[0] >= 0.5:
            shown[0] = now
            words = "-" if best is None else f"{best:.4g}"
            where = f"{number}, generation {step + 1}/{steps}"
            bar.update(len(tuning.finished(study)), best=words, trial=where)
            bar.refresh()

    if not args.quiet:
        last_validation = FIRST_VALIDATION_SEED + declared.validation - 1
        sys.stderr.write(
            f"gnp-lab: tuning {args.brain} on {args.task}: {done}/{args.trials} trials done, "
            f"{declared.generations} generations of {declared.population} per run "
            f"(≤ {declared.budget:,} env-steps), run seeds {run_seeds(declared.seeds)[0]}.., "
            f"validation seeds {FIRST_VALIDATION_SEED}..{last_validation}; "
            f"study {storage}\n"
        )
    try:
        tuning.run_trials(study, declared, task, args.trials, each, within)
    except (KeyboardInterrupt, Interrupted):
        bar.close()
        done = len(tuning.finished(study))
        sys.stderr.write(
            f"gnp-lab: interrupted: {done}/{args.trials} trials finished (the cut one will be "
            f"drawn again); continue by running the same command\n"
        )
        return EXIT_INTERRUPTED
    finally:
        bar.close()
    record = write_study_preset(study, declared, task, storage, out, args.trials)
    print(
        f"{out}: best mean validation return {record.best_value:.4g} (trial "
        f"{record.best_trial}; {record.complete} complete, {record.pruned} pruned)"
    )
    if args.brain == "gnp":
        print(f"train with: gnp-lab train --task {args.task} --preset {out}")
    return 0
