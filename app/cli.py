"""`gnp-lab`: train, implement, list and inspect runs, serve the dashboard.

A user mistake ends with one line on stderr (`gnp-lab: error: ...`) and a non-zero exit status;
no command overwrites or damages an existing run file.
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import sys
import tomllib
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import gnp
import sim
from app.cli_options import (
    add_quiet,
    add_run_name,
    add_runs_dir,
    add_setting_options,
    given_options,
    given_settings,
)
from app.config import (
    BRAINS,
    PRESET_NAMES,
    ConfigError,
    ImplementationSettings,
    RunConfig,
    build_config,
    implement_settings,
    preset_layer,
    read_toml,
    to_toml,
    train_settings,
)
from app.exit_codes import EXIT_BROKEN_PIPE, EXIT_ERROR, EXIT_INTERRUPTED, EXIT_USAGE
from app.experiments import cli as experiment_cli
from app.export.cli import add_export_parser, cmd_export
from app.fields import nested
from app.security import is_loopback
from app.store import RunFileError, RunReader, list_runs, new_run_path, resolve_run
from app.store.space import is_disk_full
from app.tasks.common import TaskError, add_replay_parser, is_task_run
from app.workers import handling, raise_interrupt

if TYPE_CHECKING:
    from app.training import GenerationSummary

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
        choices=BRAINS,
        help="gnp (default), or a neural net evolved by CMA-ES (Elman) or NEAT",
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


# --- train ----------------------------------------------------------------------------------

_CONFIG_OPTIONS = ("preset", "config", "brain", "task")
"""What else than setting options (and --set, --out) sets a new run's configuration."""


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """Thesis defaults ← --preset ← --config ← options."""
    layers: list[dict[str, Any]] = []
    sources = ["defaults"]
    if args.preset:
        layers.append(preset_layer(args.preset))
        sources.append(f"preset {args.preset}")
    if args.config:
        layers.append(read_toml(args.config))
        sources.append(args.config)
    options = nested(given_settings(args))
    if args.brain is not None:
        options["neuro"] = None if args.brain == "gnp" else {"optimiser": args.brain}
    for path, value in args.assignments:
        target = options
        for part in path[:-1]:
            target = target.setdefault(part, {})
            if not isinstance(target, dict):
                raise ConfigError(f"--set {'.'.join(path)}: {part} is not a section")
        target[path[-1]] = value
    layers.append(options)
    return build_config(*layers, source=" + ".join([*sources, "options"]))


