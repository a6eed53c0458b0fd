"""A training generation on 1 and 2 workers, side by side in one run: wall, CPU, and the wall
two idle cores would give, worked out from each process's CPU time.

    .venv/bin/python bench/workers.py [--populations 100 300 1000] [--steps 1000]
                                      [--generations 8] [--rounds 3] [--preset thesis-ch3]
                                      [--noise 50] [--physics analytic]

For each population, rounds alternate 1 worker (this process) and 2 workers (two pool processes,
this one writing the run file), so the machine's drifts hit both alike. Per generation (the
first two of a run excluded: the workers' start and numba's loading), medians of:
- wall: seconds from one generation's end to the next's;
- CPU: this process's CPU time plus its workers' (`/proc/PID/schedstat`, nanoseconds);
- idle: the wall time two idle cores would give, from the CPU times of each step of the
  generation (`Evaluator._run` watched): the lives take the longer of the busier worker's CPU
  and half of everyone's (this process writes the last generation meanwhile, on the same two
  cores), the evolution the busier worker's, plus this process's CPU sending the jobs, taking
  the answers and between the steps. One worker's idle wall is its CPU time. What it leaves
  out: the pipes' wake-up latency (tens of µs, four a generation). On a machine others keep
  busy (the load average is printed), the wall ratio reads low and the idle one is the figure
  to compare with the target (≥ 1.85×).

The 2 workers' serial share (this process's CPU outside the jobs) and the CPU they cost beyond
one worker are printed too, and each step's CPU time: the lives and the evolution in one
process, and on the two workers (RowsJob, EvolveJob: the busier worker's, and both's). Nothing
is timed that the lab does not do in a real run: it is `app.phases.training.train` into a run
file in a temporary folder.
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from app.brains.gnp_brain import GnpEvolution
from app.phases import generations
from app.phases.generations import GenerationSummary
from app.phases.training import train
from app.settings.loading import build_config, load_preset

Row = tuple[float, float, float, float]
"""A generation's wall s, CPU s, idle-core wall s and this process's serial CPU s."""


def children_ns() -> dict[int, int]:
    """CPU nanoseconds of each of this process's living children."""
    out = {}
    for child in multiprocessing.active_children():
        with contextlib.suppress(OSError, ValueError, IndexError):
            out[child.pid or 0] = int(Path(f"/proc/{child.pid}/schedstat").read_text().split()[0])
    return out


class Watch:
    """Per generation: wall, CPU of everyone, and the idle-core wall estimate."""

    def __init__(self) -> None:
        self.rows: list[Row] = []
        self.steps: dict[str, list[list[float]]] = {}  # each kind of job: workers' CPU s
        self._reset()

    def _reset(self) -> None:
        self.wall = time.perf_counter()
        self.cpu = time.process_time()
        self.kids = children_ns()
        self.idle = 0.0  # seconds the jobs' steps take on idle cores
        self.in_jobs = 0.0  # this process's CPU inside the jobs' steps (meanwhile included)

    def step(self, run: Callable[..., Any], jobs: list[Any], meanwhile: Callable[[], None]) -> Any:
        before, cpu = children_ns(), time.process_time()
        mine = 0.0

        def timed() -> None:
            nonlocal mine
            began = time.process_time()
            meanwhile()
            mine += time.process_time() - began

        out = run(jobs, timed)
        after = children_ns()
        used = [(after.get(pid, 0) - ns) / 1e9 for pid, ns in before.items()]
        busiest = max(used, default=0.0)
        self.steps.setdefault(type(jobs[0]).__name__, []).append(used)
        step = time.process_time() - cpu
        # sending the jobs and taking the answers in is serial; `meanwhile` shares the cores
        self.idle += step - mine + max(busiest, (sum(used) + mine) / 2)
        self.in_jobs += step
        return out

    def generation(self, _summary: GenerationSummary) -> None:
        wall, cpu = time.perf_counter(), time.process_time()
        kids = children_ns()
        children = sum(ns - self.kids.get(pid, ns) for pid, ns in kids.items()) / 1e9
        mine = cpu - self.cpu
        serial = mine - self.in_jobs  # this process's CPU between the jobs: the serial part
        idle = self.idle + serial if self.idle else mine
        self.rows.append((wall - self.wall, mine + children, idle, serial))
        self._reset()


