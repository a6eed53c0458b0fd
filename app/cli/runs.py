"""`gnp-lab runs`: the runs of a folder, or one run in detail."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from app.brains.registry import run_kind
from app.settings.loading import to_toml
from app.store import BEST_OF_RUN, RunReader, best_words, list_runs, resolve_run
from app.tasks.common import is_task_run

if TYPE_CHECKING:
    pass


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
    kinds = {s.name: run_kind(s) for s in summaries}
    w = max(10, *(len(kinds[s.name]) for s in summaries if not s.error))  # `task CartPole-v1`
    b = len(BEST_OF_RUN)
    print(f"{'name':32} {'method':{w}} {'generations':>12} {BEST_OF_RUN:>{b}}  status")
    for s in summaries:
        if s.error:
            print(f"{s.name:32} {'?':{w}} {'':>12} {'':>{b}}  unreadable: {s.error}")
            continue
        status = "finished" if s.finished else "running or interrupted"
        if s.implementations:
            status += f"; implementations: {', '.join(s.implementations)}"
        gens = f"{s.generations_done}/{s.generations}"
        print(f"{s.name:32} {kinds[s.name]:{w}} {gens:>12} {s.best_fitness:{b}.4f}  {status}")
    return 0


def _inspect(path: Path) -> int:
    from app.phases.implementation import describe_fault

    with RunReader(path) as run:
        history = run.history()
        done = run.generations_done
        print(f"run {path.name}: seed {run.seed}, gnp-lab {run.package_version}")
        print(
            f"generations {done}/{run.config.training.generations}, "
            f"{'finished' if run.finished else 'running or interrupted'}"
        )
        if done:
            print(best_words(history.best_fitness[:done]))
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
