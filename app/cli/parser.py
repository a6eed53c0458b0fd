"""The `gnp-lab` argument parser: every command, its options, one-line usage errors."""

from __future__ import annotations

import argparse
import sys
import tomllib
from typing import TYPE_CHECKING, Any, NoReturn

from app.brains.registry import BUILT_IN
from app.experiments import cli as experiment_cli
from app.export.cli import add_export_parser
from app.settings.cli_options import (
    add_quiet,
    add_run_name,
    add_runs_dir,
    add_setting_options,
)
from app.settings.config import PRESET_NAMES
from app.settings.loading import implement_settings, train_settings
from app.system.exit_codes import EXIT_USAGE
from app.tasks.common import add_replay_parser

if TYPE_CHECKING:
    pass


PROG = "gnp-lab"


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
    return key.strip().split("."), value


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog=PROG,
        description="GNP Lab: GNP with reinforcement learning for a Khepera robot "
        "that learns wall following and adapts when its sensors break.",
    )
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    train = commands.add_parser(
        "train",
        help="train a population (evolution + Sarsa) into a run file",
        description="Train a population. Settings come from the thesis's defaults, then "
        "--preset, then --config, then the options below (later wins).",
    )
    train.add_argument("--preset", choices=PRESET_NAMES, help="a shipped configuration")
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

    implement = commands.add_parser(
        "implement",
        help="implement a trained individual in the unseen arena, sensors breaking",
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

    runs = commands.add_parser("runs", help="list run files, or inspect one")
    runs.add_argument("name", nargs="?", metavar="NAME", help="a run to inspect")
    add_runs_dir(runs)

    serve = commands.add_parser("serve", help="open the dashboard (viser)")
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
    experiment_cli.add_parser(commands)
    add_export_parser(commands)
    add_replay_parser(commands)
    return parser