def one_run(config: Any, workers: int, steps: dict[str, list[list[float]]]) -> list[Row]:
    """A run's generations; each step's CPU time added to `steps`."""
    watch = Watch()
    watch.steps = steps
    original = generations.Evaluator._run

    def watched(self: Any, jobs: list[Any], meanwhile: Callable[[], None] = lambda: None) -> Any:
        return watch.step(lambda j, m: original(self, j, m), jobs, meanwhile)

    def timed(kind: str, call: Callable[..., Any]) -> Callable[..., Any]:
        def run(*args: Any, **kwargs: Any) -> Any:  # one process's step: its CPU time
            began = time.process_time()
            out = call(*args, **kwargs)
            watch.steps.setdefault(kind, []).append([time.process_time() - began])
            return out

        return run

    local, advance = generations.Evaluator.evaluate, GnpEvolution.advance
    generations.Evaluator._run = watched  # type: ignore[method-assign]
    if workers == 1:
        generations.Evaluator.evaluate = timed("lives in 1 process", local)  # type: ignore[method-assign]
        GnpEvolution.advance = timed("evolution in 1 process", advance)  # type: ignore[method-assign]
    try:
        with tempfile.TemporaryDirectory() as folder:
            train(config, Path(folder) / "bench.h5", workers=workers, progress=watch.generation)
    finally:
        generations.Evaluator._run = original  # type: ignore[method-assign]
        generations.Evaluator.evaluate = local  # type: ignore[method-assign]
        GnpEvolution.advance = advance  # type: ignore[method-assign]
    return watch.rows[2:]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--populations", type=int, nargs="+", default=[100, 300, 1000])
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--generations", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--preset", default="thesis-ch3")
    parser.add_argument("--noise", type=float, default=50.0)
    parser.add_argument("--physics", default="analytic")
    args = parser.parse_args()
    if args.generations < 3:  # the first two are not timed
        parser.error(f"--generations must be at least 3 (got {args.generations})")
    print(
        f"{args.preset}, σ = {args.noise:g}, {args.physics}, {args.steps} steps; medians per "
        f"generation of {args.rounds} rounds × {args.generations - 2} generations"
    )
    for population in args.populations:
        config = build_config(
            load_preset(args.preset).model_dump(),
            {
                "training": {
                    "population": population,
                    "steps": args.steps,
                    "generations": args.generations,
                    "noise_sigma": args.noise,
                    "physics": args.physics,
                }
            },
        )
        warm = build_config(config.model_dump(), {"training": {"generations": 3}})
        one_run(warm, 2, {})
        rows: dict[int, list[Row]] = {1: [], 2: []}
        loads = []
        steps: dict[str, list[list[float]]] = {}
        for _ in range(args.rounds):
            for workers in (1, 2):
                rows[workers] += one_run(config, workers, steps)
                loads.append(os.getloadavg()[0])
        med = {w: [statistics.median(r[i] for r in rows[w]) for i in range(4)] for w in rows}
        (wall1, cpu1, idle1, _), (wall2, cpu2, idle2, serial2) = med[1], med[2]
        print(
            f"population {population}: 1 worker {wall1:.3f} s wall, {cpu1:.3f} CPU s; "
            f"2 workers {wall2:.3f} s wall, {cpu2:.3f} CPU s "
            f"(parent serial {serial2 * 1e3:.1f} ms)\n"
            f"  2 / 1 worker: wall {wall1 / wall2:.2f}×, on idle cores (from CPU) "
            f"{idle1 / idle2:.2f}×; CPU {cpu2 / cpu1 - 1:+.1%}; "
            f"load average {min(loads):.1f}–{max(loads):.1f}"
        )
        for kind, used in steps.items():  # per step: the busier process, everyone's sum
            busier = statistics.median(max(u) for u in used if u)
            total = statistics.median(sum(u) for u in used if u)
            print(
                f"  {kind:24} busier process {busier * 1e3:6.1f} ms CPU, "
                f"all {total * 1e3:6.1f} ms CPU"
            )


if __name__ == "__main__":
    main()
