"""fracnetics' arm on Gymnasium's env and on the lab's compiled twin of it, side by side: CPU
microseconds per env-step of one `train_fracnetics` run on each task, the two envs alternating
within each round (the order flips every round), and the two runs' results checked equal.

    .venv/bin/python bench/fracnetics_twin.py [--population 100] [--generations 8] [--rounds 2]

Each task runs its tuned fracnetics arm (the `fracnetics-tuned` arm of
gnp-vs-fracnetics-tuned-<task>), seed 6200, 20 test episodes; env-steps are training's and the
tests'. Reported: best of `--rounds` per env and Gymnasium / twin (above 1: the twin is cheaper).

Measured 2026-12-06 (2 shared cores, ch4 running beside it at nice 19), 100 x 8, best of 2:
CartPole-v1 15.7 against 20.3 µs (1.3x; fracnetics' own decisions are most of its step),
MountainCar-v0 3.8 against 9.8 (2.6x), Acrobot-v1 2.1 against 26.7 (12.4x).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from app.experiments.spec_loading import load_shipped
from app.tasks.fracnetics_arm import (
    FracneticsResult,
    FracneticsSettings,
    arm_settings,
    train_fracnetics,
)

TASKS = {
    "CartPole-v1": "gnp-vs-fracnetics-tuned-cartpole",
    "MountainCar-v0": "gnp-vs-fracnetics-tuned-mountaincar",
    "Acrobot-v1": "gnp-vs-fracnetics-tuned-acrobot",
}


def _tuned(task: str) -> tuple[FracneticsSettings, list[int]]:
    """The spec's tuned fracnetics settings on `task`, and its test episode seeds."""
    spec = load_shipped(TASKS[task])
    assert spec.task is not None, f"{TASKS[task]} is a task experiment"
    return arm_settings(task, spec.arm("fracnetics-tuned").fracnetics), list(spec.task.seeds())


def _run(
    task: str, tuned: tuple[FracneticsSettings, list[int]], population: int, generations: int,
    twin: bool,
) -> tuple[float, FracneticsResult]:  # fmt: skip
    settings, tests = tuned
    cpu = time.process_time()
    result = train_fracnetics(task, settings, population, generations, 6200, 500, tests, twin=twin)
    cpu = time.process_time() - cpu
    steps = int(result.env_steps.sum() + result.test_lengths.sum())
    return cpu / steps * 1e6, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--population", type=int, default=100)
    parser.add_argument("--generations", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    print(f"population {args.population}, {args.generations} generations, best of {args.rounds}")
    print(f"{'task':16}{'gymnasium µs':>14}{'twin µs':>10}{'gymnasium / twin':>18}")
    for task in TASKS:
        tuned = _tuned(task)
        best = {True: np.inf, False: np.inf}
        results: dict[bool, FracneticsResult] = {}
        for r in range(args.rounds):
            for twin in (r % 2 == 0, r % 2 == 1):
                cost, results[twin] = _run(task, tuned, args.population, args.generations, twin)
                best[twin] = min(best[twin], cost)
        same = np.array_equal(results[True].fitness, results[False].fitness) and np.array_equal(
            results[True].test_returns, results[False].test_returns
        )
        if not same:
            raise SystemExit(f"{task}: the twin's run differs from Gymnasium's")
        print(f"{task:16}{best[False]:>14.2f}{best[True]:>10.2f}{best[False] / best[True]:>17.1f}x")


if __name__ == "__main__":
    main()
