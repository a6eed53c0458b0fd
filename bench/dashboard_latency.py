"""How fast the dashboard's controls answer while it trains, on the server side.

Builds the dashboard (no browser), starts a training run from its Train tab, and every 100 ms
applies a control action the way a GUI callback does (`status.guarded`: wait for the
dashboard's lock, act). Prints the latency distribution; the brief asks for answers within 200 ms.

    .venv/bin/python bench/dashboard_latency.py --seconds 30
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import viser

from app.dashboard.app import Dashboard
from app.dashboard.status import set_value


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="how long to measure")
    parser.add_argument("--runs-dir", default=None, help="runs dir (default: a temporary one)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as scratch:
        runs_dir = Path(args.runs_dir or scratch)
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
        dashboard = Dashboard(server, runs_dir)
        try:
            set_value(dashboard.train.preset, "quick")
            set_value(dashboard.train.generations, 10_000)  # keeps training for the whole measure
            dashboard.status.guarded(None, dashboard.train.start)
            latencies = []
            end = time.monotonic() + args.seconds
            while time.monotonic() < end:
                start = time.perf_counter()
                dashboard.status.guarded(None, dashboard.faults.repair)
                latencies.append(time.perf_counter() - start)
                time.sleep(0.1)
            ms = 1000 * np.array(latencies)
            generation = dashboard.plots.fitness_points
            print(
                f"{len(ms)} control actions during training (generation {generation} reached): "
                f"median {np.median(ms):.1f} ms, p95 {np.percentile(ms, 95):.1f} ms, "
                f"p99 {np.percentile(ms, 99):.1f} ms, max {ms.max():.1f} ms"
            )
        finally:
            dashboard.stop()
            server.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
