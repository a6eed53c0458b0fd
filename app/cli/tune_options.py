"""`gnp-lab tune`'s options, built without Optuna, Gymnasium or the rest of the command
(app/cli/tune.py)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from app.settings.cli_options import add_quiet, add_runs_dir
from app.tune.space import BRAINS


def _count(text: str) -> int:
    """An integer, also written 1e6 or 1_000_000."""
    try:
        value = float(text.replace("_", "")) if any(c in text for c in "eE.") else int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value != int(value):
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}")
    return int(value)


def add_parser(commands: Any, help_text: str, assignment: Callable[[str], Any]) -> None:
    """`gnp-lab tune`'s options (`assignment`: how `--set` reads SECTION.KEY=VALUE)."""

    tune = commands.add_parser(
        "tune",
        help=help_text,
        description="Tune a brain's settings on a Gymnasium task with Optuna (TPE, median "
        "pruning) on tuning seeds only, at a budget in env-steps per training run; the study "
        "lives in RUNS_DIR/tuning/STUDY.db, so rerunning the same command continues a cut "
        "study to its --trials. Writes a preset TOML for `gnp-lab train --task ID --preset "
        "FILE` (docs/tasks.md, Tuning).",
    )
    tune.add_argument("--task", metavar="ID", required=True, help="a Gymnasium task id")
    tune.add_argument(
        "--brain",
        "--arm",
        choices=BRAINS,
        default="gnp",
        help="what to tune: our GNP (default) or fracnetics (its documented settings' space)",
    )
    tune.add_argument(
        "--method", choices=("RL", "BS", "CS"), help="GNP's method (default: the lab's)"
    )
    tune.add_argument("--trials", type=_count, default=50, help="trials to finish (default 50)")
    tune.add_argument(
        "--budget",
        type=_count,
        default=1_000_000,
        metavar="ENV_STEPS",
        help="env-steps one training run may spend at most; its generations are as many as "
        "the budget holds with every life at its cap (default 1e6)",
    )
    tune.add_argument(
        "--population", type=_count, default=100, help="individuals (the study's, default 100)"
    )
    tune.add_argument(
        "--steps", type=_count, help="a life's cap in steps (default: the task's time limit)"
    )
    tune.add_argument("--seeds", type=_count, default=1, help="training runs per trial (default 1)")
    tune.add_argument(
        "--validation",
        type=_count,
        default=10,
        metavar="K",
        help="validation episodes scoring a trial's elite (default 10)",
    )
    tune.add_argument(
        "--sampler-seed", type=_count, default=0, help="seed of the TPE sampler (default 0)"
    )
    tune.add_argument(
        "--study", metavar="NAME", help="the study's name (default TASK-BRAIN[-METHOD])"
    )
    tune.add_argument(
        "--out", metavar="FILE", help="the preset (default RUNS_DIR/tuning/STUDY.toml)"
    )
    tune.add_argument(
        "--set",
        dest="assignments",
        type=assignment,
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="fix a setting for every trial (it leaves the search space), e.g. "
        "controller.fuzzy=false, or fracnetics.jn=2",
    )
    add_runs_dir(tune)
    add_quiet(tune)
