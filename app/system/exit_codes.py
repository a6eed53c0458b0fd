"""The exit codes of every `gnp-lab` command, written once (app.cli and its subcommands)."""

from __future__ import annotations

EXIT_ERROR = 1  # the command failed: a one-line message on stderr says why
EXIT_USAGE = 2  # arguments that do not make sense (argparse's own code)
EXIT_INTERRUPTED = 130  # 128 + SIGINT: Ctrl-C, or SIGTERM handled as Ctrl-C
EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE, as a shell reports a command a closed pipe stopped
