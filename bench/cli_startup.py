"""`gnp-lab`'s start-up: today's lazy entry point against the eager one it replaced.

    .venv/bin/python bench/cli_startup.py [--rounds 5] [--runs-dir saved_runs]

Each command runs in a fresh interpreter (`python -c "from app.cli import main; main()" ARGS`,
what the `gnp-lab` script does), twice per round and side by side:

- **lazy**: the entry point as it is (`app.cli.main` imports each command's modules when it runs);
- **eager**: the same entry point after importing, first, every module `app/cli/main.py` imported
  at its top before it turned lazy (commit b8b20ec: numba through `sim` and `gnp`, the commands'
  modules, Dask's experiment CLI, the export) and building every command's options, as its
  parser did. That is the old start-up's work, timed in this tree with this numba cache. Since
  then `sim`, `gnp` and `neuro` turned lazy too (their `__init__`s import no submodule, issue #43
  item 4), so the eager side imports, by name, the submodules those `__init__`s imported, and
  the fused loop `app.brains` imported at its top.

Reported per command: the best wall and CPU seconds of the rounds (children's user + system
time, less noisy than wall time on a shared machine) and eager / lazy. The target (issue #43):
`--help` and `runs` in at most 0.5 s on a quiet machine.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

EAGER_MODULES = (
    *("gnp.config", "gnp.controller_file", "gnp.engine", "gnp.evolution", "gnp.methods"),
    *("gnp.population", "gnp.schedules"),
    *("sim.arena", "sim.check", "sim.faults", "sim.khepera", "sim.noise", "sim.reward"),
    *("sim.sensors", "sim.world"),
    *("neuro.controller_file", "neuro.nets", "neuro.neat_evolution"),
    "app.loop.rollout",
    "app.cli.implement",
    "app.cli.runs",
    "app.cli.serve",
    "app.cli.train",
    "app.experiments.cli",
    "app.export.cli",
    "app.settings.config",
    "app.store",
    "app.store.space",
    "app.tasks.common",
)
"""What `app/cli/main.py` imported at its top at commit b8b20ec (directly or through the old
parser, which imported these too), the eager package `__init__`s' submodules named."""

LAZY = "import sys; from app.cli import main; sys.exit(main())"
EAGER = (
    f"import {', '.join(EAGER_MODULES)}; from app.cli.parser import build_parser; "
    "build_parser(); " + LAZY
)


def run(code: str, arguments: list[str]) -> tuple[float, float]:
    """(wall s, CPU s) of `python -c code arguments` in a fresh interpreter."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    began = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", code, *arguments], cwd=ROOT, capture_output=True, text=True
    )
    wall = time.perf_counter() - began
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"cli_startup.py: {arguments} failed:\n{done.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--runs-dir", default=str(ROOT / "saved_runs"), help="listed by `runs`")
    args = parser.parse_args()
    cases = {
        "gnp-lab --help": ["--help"],
        "gnp-lab runs --help": ["runs", "--help"],
        "gnp-lab runs": ["runs", "--runs-dir", args.runs_dir],
        "gnp-lab train --help": ["train", "--help"],
        "gnp-lab implement --help": ["implement", "--help"],
    }
    run(LAZY, ["--help"])  # numba's cache and the OS's file cache filled before timing
    run(EAGER, ["--help"])
    best: dict[tuple[str, str], tuple[float, float]] = {}
    for _ in range(args.rounds):
        for name, arguments in cases.items():
            for side, code in (("lazy", LAZY), ("eager", EAGER)):
                wall, cpu = run(code, arguments)
                old = best.get((name, side), (wall, cpu))
                best[(name, side)] = (min(old[0], wall), min(old[1], cpu))
    print(f"gnp-lab start-up, best of {args.rounds} rounds (wall s / CPU s; eager: the imports")
    print("of app/cli/main.py before it turned lazy, then the same command)")
    for name in cases:
        (lazy_wall, lazy_cpu), (eager_wall, eager_cpu) = best[(name, "lazy")], best[(name, "eager")]
        print(
            f"  {name:26} lazy {lazy_wall:5.2f} / {lazy_cpu:5.2f}   "
            f"eager {eager_wall:5.2f} / {eager_cpu:5.2f}   "
            f"eager / lazy {eager_wall / lazy_wall:4.1f}× wall, {eager_cpu / lazy_cpu:4.1f}× CPU"
        )


if __name__ == "__main__":
    main()
