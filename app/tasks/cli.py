"""The command line of task runs of any brain family: `gnp-lab train --task ID [--brain NAME]`,
`--resume` of a task run, `gnp-lab replay`, `gnp-lab runs NAME` and `gnp-lab export` of a task
run's controller (hooked in app/cli.py)."""

from __future__ import annotations

import argparse
import csv
import math
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from app.settings.config import ConfigError, RunConfig
from app.store import RunFileError, resolve_run
from app.store.controller_file import save_document
from app.system.exit_codes import EXIT_INTERRUPTED
from app.tasks.common import EpisodeProtocol
from app.tasks.config import TaskRunConfig, TaskSettings
from app.tasks.faults import ObservationFault
from app.tasks.store import read_task_run
from app.tasks.training import (
    GenerationSummary,
    Interrupted,
    check_episodes_memory,
    replay_episodes,
    resume_task,
    train_task,
)
from sim.gym_env import SEED_BOUND

_TASK_KEYS = ("obs_low", "obs_high", "act_low", "act_high")


def task_settings(task: str, assignments: list[tuple[list[str], Any]]) -> TaskSettings:
    """--task and the `--set task.KEY=VALUE` assignments (removed from `assignments`): NaN in a
    bound list means the space's bound (TOML has no null)."""
    given: dict[str, Any] = {"id": task}
    for path, value in list(assignments):
        if path[0] != "task":
            continue
        assignments.remove((path, value))
        key = ".".join(path[1:])
        if key not in _TASK_KEYS:
            raise ConfigError(f"--set task.{key}: unknown; task settings are {_TASK_KEYS}")
        if not isinstance(value, list):
            raise ConfigError(f"--set task.{key}: give a list, e.g. [-3.0, nan]")
        given[key] = tuple(None if v != v else v for v in value)  # NaN: the space's
    return TaskSettings(**given)


def _progress(quiet: bool) -> Any:
    def show(g: GenerationSummary) -> None:
        if not quiet:
            sys.stderr.write(
                f"generation {g.generation + 1}/{g.generations}: best return "
                f"{g.best_fitness:.1f}, mean {g.mean_fitness:.1f}, "
                f"{g.steps / max(g.seconds, 1e-9):,.0f} env-steps/s\n"
            )

    return show


def train(
    args: argparse.Namespace,
    settings: TaskSettings,
    config: RunConfig,
    protocol: EpisodeProtocol | None = None,
) -> int:
    """`gnp-lab train --task ...`: a task run file from the lab's settings (and a tuned
    preset's episode protocol)."""
    task_config = TaskRunConfig.from_run_config(config, settings, protocol)
    family = task_config.family  # an unusable task or brain: one line, before any file
    if args.print_config:
        sys.stdout.write(task_config.model_dump_json(indent=2) + "\n")
        return 0
    if args.out:
        path = Path(args.out)
    else:
        stamp = datetime.now(UTC).strftime("%Y%m%d-%H%M%S")
        name = settings.id.replace("/", "_")  # "ALE/Pong-v5": a file name, not a folder
        path = Path(args.runs_dir) / f"{name}-{family.label}-{stamp}.h5"
    try:
        train_task(task_config, path, _progress(args.quiet))
    except (KeyboardInterrupt, Interrupted):
        return _interrupted(path)
    return _finished(path)


def _finished(path: Path) -> int:
    """A task run trained to its last generation: one line with its best return."""
    run = read_task_run(path)
    print(f"{path}: finished, best return {run.fitness.max():.1f} on {run.config.task.id}")
    return 0


def _interrupted(path: Path) -> int:
    """Ctrl-C or SIGTERM: the file holds every complete generation (or does not exist)."""
    if not path.exists():
        raise KeyboardInterrupt  # nothing was written: the lab's own message
    done = read_task_run(path).generation_done
    sys.stderr.write(
        f"gnp-lab: interrupted: stopped after {done} complete generation(s); "
        f"continue with: gnp-lab train --resume {path}\n"
    )
    return EXIT_INTERRUPTED


