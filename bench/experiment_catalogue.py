"""The dashboard's Experiments tab: reading the experiments' run counts, first and again.

    .venv/bin/python bench/experiment_catalogue.py [--runs-dir saved_runs] [--rounds 3]

Counting an experiment's runs done validates each run file (`planning.inspect`); the tab's
`StateCache` remembers a file's state while the file is unchanged, so a Refresh reads only the
files that changed. Each round reads the catalogue with an empty cache ("first read", what the
page does when it opens) and then again ("again", a Refresh with nothing written meanwhile),
side by side. Without `--runs-dir`, a folder of its own holds ch3-bs-rl's smoke runs (trained
first, a few seconds).

Measured 2026-12-07 on the development machine's saved_runs (1435 run files in 23 experiments'
folders, 2 idle cores): first read 13.7 s, again 0.53 s (26×, best of 2); after validation
looked each path up once (649e3d9), first read 10.7 s, again 0.51 s.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from app.dashboard import experiment_view as ev
from app.experiments import planning
from app.experiments.spec import ExperimentSpec

ROOT = Path(__file__).resolve().parents[1]


def read(runs_dir: Path, shipped: tuple[ExperimentSpec, ...]) -> float:
    """Seconds to read the catalogue with the current cache."""
    began = time.perf_counter()
    ev.catalogue(runs_dir, shipped)
    return time.perf_counter() - began


def smoke_runs(folder: Path) -> Path:
    """A runs dir holding ch3-bs-rl's smoke runs."""
    gnp_lab = [sys.executable, "-c", "import sys; from app.cli import main; sys.exit(main())"]
    subprocess.run(
        [*gnp_lab, "experiment", "run", "ch3-bs-rl", "--scale", "smoke", "--runs-dir",
         str(folder), "--workers", "1", "--quiet"],
        check=True, cwd=ROOT, stdout=subprocess.DEVNULL,
    )  # fmt: skip
    return folder


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs-dir", type=Path, default=None)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="gnp-lab-bench-") as folder:
        runs_dir = args.runs_dir or smoke_runs(Path(folder))
        shipped = ev.shipped_specs()
        first, again = [], []
        for _ in range(args.rounds):
            ev.STATES = planning.StateCache()  # what a new page starts from
            first.append(read(runs_dir, shipped))
            again.append(read(runs_dir, shipped))
        files = len(list((runs_dir / "experiments").glob("*/*/*.h5")))
    print(f"experiments catalogue: {files} run files in {runs_dir.name}'s experiments")
    print(
        f"  first read {min(first):8.3f} s   again {min(again):8.3f} s   "
        f"first / again {min(first) / min(again):.1f}×  (best of {args.rounds})"
    )


if __name__ == "__main__":
    main()
