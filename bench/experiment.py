"""Experiment scale-out: the same runs one after another in one process vs on a LocalCluster.

    .venv/bin/python bench/experiment.py [--experiment ch3-bs-rl] [--scale smoke] [--seeds 3]
        [--population 100] [--generations 20] [--steps 1000] [--workers 2]

The training sizes (population, generations, steps) overlay the scale's, so a modest bench
(default: 6 runs of about 5 s each, a minute in all) uses the experiment's own arms and
conditions. Prints the wall time of both, the scale-out, the cluster's start-up, the per-task
overhead (a batch of trivial tasks, and the cluster's wall time beyond the best possible
schedule of the measured run times), and checks that both give identical results.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from distributed import get_task_stream

from app.experiments.cluster import connect, warm_numba
from app.experiments.execution import execute, run_task
from app.experiments.harvest import collect
from app.experiments.planning import plan
from app.experiments.spec import ExperimentSpec
from app.experiments.spec_loading import load_shipped, parse


def _sized(spec: ExperimentSpec, scale: str, sizes: dict[str, int]) -> ExperimentSpec:
    data = spec.model_dump()
    training = data["scales"][scale]["config"].setdefault("training", {})
    training.update({k: v for k, v in sizes.items() if v})
    return parse(data, "bench")


def _best_schedule(durations: list[float], workers: int) -> float:
    """Wall time of the longest-first schedule of `durations` on `workers` (a lower bound's
    stand-in: what a zero-overhead cluster would take)."""
    loads = [0.0] * workers
    for d in sorted(durations, reverse=True):
        loads[loads.index(min(loads))] += d
    return max(loads)


def _noop(i: int) -> int:
    return i


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--experiment", default="ch3-bs-rl")
    parser.add_argument("--scale", default="smoke")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--population", type=int, default=100)
    parser.add_argument("--generations", type=int, default=20)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    sizes = {"population": args.population, "generations": args.generations, "steps": args.steps}
    spec = _sized(load_shipped(args.experiment), args.scale, sizes)
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="gnp-lab-bench-") as folder:
        alone, cluster = Path(folder) / "sequential", Path(folder) / "cluster"
        tasks = plan(spec, args.scale, alone, args.seeds)
        warm_numba(tasks)
        durations = []
        cpu = time.process_time()
        began = time.perf_counter()
        for task in tasks:
            t = time.perf_counter()
            run_task(task)
            durations.append(time.perf_counter() - t)
        sequential = time.perf_counter() - began
        cpu_sequential = time.process_time() - cpu

        t = time.perf_counter()
        with connect(workers=args.workers) as client:
            startup = time.perf_counter() - t
            t = time.perf_counter()
            client.run(warm_numba, tasks)  # imports and numba's cache, once per worker
            warm = time.perf_counter() - t
            t = time.perf_counter()
            client.gather(client.map(_noop, range(200), pure=False))
            trivial = (time.perf_counter() - t) / 200
            cpu_before = client.run(time.process_time)  # after the warm-up
            t = time.perf_counter()
            with get_task_stream(client) as stream:
                errors = execute(plan(spec, args.scale, cluster, args.seeds), client, quiet=True)
            parallel = time.perf_counter() - t
            cpu_after = client.run(time.process_time)
            cpu_workers = sum(cpu_after[w] - cpu_before[w] for w in cpu_before)
        assert not errors, errors
        a = collect(spec, args.scale, alone, args.seeds)
        b = collect(spec, args.scale, cluster, args.seeds)
        same = all(np.array_equal(a.scalars[k], b.scalars[k], equal_nan=True) for k in a.scalars)
        same &= all(np.array_equal(a.curves[k], b.curves[k], equal_nan=True) for k in a.curves)
    in_cluster = [
        part["stop"] - part["start"]
        for record in stream.data
        for part in record["startstops"]
        if part["action"] == "compute"
    ]
    ideal = _best_schedule(durations, args.workers)
    load = f"load average {load_before:.1f} before, {os.getloadavg()[0]:.1f} after"
    lines = [
        f"{spec.name} at {args.scale} with {sizes}: {len(tasks)} runs × "
        f"{len(spec.conditions)} conditions; {os.cpu_count()} cores, {load}",
        f"  sequential, one process  {sequential:7.2f} s  "
        f"(runs {min(durations):.2f}-{max(durations):.2f} s, sum {sum(durations):.2f} s)",
        f"  LocalCluster, {args.workers} workers  {parallel:7.2f} s  "
        f"(not included: start-up {startup:.2f} s, workers' imports and numba cache "
        f"{warm:.2f} s; runs in workers: sum {sum(in_cluster):.2f} s)",
        f"  scale-out                {sequential / parallel:7.2f}x  "
        f"(best schedule of the sequential run times: {sequential / ideal:.2f}x)",
        f"  per-task overhead        {trivial * 1e3:7.2f} ms per trivial task; wall time beyond "
        f"the workers' busiest share: {parallel - sum(in_cluster) / args.workers:+.2f} s",
        f"  CPU seconds              {cpu_sequential:7.2f} s in one process, "
        f"{cpu_workers:.2f} s in the workers ({cpu_workers / cpu_sequential - 1:+.1%}); "
        f"on {args.workers} idle cores: at most "
        f"{args.workers * cpu_sequential / cpu_workers:.2f}x",
        f"  identical results: {same}",
    ]
    print("\n".join(lines))


if __name__ == "__main__":
    main()