def resume(path: Path, quiet: bool) -> int:
    """`gnp-lab train --resume` of a task run."""
    try:
        resume_task(path, _progress(quiet))
    except (KeyboardInterrupt, Interrupted):
        return _interrupted(path)
    return _finished(path)


def inspect(path: Path) -> int:
    """`gnp-lab runs NAME` of a task run: its task, progress, a few generations, its config."""
    run = read_task_run(path)
    done, total = run.generation_done, run.config.training.generations
    print(f"task run {path.name}: {run.config.task.id}, seed {run.config.seed}, "
          f"gnp-lab {run.package_version}")  # fmt: skip
    print(f"brain: {run.config.description}")
    print(f"generations {done}/{total}, {'finished' if done == total else 'interrupted'}")
    for g in sorted({0, done // 2, done - 1} if done else set()):
        returns = run.fitness[g]
        learned = not math.isnan(run.epsilon[g])  # NaN: a family that does not learn online
        rates = f"  ε {run.epsilon[g]:.3f}  α {run.alpha[g]:.3f}" if learned else ""
        print(
            f"  generation {g:5d}: best return {returns.max():.1f}  mean {returns.mean():.1f}"
            f" ± {returns.std():.1f}{rates}"
        )
    print("\n# config")
    print(run.config.model_dump_json(indent=2))
    return 0


def replay(args: argparse.Namespace) -> int:
    """`gnp-lab replay` (its options: `app.tasks.common.add_replay_parser`)."""
    path = resolve_run(args.runs_dir, args.run)
    try:
        features = tuple(int(f) for f in args.fault_features.split(",") if f.strip())
    except ValueError:
        raise ConfigError(
            f"--fault-features: expected J,K,... got {args.fault_features!r}"
        ) from None
    faults = (ObservationFault(args.fault_step, features, args.fault_mode),) if features else ()
    if args.episodes < 1:
        raise ConfigError(f"--episodes must be at least 1, got {args.episodes}")
    if args.seed < 0 or args.seed + args.episodes > SEED_BOUND:
        raise ConfigError(
            f"--seed: the seeds SEED..SEED+K-1 must lie in 0..{SEED_BOUND - 1}, got {args.seed}"
        )
    check_episodes_memory(read_task_run(path).config, args.episodes)
    seeds = list(range(args.seed, args.seed + args.episodes))
    epsilon = 0.0 if args.greedy else None
    lives = replay_episodes(path, seeds, args.generation, faults, epsilon=epsilon)
    if args.episodes == 1:
        print(f"return {lives.returns[0]:.1f} in {lives.lengths[0]} steps (seed {args.seed})")
    else:
        print(
            f"mean return {lives.returns.mean():.1f} ± {lives.returns.std(ddof=1):.1f} (sd) over "
            f"{args.episodes} episodes, seeds {seeds[0]}..{seeds[-1]}; "
            f"min {lives.returns.min():.1f}, max {lives.returns.max():.1f}"
        )
    return 0


def export(path: Path, out: Path, generation: int | None) -> int:
    """`gnp-lab export` of a task run: controller.json (the family's controller document, the
    task in its settings), fitness.csv."""
    run = read_task_run(path)
    g = run.generation_done - 1 if generation is None else generation
    family = run.config.family
    individual = run.best_individual(g)
    if out.exists() and any(out.iterdir()):
        raise RunFileError(f"{out} is not empty")
    rates = {"epsilon": float(run.epsilon[g]), "alpha": float(run.alpha[g])}
    about = {
        "run": path.stem,
        "generation": g,
        "task": run.config.task.model_dump(),
        **family.export_settings(),
        "seed": run.config.seed,
        **(rates if family.learns_online else {}),
        "fitness": float(run.fitness[g].max()),
        "gnp_lab_version": run.package_version,
    }
    document = family.controller_document(individual, about)
    out.mkdir(parents=True, exist_ok=True)
    save_document(out / "controller.json", document)
    with (out / "fitness.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["generation", "best_return", "mean_return"])
        for i, row in enumerate(run.fitness):
            writer.writerow([i, f"{row.max():.6g}", f"{row.mean():.6g}"])
    print(f"{out}: controller.json, fitness.csv")
    return 0
