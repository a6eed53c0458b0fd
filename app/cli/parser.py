"""The `gnp-lab` argument parser: every command, its options, one-line usage errors.

Only the chosen command's parser is built with its options (`build_parser(verbs)`): the others
are listed by name and help. A command's options may need heavy modules (`train`'s are built
from the run configuration's models, which import the simulator and numba), so `gnp-lab --help`
and `gnp-lab runs` never import them (tests/app/cli/test_cli_startup.py).
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from collections.abc import Callable, Collection, Sequence
from typing import Any, NoReturn

from app.settings.cli_options import add_quiet, add_run_name, add_runs_dir
from app.system.exit_codes import EXIT_USAGE

PROG = "gnp-lab"

COMMANDS: dict[str, str] = {
    "train": "train a population (evolution + Sarsa) into a run file",
    "implement": "implement a trained individual in the unseen arena, sensors breaking",
    "runs": "list run files, or inspect one",
    "serve": "open the dashboard (viser)",
    "experiment": "compare methods over seeds and sensor faults, on Dask, with statistics",
    "export": "export a run's controller, graph and tables, or a replay folder",
    "replay": "live a task run's best individual one episode again and print its return",
    "tune": "tune a brain's settings on a Gymnasium task with Optuna, into a preset",
}
"""Each command and its one-line help, in `gnp-lab --help`'s order. `experiment`, `export` and
`replay` build their parsers in their packages (with the same help: a test keeps them equal)."""


class UsageError(Exception):
    """Command-line arguments that do not make sense together."""


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage mistake on one line."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{PROG}: error: {message} (see {self.prog} --help)\n")
        raise SystemExit(EXIT_USAGE)


def _port(text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        port = -1
    if not 1 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"expected a TCP port in 1..65535, got {text!r}")
    return port


def _assignment(text: str) -> tuple[list[str], Any]:
    key, sep, raw = text.partition("=")
    if not sep or not key.strip():
        raise argparse.ArgumentTypeError(f"expected SECTION.KEY=VALUE, got {text!r}")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw  # a bare word: a string
    except RecursionError:  # tomllib recurses into nested arrays and inline tables
        raise argparse.ArgumentTypeError(f"{key.strip()}: a value nested too deep") from None
    return key.strip().split("."), value


def chosen_command(argv: Sequence[str]) -> str | None:
    """The command `argv` names (its first word that is not an option), or None."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in COMMANDS else None
    return None


def build_parser(verbs: Collection[str] | None = None) -> argparse.ArgumentParser:
    """`gnp-lab`'s parser, with the options of `verbs` (default: every command's); the other
    commands are listed with their help but parse no options."""
    parser = _Parser(
        prog=PROG,
        description="GNP Lab: GNP with reinforcement learning for a Khepera robot "
        "that learns wall following and adapts when its sensors break.",
    )
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for verb, text in COMMANDS.items():
        if verbs is None or verb in verbs:
            _BUILDERS[verb](commands)
        else:
            commands.add_parser(verb, help=text)
    return parser


def _add_train(commands: Any) -> None:
    from app.brains.registry import BUILT_IN
    from app.settings.cli_options import add_setting_options
    from app.settings.config import PRESET_NAMES
    from app.settings.loading import train_settings

    train = commands.add_parser(
        "train",
        help=COMMANDS["train"],
        description="Train a population. Settings come from the thesis's defaults, then "
        "--preset, then --config, then the options below (later wins).",
    )
    train.add_argument(
        "--preset",
        metavar="NAME|FILE",
        help=f"a shipped configuration ({', '.join(PRESET_NAMES)}) or a preset file, e.g. "
        "one `gnp-lab tune` wrote",
    )
    train.add_argument("--config", metavar="FILE", help="a TOML config file")
    train.add_argument(
        "--brain",
        metavar="NAME",
        help=f"a brain family: {', '.join(BUILT_IN)} (gnp, the default; a net evolved by "
        "CMA-ES (Elman) or NEAT), or one registered from outside (docs/brains.md)",
    )
    train.add_argument(
        "--task",
        metavar="ID",
        help="a Gymnasium task (e.g. CartPole-v1) instead of the robot; bounds with --set "
        "task.obs_low=[...] (see docs/tasks.md)",
    )
    add_setting_options(train, train_settings(), show_default=True)
    train.add_argument(
        "--set",
        dest="assignments",
        type=_assignment,
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="any other setting, e.g. training.redraw_every=500 (repeatable)",
    )
    train.add_argument("--out", metavar="FILE", help="new run file (default: in --runs-dir)")
    add_runs_dir(train)
    train.add_argument(
        "--workers",
        type=int,
        metavar="W",
        help="worker processes (default: one per core; at most one per training.shard_size robots)",
    )
    train.add_argument(
        "--resume", metavar="FILE", help="continue an interrupted run with its own settings"
    )
    add_quiet(train)
    train.add_argument(
        "--print-config", action="store_true", help="print the resulting config as TOML and stop"
    )


def _add_implement(commands: Any) -> None:
    from app.settings.cli_options import add_setting_options
    from app.settings.loading import implement_settings

    implement = commands.add_parser(
        "implement",
        help=COMMANDS["implement"],
        description="Clone the final elite (or the best of --generation) into 10 start "
        "poses × --repeats trials in the implementation arena, with online Sarsa; the sensors "
        "of --break fail at --fault-step. Results are stored in the run file. Unset options "
        "take the run's implementation settings.",
    )
    add_run_name(implement)
    add_runs_dir(implement)
    add_setting_options(implement, implement_settings(), show_default=False)
    implement.add_argument("--name", help="name of the result in the run file")
    add_quiet(implement)
    implement.add_argument(
        "--workers",
        type=int,
        help="worker processes sharing the trials (default: one per core; results do not "
        "depend on it)",
    )


def _add_runs(commands: Any) -> None:
    runs = commands.add_parser("runs", help=COMMANDS["runs"])
    runs.add_argument("name", nargs="?", metavar="NAME", help="a run to inspect")
    add_runs_dir(runs)


def _add_serve(commands: Any) -> None:
    serve = commands.add_parser("serve", help=COMMANDS["serve"])
    serve.add_argument("--host", default="127.0.0.1", help="address to bind")
    serve.add_argument("--port", type=_port, default=8080, help="port to bind (1..65535)")
    add_runs_dir(serve)
    serve.add_argument("--run", metavar="NAME", help="run to open first")
    serve.add_argument(
        "--allow-remote",
        action="store_true",
        help="allow a --host other machines can reach: the dashboard has no login and can "
        "train, export and start experiments as you",
    )


def _add_experiment(commands: Any) -> None:
    from app.experiments import cli as experiment_cli

    experiment_cli.add_parser(commands)


def _add_export(commands: Any) -> None:
    from app.export.cli import add_export_parser

    add_export_parser(commands)


def _add_replay(commands: Any) -> None:
    from app.tasks.common import add_replay_parser

    add_replay_parser(commands)


def _add_tune(commands: Any) -> None:
    from app.cli.tune_options import add_parser

    add_parser(commands, COMMANDS["tune"], _assignment)


_BUILDERS: dict[str, Callable[[Any], None]] = {
    "train": _add_train,
    "implement": _add_implement,
    "runs": _add_runs,
    "serve": _add_serve,
    "experiment": _add_experiment,
    "export": _add_export,
    "replay": _add_replay,
    "tune": _add_tune,
}
