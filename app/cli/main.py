"""`gnp-lab`'s entry point: the command's handler, and every user mistake on one line.

Nothing heavy is imported here: each command's module (and what it needs: numba, the simulator,
the dashboard, Dask) is imported when that command runs, so `gnp-lab --help` and `gnp-lab runs`
start at once (bench/cli_startup.py).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

from app.cli.parser import PROG, UsageError, build_parser, chosen_command
from app.system.exit_codes import EXIT_BROKEN_PIPE, EXIT_ERROR, EXIT_INTERRUPTED, EXIT_USAGE
from app.system.signals import interrupted_by_signals

HANDLERS: dict[str, tuple[str, str]] = {
    "train": ("app.cli.train", "cmd_train"),
    "implement": ("app.cli.implement", "cmd_implement"),
    "runs": ("app.cli.runs", "cmd_runs"),
    "serve": ("app.cli.serve", "cmd_serve"),
    "experiment": ("app.experiments.cli", "main"),
    "export": ("app.export.cli", "cmd_export"),
    "replay": ("app.tasks.cli", "replay"),
    "tune": ("app.cli.tune", "cmd_tune"),
}
"""Each command's handler: (module, function), imported when the command runs."""

COMPILING_COMMANDS = ("train", "implement", "replay", "tune")
"""The commands that may compile numba's kernels (the first run on a machine): what numba
compiles while they run is said on stderr (`app.phases.warm.CompileWatch`)."""

USER_ERRORS: tuple[tuple[str, str], ...] = (
    ("app.settings.config", "ConfigError"),
    ("app.store.files", "RunFileError"),
    ("app.phases.implementation", "ImplementationError"),
    ("app.phases.generations", "TrainingError"),
    ("sim.arena", "ArenaError"),
    ("sim.faults", "WorldError"),
    ("app.experiments.spec", "ExperimentError"),
    ("gnp.config", "GnpError"),
    ("app.tasks.common", "TaskError"),
    ("app.tune.space", "TuneError"),
)
"""The errors that are a user's mistake (reported on one line), by the module defining each."""


def _user_errors() -> tuple[type[BaseException], ...]:
    """The classes of `USER_ERRORS` whose modules are loaded: an error raised was defined by a
    module that is, and none is imported just to be caught."""
    return tuple(
        getattr(sys.modules[module], name) for module, name in USER_ERRORS if module in sys.modules
    )


def _compiles_said(command: str | None, words: list[str]) -> contextlib.AbstractContextManager[Any]:
    """Say on stderr what numba compiles while a `COMPILING_COMMANDS` command is imported and
    runs (kernel by kernel unless --quiet); nothing on a warm cache. Its options are built
    before, without numba (the watch imports it), so its `--help` imports none."""
    if command not in COMPILING_COMMANDS:
        return contextlib.nullcontext()
    from app.phases.warm import CompileWatch

    def say(line: str) -> None:
        sys.stderr.write(f"{PROG}: {line}\n")
        sys.stderr.flush()

    return CompileWatch(say, each="--quiet" not in words)


def _handler(command: str) -> Callable[[argparse.Namespace], int]:
    module, function = HANDLERS[command]
    handler: Callable[[argparse.Namespace], int] = getattr(
        importlib.import_module(module), function
    )
    return handler


# --- entry point ----------------------------------------------------------------------------


def main(argv: Sequence[str] | None = None) -> int:
    """Run `gnp-lab`; returns the exit status."""
    words = list(sys.argv[1:] if argv is None else argv)
    status = _run(chosen_command(words), words)
    if argv is None and status == EXIT_INTERRUPTED:
        # The command's own process, stopped by Ctrl-C or SIGTERM: everything it keeps is
        # closed by now. End without the interpreter's teardown, whose finalizers can crash
        # (SIGSEGV, seen once in CI) on a numba compilation the signal cut half-way.
        with contextlib.suppress(OSError):  # a closed pipe has nothing left to take
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(status)
    return status


def _run(command: str | None, words: list[str]) -> int:
    try:
        args = build_parser(() if command is None else (command,)).parse_args(words)
    except SystemExit as stop:  # --help, or a usage error already reported on one line
        return stop.code if isinstance(stop.code, int) else EXIT_USAGE
    try:
        # SIGTERM ends a command as Ctrl-C does: its worker pool and Dask cluster are closed,
        # its temporary files removed, and it says so on one line.
        with interrupted_by_signals(), _compiles_said(command, words):
            status = _handler(args.command)(args)
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
    except Exception as error:
        if isinstance(error, _user_errors()):
            sys.stderr.write(f"{PROG}: error: {error}\n")
            return EXIT_ERROR
        if isinstance(error, OSError | RuntimeError):
            from app.store.space import is_disk_full

            if isinstance(error, OSError) or is_disk_full(error):
                return _os_error(error, disk_full=is_disk_full(error))
        raise


def _os_error(error: Exception, disk_full: bool) -> int:
    """An OSError, or HDF5's RuntimeError for a full disk, on one line."""
    text = str(error).splitlines()[0] if str(error) else type(error).__name__
    if disk_full:
        text = f"no space left on the device: {text}"
    sys.stderr.write(f"{PROG}: error: {text}\n")
    if disk_full:
        # HDF5 cannot close a file after a failed write: it would fail again at every
        # flush and crash at exit. What was complete is on disk: end here.
        sys.stderr.flush()
        os._exit(EXIT_ERROR)
    return EXIT_ERROR
