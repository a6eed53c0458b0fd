"""Training throughput: one generation in-process vs split over worker processes, side by side.

    .venv/bin/python bench/training.py [--population 300] [--steps 300] [--generations 3]

Builds both evaluators once (worker start-up excluded), evaluates the same generation-0
population with the same seeds `--generations` times with each, alternating, and prints the
best wall time per generation and robot-steps per second. Also checks that both give the same
fitness (the determinism the run store relies on).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from app.config import build_config
from app.training import (
    Evaluator,
    LocalEvaluator,
    ProcessEvaluator,
    initial_population,
    life_seeds,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--population", type=int, default=300)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--generations", type=int, default=3)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--method", default="CS")
    args = parser.parse_args()
    config = build_config(
        {
            "controller": {"method": args.method},
            "training": {"population": args.population, "steps": args.steps},
        }
    )
    pop = initial_population(config)
    seeds = life_seeds(config.seed, 0, np.arange(args.population), 1, 10)
    evaluators: dict[str, Evaluator] = {
        "in-process": LocalEvaluator(config),
        f"{args.workers} workers": ProcessEvaluator(config, args.workers),
    }
    best = dict.fromkeys(evaluators, float("inf"))
    fitness = {}
    try:
        for name, evaluator in evaluators.items():  # warm-up: numba caches, first contacts
            fitness[name] = evaluator.evaluate(pop, seeds, 0.1, 0.1)[0].fitness
        for _ in range(args.generations):
            for name, evaluator in evaluators.items():
                began = time.perf_counter()
                evaluator.evaluate(pop, seeds, 0.1, 0.1)
                best[name] = min(best[name], time.perf_counter() - began)
    finally:
        for evaluator in evaluators.values():
            evaluator.close()
    robot_steps = args.population * args.steps
    print(f"{args.method}, {args.population} individuals × {args.steps} steps per generation")
    for name, seconds in best.items():
        print(
            f"  {name:12} {seconds:7.3f} s/generation  {robot_steps / seconds:10,.0f} robot-steps/s"
        )
    same = all(np.array_equal(f, fitness["in-process"]) for f in fitness.values())
    print(f"  same fitness in-process and in workers: {same}")


if __name__ == "__main__":
    main()