class _Bar:
    """A tqdm bar on stderr (ETA included), created at the first update so that an error
    found before any work is the only thing printed."""

    def __init__(self, total: int, initial: int, desc: str, unit: str, quiet: bool) -> None:
        self._options = dict(
            total=total, initial=initial, desc=desc, unit=unit, disable=quiet, dynamic_ncols=True
        )
        self._bar: Any = None

    def update(self, done: int, **postfix: str) -> None:
        if self._bar is None:
            from tqdm import tqdm

            self._bar = tqdm(file=sys.stderr, **self._options)
        if postfix:
            self._bar.set_postfix(postfix, refresh=False)
        self._bar.update(done - self._bar.n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


class _GenerationBar(_Bar):
    """Progress over generations with the current best and mean fitness."""

    def __init__(self, total: int, initial: int, quiet: bool) -> None:
        super().__init__(total, initial, "train", "gen", quiet)
        self.best = float("nan")

    def __call__(self, summary: GenerationSummary) -> None:
        self.best = summary.best_fitness
        self.update(
            summary.generation + 1,
            best=f"{summary.best_fitness:.3f}",
            mean=f"{summary.mean_fitness:.3f}",
        )


def _workers(option: int | None) -> int:
    """--workers: default one per core, at least 1."""
    from app.training import default_workers

    workers = option if option is not None else default_workers()
    if workers < 1:
        raise UsageError(f"--workers must be at least 1, got {workers}")
    return workers


def _interrupted(stop: Exception, path: Path) -> int:
    sys.stderr.write(f"{PROG}: interrupted: {stop}; continue with: {PROG} train --resume {path}\n")
    return EXIT_INTERRUPTED


def cmd_train(args: argparse.Namespace) -> int:
    from app import training

    workers = _workers(args.workers)
    if args.resume:
        given = [f"--{name}" for name in _CONFIG_OPTIONS if getattr(args, name) is not None]
        given += [option.given_as(value) for option, value in given_options(args).items()]
        given += ["--set"] if args.assignments else []
        given += ["--out"] if args.out else []
        if given:
            raise UsageError(
                f"--resume continues a run with its stored settings; drop {', '.join(given)}"
            )
        path = Path(args.resume)
        if is_task_run(path):
            from app.tasks import cli as task_cli

            return task_cli.resume(path, args.quiet)
        with RunReader(path) as run:
            config, start = run.config, run.generations_done
            if run.finished:
                raise RunFileError(f"{path} is a finished run; there is nothing to resume")
        bar = _GenerationBar(config.training.generations, start, args.quiet)
        try:
            training.resume(path, workers=workers, progress=bar)
        except training.Interrupted as stop:
            bar.close()  # before the message, so the message is the last line
            return _interrupted(stop, path)
        finally:
            bar.close()
    elif args.task:
        from app.tasks import cli as task_cli

        task = task_cli.task_settings(args.task, args.assignments)
        return task_cli.train(args, task, config_from_args(args))
    else:
        config = config_from_args(args)
        if args.print_config:
            sys.stdout.write(to_toml(config))
            return 0
        now = datetime.now(UTC)
        path = Path(args.out) if args.out else new_run_path(args.runs_dir, config, now)
        if path.exists():
            raise RunFileError(f"{path} already exists; choose another --out or --resume it")
        bar = _GenerationBar(config.training.generations, 0, args.quiet)
        try:
            training.train(config, path, workers=workers, progress=bar)
        except training.Interrupted as stop:
            bar.close()  # before the message, so the message is the last line
            return _interrupted(stop, path)
        finally:
            bar.close()
    print(f"{path}: finished, best fitness {bar.best:.4f}")
    return 0


# --- implement ------------------------------------------------------------------------------


def cmd_implement(args: argparse.Namespace) -> int:
    from app.implementation import implement

    changes = {path[-1]: value for path, value in given_settings(args).items()}
    count = changes.get("break_count")
    if count is not None and not 1 <= count <= sim.N_SENSORS:
        raise UsageError(
            f"--break-count must be 1..{sim.N_SENSORS}, got {count} "
            "(for no fault, give --break none)"
        )
    path = resolve_run(args.runs_dir, args.run)
    with RunReader(path) as run:
        stored = run.config.implementation
    # A fixed set and k random sensors exclude each other: the option given replaces the other.
    if "broken_sensors" in changes and count is None:
        changes["break_count"] = 0
    if count is not None and "broken_sensors" not in changes:
        changes["broken_sensors"] = ()
    config = build_config(
        {"implementation": stored.model_dump()},
        {"implementation": changes},
        source="implementation options",
    )
    settings: ImplementationSettings = config.implementation
    workers = _workers(args.workers)
    trial_steps = sim.N_START_POSES * settings.repeats * settings.steps
    bar = _Bar(trial_steps, 0, "implement", "trial-step", args.quiet)

    def progress(done: int, total: int) -> None:
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


# --- runs -----------------------------------------------------------------------------------


def cmd_runs(args: argparse.Namespace) -> int:
    if args.name:
        path = resolve_run(args.runs_dir, args.name)
        if is_task_run(path):
            from app.tasks.cli import inspect

            return inspect(path)
        return _inspect(path)
    summaries = list_runs(args.runs_dir)
    if not summaries:
        print(f"no runs in {args.runs_dir}")
        return 0
    print(f"{'name':32} {'method':10} {'generations':>12} {'best':>7}  status")
    for s in summaries:
        if s.error:
            print(f"{s.name:32} {'?':10} {'':>12} {'':>7}  unreadable: {s.error}")
            continue
        kind = f"{s.method} {gnp.judgment_name(s.fuzzy)}" if s.brain == "gnp" else s.brain
        status = "finished" if s.finished else "running or interrupted"
        if s.implementations:
            status += f"; implementations: {', '.join(s.implementations)}"
        gens = f"{s.generations_done}/{s.generations}"
        print(f"{s.name:32} {kind:10} {gens:>12} {s.best_fitness:7.4f}  {status}")
    return 0


def _inspect(path: Path) -> int:
    from app.implementation import describe_fault

    with RunReader(path) as run:
        history = run.history()
        done = run.generations_done
        print(f"run {path.name}: seed {run.seed}, gnp-lab {run.package_version}")
        print(
            f"generations {done}/{run.config.training.generations}, "
            f"{'finished' if run.finished else 'running or interrupted'}"
        )
        if done:
            for g in sorted({0, done // 2, done - 1}):
                print(
                    f"  generation {g:5d}: best {history.best_fitness[g]:.4f}  "
                    f"mean {history.mean_fitness[g]:.4f} ± {history.std_fitness[g]:.4f}  "
                    f"ε {history.epsilon[g]:.3f}  α {history.alpha[g]:.3f}"
                )
        for name in run.implementation_names():
            result = run.implementation(name)
            settings = result.settings
            fault = describe_fault(settings)
            print(
                f"implementation {name}: {fault}, {len(result.trial_mean_reward)} trials "
                f"x {settings.steps} steps: mean reward {result.mean_reward:.4f}, "
                f"from step {settings.fault_step} on {result.mean_after_fault:.4f}"
            )
        print("\n# config")
        sys.stdout.write(to_toml(run.config))
    return 0


# --- serve ----------------------------------------------------------------------------------


def _check_host(host: str) -> None:
    """Refuse an address this machine cannot listen on, before viser's server thread tries."""
    try:
        infos = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as error:
        raise UsageError(f"--host {host!r} is not an address of this machine ({error})") from None
    family, kind, _, _, address = infos[0]
    try:
        with socket.socket(family, kind) as probe:
            probe.bind(address)
    except OSError as error:
        raise UsageError(f"cannot listen on --host {host!r}: {error.strerror}") from None


def cmd_serve(args: argparse.Namespace) -> int:
    if args.run is not None:
        resolve_run(args.runs_dir, args.run)
    _check_host(args.host)
    if not is_loopback(args.host):
        if not args.allow_remote:
            raise UsageError(
                f"--host {args.host} lets other machines reach the dashboard, which has no "
                "login and runs training, exports and experiments as you; keep 127.0.0.1 and "
                "use an SSH tunnel (ssh -L 8080:127.0.0.1:8080 HOST), or add --allow-remote"
            )
        sys.stderr.write(
            f"{PROG}: WARNING: the dashboard on {args.host} has no login: anyone who can "
            "reach this port can train, export and start experiments as you\n"
        )
    from app.dashboard import serve

    serve(host=args.host, port=args.port, runs_dir=args.runs_dir, run=args.run)
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from app.tasks.cli import replay

    return replay(args)


# --- entry point ----------------------------------------------------------------------------


def main(argv: Sequence[str] | None = None) -> int:
    """Run `gnp-lab`; returns the exit status."""
    import sim
    from app.implementation import ImplementationError
    from app.training import TrainingError

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
        with handling(signal.SIGTERM, raise_interrupt):
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


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
