"""Issue #48's kernels against a base commit's worktree: a training generation's CPU time and the
compiled loop's robot-steps per CPU second, side by side in one run.

    git worktree add --detach ../gnp-lab-f8707a9 f8707a9     # issue #48's base
    .venv/bin/python bench/kernels.py --baseline ../gnp-lab-f8707a9 [--population 300]
        [--steps 1000] [--loop-steps 500] [--rounds 5]

Every measurement is a fresh process of this venv whose PYTHONPATH is the tree measured, running
that tree's own bench code (`bench/versus.py`'s generation, `bench/limit.py`'s life), so both
trees run on the same interpreter and packages; the trees alternate within each round (the
order flips every round), so a busy machine's drifts hit both alike. Measured (thesis-ch3,
σ = 50, analytic physics):
- a training generation: `app.phases.training.train`, `--population` × `--steps`, 1 worker, the
  second of three generations' evaluate + evolve + write (`bench/versus.py`); the target is at
  most 1/1.4 of the base's CPU time;
- the compiled loop: `bench/limit.py`'s "rollout analytic" (a recorded life of `--population`
  generation-0 controllers, `--loop-steps` steps, k steps a compiled call, robots in blocks),
  best of 3 lives per process; the moonshot is 3.5 M robot-steps per CPU second.
Reported: best of `--rounds` CPU seconds (the process and its children) and the ratio base /
this tree (above 1: this tree is faster).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
GENERATION_TARGET = 1.4
LOOP_MOONSHOT = 3.5e6


def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _tree_bench(tree: Path) -> None:
    """Import the measured tree's own bench modules (`versus`, `limit`) first."""
    sys.path.insert(0, str(tree / "bench"))


def generation_child(tree: Path, population: int, steps: int) -> float:
    """CPU seconds of the second of three generations (`bench/versus.py`'s `generation`)."""
    _tree_bench(tree)
    import versus

    return float(versus.generation(population, steps)[1])


def loop_child(tree: Path, robots: int, steps: int, lives: int = 3) -> float:
    """Best CPU seconds of `lives` lives of `bench/limit.py`'s "rollout analytic"."""
    _tree_bench(tree)
    import limit

    from app.settings.loading import build_config, load_preset

    config = build_config(
        load_preset("thesis-ch3").model_dump(), {"training": {"noise_sigma": 50.0}}
    )
    life = limit.record(config, robots, steps)
    run = limit.rollout_life(life, physics="analytic")
    run()  # numba's caches loaded
    best = float("inf")
    for _ in range(lives):
        began = time.process_time()
        run()
        best = min(best, time.process_time() - began)
    return best


def _measure(tree: Path, args: list[str]) -> float:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    command = [sys.executable, __file__, "--child", str(tree), *args]
    out = subprocess.run(command, env=env, check=True, capture_output=True)
    return float(json.loads(out.stdout.decode().strip().splitlines()[-1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--baseline", type=Path)
    parser.add_argument("--population", type=int, default=300)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--loop-steps", type=int, default=500)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        tree, kind, *numbers = args.child
        values = [int(v) for v in numbers]
        measure = generation_child if kind == "generation" else loop_child
        print(json.dumps(measure(Path(tree), *values)))
        return
    if args.baseline is None:
        parser.error("--baseline (a git worktree of the commit to compare with) is required")
    trees = {"this tree": HERE, "baseline": args.baseline.resolve()}
    cases = {
        "training generation": ["generation", str(args.population), str(args.steps)],
        "compiled loop": ["loop", str(args.population), str(args.loop_steps)],
    }
    best = {(case, tree): float("inf") for case in cases for tree in trees}
    for r in range(args.rounds):
        for case, arguments in cases.items():
            order = list(trees) if r % 2 == 0 else list(trees)[::-1]
            for tree in order:
                seconds = _measure(trees[tree], arguments)
                best[case, tree] = min(best[case, tree], seconds)
    print(
        f"thesis-ch3, σ = 50, analytic, 1 worker; generation {args.population} × {args.steps} "
        f"steps, loop {args.population} × {args.loop_steps}; best of {args.rounds} alternating "
        "rounds, CPU seconds"
    )
    for case in cases:
        new, old = best[case, "this tree"], best[case, "baseline"]
        print(
            f"  {case:20} this tree {new:7.4f}   baseline {old:7.4f}   baseline / this tree "
            f"{old / new:5.2f}×"
        )
    ratio = best["training generation", "baseline"] / best["training generation", "this tree"]
    met = "met" if ratio >= GENERATION_TARGET else "not met"
    print(f"  generation target ≥ {GENERATION_TARGET}× the baseline's speed: {ratio:.2f}×, {met}")
    work = args.population * args.loop_steps
    for tree in trees:
        rate = work / best["compiled loop", tree]
        print(
            f"  {tree}: compiled loop {rate / 1e6:.2f} M robot-steps per CPU second "
            f"({1e9 / rate:.0f} ns per robot-step; moonshot {LOOP_MOONSHOT / 1e6:.1f} M)"
        )


if __name__ == "__main__":
    main()
