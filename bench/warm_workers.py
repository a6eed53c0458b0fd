"""A Dask worker's first task, cold and warm: what `WarmWorkers` moves out of it.

    .venv/bin/python bench/warm_workers.py [--experiment ch3-bs-rl] [--rounds 2]

For each round, a fresh LocalCluster of one worker runs one of the experiment's smoke-scale
runs twice, one after the other (client-side wall time of each task), first without the plugin (the
worker imports the lab and loads numba's kernels inside its first task), then with it (the
worker does that as it starts; the registration's wall time is shown apart). numba's on-disk
cache is warm in both (the client fills it first, as `execute` does).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from app.experiments.cluster import connect, warm_numba
from app.experiments.execution import run_task
from app.experiments.planning import plan
from app.experiments.spec_loading import load_shipped


def first_tasks(warm: bool, experiment: str, folder: Path) -> tuple[float, float, float]:
    """(registration s, first task s, second task s) on a fresh one-worker cluster."""
    spec = load_shipped(experiment)
    # the same run twice (in two folders): the second one finds the worker warm either way
    tasks = [plan(spec, "smoke", folder / part, 1)[0] for part in ("a", "b")]
    warm_numba(tasks)  # numba's cache on disk, from this process
    with connect(workers=1) as client:
        began = time.perf_counter()
        if warm:
            warm_numba(tasks, client)
        registration = time.perf_counter() - began
        seconds = []
        for task in tasks:
            began = time.perf_counter()
            client.submit(run_task, task, pure=False).result()
            seconds.append(time.perf_counter() - began)
    return registration, seconds[0], seconds[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--experiment", default="ch3-bs-rl")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    best: dict[bool, tuple[float, float, float]] = {}
    for _ in range(args.rounds):
        for warm in (False, True):
            with tempfile.TemporaryDirectory(prefix="gnp-lab-bench-") as folder:
                got = first_tasks(warm, args.experiment, Path(folder))
            best[warm] = min(best.get(warm, got), got, key=lambda t: t[1])
    print(f"{args.experiment} smoke runs on a fresh 1-worker LocalCluster (best of {args.rounds})")
    for warm, (registration, first, second) in best.items():
        label = "with WarmWorkers" if warm else "cold worker     "
        print(
            f"  {label}  first task {first:6.2f} s   second {second:6.2f} s   "
            f"first − second {first - second:+6.2f} s   registration {registration:5.2f} s"
        )


if __name__ == "__main__":
    main()
