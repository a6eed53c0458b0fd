"""`gnp-lab train`: a new run from defaults ← preset ← config file ← options, or a resumed
one; and the progress bars the commands share."""

from __future__ import annotations

import argparse
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.brains.registry import family_class, family_of
from app.cli.parser import PROG, UsageError
from app.settings.cli_options import (
    given_options,
    given_settings,
)
from app.settings.config import PRESET_NAMES, ConfigError, RunConfig, preset_layer
from app.settings.fields import nested
from app.settings.loading import build_config, read_toml, to_toml
from app.store import RunFileError, RunReader, best_words, new_run_path
from app.system.exit_codes import EXIT_INTERRUPTED
from app.tasks.common import is_task_run

if TYPE_CHECKING:
    from app.phases.training import GenerationSummary
    from app.tasks.common import EpisodeProtocol


# --- train ----------------------------------------------------------------------------------

_CONFIG_OPTIONS = ("preset", "config", "brain", "task")
"""What else than setting options (and --set, --out) sets a new run's configuration."""


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """Thesis defaults ← --preset ← --config ← options."""
    layers: list[dict[str, Any]] = []
    sources = ["defaults"]
    if args.preset in PRESET_NAMES:
        layers.append(preset_layer(args.preset))
        sources.append(f"preset {args.preset}")
    elif args.preset:
        layers.append(_preset_file(args.preset, args.task))
        sources.append(f"preset {args.preset}")
    if args.config:
        layers.append(read_toml(args.config))
        sources.append(args.config)
    options = nested(given_settings(args))
    if args.brain is not None:  # beside the options: a GNP option with --brain cmaes is refused
        for key, value in family_class(args.brain).selection().items():
            given = options.get(key)
            if isinstance(given, dict) and isinstance(value, dict):
                value = {**given, **value}
            options[key] = value
    for path, value in args.assignments:
        target = options
        for part in path[:-1]:
            target = target.setdefault(part, {})
            if not isinstance(target, dict):
                raise ConfigError(f"--set {'.'.join(path)}: {part} is not a section")
        target[path[-1]] = value
    layers.append(options)
    return build_config(*layers, source=" + ".join([*sources, "options"]))


def _preset_file(preset: str, task: str | None) -> dict[str, Any]:
    """--preset FILE: a preset file's settings (a tuned one: for its task)."""
    from app.tune.preset import train_layer

    if not Path(preset).is_file() and not preset.endswith(".toml"):
        raise ConfigError(
            f"unknown preset {preset!r}; choose one of {', '.join(PRESET_NAMES)}, or give a "
            "preset file (.toml)"
        )
    return train_layer(preset, task)


def _preset_task(preset: str | None) -> tuple[EpisodeProtocol | None, dict[str, Any]]:
    """A preset file's episode protocol and task bounds (a tuned preset's `[task]`); none for
    any other."""
    if preset is None or preset in PRESET_NAMES or not Path(preset).is_file():
        return None, {}
    from app.tune.preset import train_task_table

    return train_task_table(preset)


class Bar:
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


class GenerationBar(Bar):
    """Progress over generations with the generation's best and mean fitness."""

    def __init__(self, total: int, initial: int, quiet: bool) -> None:
        super().__init__(total, initial, "train", "gen", quiet)

    def __call__(self, summary: GenerationSummary) -> None:
        self.update(
            summary.generation + 1,
            best=f"{summary.best_fitness:.3f}",
            mean=f"{summary.mean_fitness:.3f}",
        )


def workers_option(option: int | None) -> int:
    """--workers: default one per core, at least 1."""
    from app.phases.training import default_workers

    workers = option if option is not None else default_workers()
    if workers < 1:
        raise UsageError(f"--workers must be at least 1, got {workers}")
    return workers


def warm(config: RunConfig) -> None:
    """Compile (or load) the run's kernels in this process before its workers need them; the
    compile, on a cold cache only, is said by the command's `CompileWatch`."""
    from app.phases.warm import compiles_done, warm_up

    warm_up([config])
    compiles_done()


def _interrupted(stop: Exception, path: Path) -> int:
    sys.stderr.write(f"{PROG}: interrupted: {stop}; continue with: {PROG} train --resume {path}\n")
    return EXIT_INTERRUPTED


def cmd_train(args: argparse.Namespace) -> int:
    from app.phases import training

    workers = workers_option(args.workers)
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
        warm(config)
        bar = GenerationBar(config.training.generations, start, args.quiet)
        try:
            training.resume(path, workers=workers, progress=bar)
        except training.Interrupted as stop:
            bar.close()  # before the message, so the message is the last line
            return _interrupted(stop, path)
        finally:
            bar.close()
    elif args.task:
        from app.tasks import cli as task_cli

        protocol, bounds = _preset_task(args.preset)
        args.assignments[:0] = [(["task", key], value) for key, value in bounds.items()]
        task = task_cli.task_settings(args.task, args.assignments)  # --set task.* wins
        return task_cli.train(args, task, config_from_args(args), protocol)
    else:
        config = config_from_args(args)
        if args.print_config:
            sys.stdout.write(to_toml(config))
            return 0
        now = datetime.now(UTC)
        stem = family_of(config).file_stem
        path = Path(args.out) if args.out else new_run_path(args.runs_dir, stem, config.seed, now)
        if path.exists():
            raise RunFileError(f"{path} already exists; choose another --out or --resume it")
        warm(config)
        bar = GenerationBar(config.training.generations, 0, args.quiet)
        try:
            training.train(config, path, workers=workers, progress=bar)
        except training.Interrupted as stop:
            bar.close()  # before the message, so the message is the last line
            return _interrupted(stop, path)
        finally:
            bar.close()
    with RunReader(path) as run:  # the run's own record, as `gnp-lab runs` reads it
        print(f"{path}: finished, {best_words(run.history().best_fitness)}")
    return 0
