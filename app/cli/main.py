"""`gnp-lab`'s entry point: the command's handler, and every user mistake on one line."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

import gnp
import sim
from app.cli.implement import cmd_implement
from app.cli.parser import PROG, UsageError, build_parser
from app.cli.runs import cmd_runs
from app.cli.serve import cmd_serve
from app.cli.train import cmd_train
from app.experiments import cli as experiment_cli
from app.export.cli import cmd_export
from app.settings.config import (
    ConfigError,
)
from app.store import RunFileError
from app.store.space import is_disk_full
from app.system.exit_codes import EXIT_BROKEN_PIPE, EXIT_ERROR, EXIT_INTERRUPTED, EXIT_USAGE
from app.system.signals import interrupted_by_signals
from app.tasks.common import TaskError

if TYPE_CHECKING:
    pass


def cmd_replay(args: argparse.Namespace) -> int:
    from app.tasks.cli import replay

    return replay(args)


# --- entry point ----------------------------------------------------------------------------


def main(argv: Sequence[str] | None = None) -> int:
    """Run `gnp-lab`; returns the exit status."""
    from app.phases.implementation import ImplementationError
    from app.phases.training import TrainingError

    try:
        args = build_parser().parse_args(argv)
    except SystemExit as stop:  # --help, or a usage error already reported on one line
        return stop.code if isinstance(stop.code, int) else EXIT_USAGE
    handlers = {
        "train": cmd_train,
        "implement": cmd_implement,
        "runs": cmd_runs,
        "serve": cmd_serve,
        "experiment": experiment_cli.main,
        "export": cmd_export,
        "replay": cmd_replay,
    }
    try:
        # SIGTERM ends a command as Ctrl-C does: its worker pool and Dask cluster are closed,
        # its temporary files removed, and it says so on one line.
        with interrupted_by_signals():
            status = handlers[args.command](args)
        sys.stdout.flush()  # here, not at exit, so that a closed pipe is caught below
        return status
    except KeyboardInterrupt:
        sys.stderr.write(f"{PROG}: interrupted; nothing was written\n")
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # `gnp-lab runs | head`: the reader has what it wanted
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no flush error at exit
        return EXIT_BROKEN_PIPE
    except UsageError as error:
        sys.stderr.write(f"{PROG}: error: {error}\n")
        return EXIT_USAGE
    except (
        ConfigError,
        RunFileError,
        ImplementationError,
        TrainingError,
        sim.ArenaError,
        sim.WorldError,
        experiment_cli.ExperimentError,
        gnp.GnpError,
        TaskError,
    ) as error:
        sys.stderr.write(f"{PROG}: error: {error}\n")
        return EXIT_ERROR
    except (OSError, RuntimeError) as error:
        if not (isinstance(error, OSError) or is_disk_full(error)):
            raise
        text = str(error).splitlines()[0] if str(error) else type(error).__name__
        if is_disk_full(error):
            text = f"no space left on the device: {text}"
        sys.stderr.write(f"{PROG}: error: {text}\n")
        if is_disk_full(error):
            # HDF5 cannot close a file after a failed write: it would fail again at every
            # flush and crash at exit. What was complete is on disk: end here.
            sys.stderr.flush()
            os._exit(EXIT_ERROR)
        return EXIT_ERROR
