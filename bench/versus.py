"""The lab's loop against an older commit's, side by side: a training generation and a block
of implementation trials, wall and CPU time.

    git worktree add ../gnp-lab-3cf00cf 3cf00cf      # the commit before the compiled loop
    .venv/bin/python bench/versus.py --baseline ../gnp-lab-3cf00cf [--population 300]
        [--steps 1000] [--trials 1000] [--impl-steps 3000] [--rounds 3] [--workers 1 2]

Every measurement is a fresh process of this venv whose PYTHONPATH is the tree measured (this
checkout or the baseline's), so both run on the same interpreter and packages; the two trees
alternate within each round, so a busy machine's drifts hit both alike. Measured (thesis-ch3,
σ = 50, analytic physics):
- a training generation: `app.phases.training.train`, `--population` × `--steps`, 1 worker;
  the second of three generations' evaluate + evolve + write (the first pays for loading
  numba's caches, the last for re-living the elite);
- an implementation block: `run_implementation`, `--trials` trials × `--impl-steps` steps (a
  dead sensor at step 500), on each of `--workers`.
Reported: best of `--rounds` wall and CPU seconds (CPU: the process and its children), and the
baseline's time over this tree's (above 1: this tree is faster).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

HERE = Path(__file__).resolve().parents[1]


def _lab() -> SimpleNamespace:
    """The lab's entry points in the tree measured: app/ by role (#33), or the flat layout
    before it (3cf00cf), whose implementation phase took the GNP config, not a brain family.

    The layout is read from the tree's files, not from a failed import: the venv's editable
    install finds a module the tree lacks in the checkout that installed it, mixing two trees."""
    import app

    if (Path(app.__file__).parent / "phases").is_dir():
        from app.brains.gnp_brain import initial_population
        from app.brains.registry import family_of
        from app.phases.implementation import run_implementation
        from app.phases.training import train
        from app.settings.loading import build_config, load_preset

        brain = family_of
    else:
        from app.config import build_config, load_preset  # type: ignore[no-redef]
        from app.implementation import run_implementation  # type: ignore[no-redef]
        from app.training import initial_population, train  # type: ignore[no-redef]

        def brain(config: Any, io: Any = None) -> Any:  # noqa: ARG001
            return config.controller.gnp_config()

    return SimpleNamespace(
        build_config=build_config,
        load_preset=load_preset,
        initial_population=initial_population,
        run_implementation=run_implementation,
        train=train,
        brain=brain,
    )


def _config(population: int, steps: int) -> Any:
    lab = _lab()
    return lab.build_config(
        lab.load_preset("thesis-ch3").model_dump(),
        {
            "training": {
                "population": population,
                "steps": steps,
                "generations": 3,
                "noise_sigma": 50.0,
                "physics": "analytic",
            }
        },
    )


def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def generation(population: int, steps: int) -> tuple[float, float]:
    """(wall s, CPU s) of the second of three generations of a training run, 1 worker (the
    first loads numba's caches, the last re-lives the elite, recording it)."""
    marks: list[tuple[float, float]] = [(time.perf_counter(), _cpu())]
    with tempfile.TemporaryDirectory() as folder:
        _lab().train(
            _config(population, steps),
            Path(folder) / "bench.h5",
            workers=1,
            progress=lambda _: marks.append((time.perf_counter(), _cpu())),
        )
    (wall0, cpu0), (wall1, cpu1) = marks[1], marks[2]
    return wall1 - wall0, cpu1 - cpu0


def implementation(trials: int, steps: int, workers: int) -> tuple[float, float]:
    """(wall s, CPU s) of an implementation phase of a generation-0 individual."""
    lab = _lab()
    config = _config(2, 10)
    settings = config.implementation.model_copy(
        update={"repeats": trials // 10, "steps": steps, "noise_sigma": 50.0}
    )
    individual = lab.initial_population(config)
    run = {
        "seed": 0,
        "control_period": config.training.control_period,
        "name": "bench",
        "generation": 0,
        "physics": "analytic",
    }
    small = settings.model_copy(update={"repeats": 1, "steps": 20})
    brain = lab.brain(config)
    lab.run_implementation(brain, individual, small, **run)  # warm caches
    wall, cpu = time.perf_counter(), _cpu()
    lab.run_implementation(brain, individual, settings, workers=workers, **run)
    return time.perf_counter() - wall, _cpu() - cpu


def _measure(tree: Path, args: list[str]) -> tuple[float, float]:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    out = subprocess.run(
        [sys.executable, __file__, "--child", *args], env=env, check=True, capture_output=True
    )
    wall, cpu = json.loads(out.stdout.decode().strip().splitlines()[-1])
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--baseline", type=Path)
    parser.add_argument("--population", type=int, default=300)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--trials", type=int, default=1000)
    parser.add_argument("--impl-steps", type=int, default=3000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        kind, *numbers = args.child
        values = [int(v) for v in numbers]
        result = generation(*values) if kind == "generation" else implementation(*values)
        print(json.dumps(result))
        return
    if args.baseline is None:
        parser.error("--baseline (a git worktree of the commit to compare with) is required")
    trees = {"this tree": HERE, "baseline": args.baseline.resolve()}
    cases = {"training generation, 1 worker": ["generation", args.population, args.steps]}
    for w in args.workers:
        cases[f"implementation block, {w} worker{'s' * (w > 1)}"] = [
            "implementation",
            args.trials,
            args.impl_steps,
            w,
        ]
    best = {(c, t): (float("inf"), float("inf")) for c in cases for t in trees}
    for r in range(args.rounds):
        for case, child in cases.items():
            order = list(trees) if r % 2 == 0 else list(trees)[::-1]
            for tree in order:
                wall, cpu = _measure(trees[tree], [str(v) for v in child])
                old = best[case, tree]
                best[case, tree] = (min(old[0], wall), min(old[1], cpu))
    print(
        f"thesis-ch3, σ = 50, analytic; training {args.population} × {args.steps} steps, "
        f"implementation {args.trials // 10 * 10} trials × {args.impl_steps} steps; "
        f"best of {args.rounds} alternating rounds, seconds wall / CPU"
    )
    for case in cases:
        (nw, nc), (bw, bc) = best[case, "this tree"], best[case, "baseline"]
        print(
            f"  {case:34} this tree {nw:7.2f} / {nc:7.2f}   baseline {bw:7.2f} / {bc:7.2f}"
            f"   baseline / this tree {bw / nw:5.2f}× wall, {bc / nc:5.2f}× CPU"
        )
    for tree in trees:
        one = best["implementation block, 1 worker", tree][0] if 1 in args.workers else None
        for w in args.workers:
            if one is not None and w > 1:
                many = best[f"implementation block, {w} workers", tree][0]
                print(f"  {tree}: implementation, {w} workers / 1 worker {one / many:.2f}× (wall)")


if __name__ == "__main__":
    main()
