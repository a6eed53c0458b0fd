"""`gnp-lab implement`: a finished run's implementation phase, stored in its file."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import sim
from app.cli.parser import UsageError
from app.cli.train import Bar, warm, workers_option
from app.settings.cli_options import (
    given_settings,
)
from app.settings.config import ImplementationSettings
from app.settings.loading import build_config
from app.store import RunReader, resolve_run

if TYPE_CHECKING:
    pass


# --- implement ------------------------------------------------------------------------------


def cmd_implement(args: argparse.Namespace) -> int:
    from app.phases.implementation import implement

    changes = {path[-1]: value for path, value in given_settings(args).items()}
    count = changes.get("break_count")
    if count is not None and not 1 <= count <= sim.N_SENSORS:
        raise UsageError(
            f"--break-count must be 1..{sim.N_SENSORS}, got {count} "
            "(for no fault, give --break none)"
        )
    path = resolve_run(args.runs_dir, args.run)
    with RunReader(path) as run:
        stored = run.config
    warm(stored)
    # A fixed set and k random sensors exclude each other: the option given replaces the other.
    if "broken_sensors" in changes and count is None:
        changes["break_count"] = 0
    if count is not None and "broken_sensors" not in changes:
        changes["broken_sensors"] = ()
    config = build_config(
        {"implementation": stored.implementation.model_dump()},
        {"implementation": changes},
        source="implementation options",
    )
    settings: ImplementationSettings = config.implementation
    workers = workers_option(args.workers)
    trial_steps = sim.N_START_POSES * settings.repeats * settings.steps
    bar = Bar(trial_steps, 0, "implement", "trial-step", args.quiet)

    def progress(done: int, _total: int) -> None:
        bar.update(done)

    try:
        result = implement(path, settings, name=args.name, progress=progress, workers=workers)
    finally:
        bar.close()
    print(
        f"{path}: implementation/{result.name}: mean reward {result.mean_reward:.4f}, "
        f"after the fault {result.mean_after_fault:.4f} "
        f"({len(result.trial_mean_reward)} trials)"
    )
    return 0
