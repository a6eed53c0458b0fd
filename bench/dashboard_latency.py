"""How fast the dashboard's controls answer while it trains or runs an experiment, server side.

Builds the dashboard (no browser), starts a training run from its Train tab (or, with
`--during experiment`, ch3-bs-rl at small scale from its Experiments tab, on the dashboard's
Dask cluster), and every 100 ms applies a control action the way a GUI callback does
(`status.guarded`: wait for the dashboard's lock, act). Prints the latency distribution; the
brief asks for answers within 200 ms. During an experiment it also times switching the
Experiments tab's scale until the other scale's view is on the page (read in the background).

    .venv/bin/python bench/dashboard_latency.py --seconds 30
    .venv/bin/python bench/dashboard_latency.py --seconds 60 --during experiment
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import viser

from app.dashboard.app import Dashboard
from app.dashboard.status import set_value


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="how long to measure")
    parser.add_argument("--runs-dir", default=None, help="runs dir (default: a temporary one)")
    parser.add_argument("--during", choices=("training", "experiment"), default="training")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as scratch:
        runs_dir = Path(args.runs_dir or scratch)
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
        dashboard = Dashboard(server, runs_dir)
        try:
            if args.during == "training":
                set_value(dashboard.train.preset, "quick")
                generations = dashboard.train.settings.controls[("training", "generations")]
                set_value(generations, 10_000)  # trains for the whole measure
                dashboard.status.guarded(None, dashboard.train.start)

                def busy() -> str:
                    return f"generation {dashboard.plots.fitness_points} reached"

            else:
                busy = start_experiment(dashboard)
            latencies, views = [], []
            end = time.monotonic() + args.seconds
            while time.monotonic() < end:
                start = time.perf_counter()
                dashboard.status.guarded(None, dashboard.faults.repair)
                latencies.append(time.perf_counter() - start)
                if args.during == "experiment" and len(latencies) % 20 == 0:
                    views.append(switch_scale(dashboard))
                time.sleep(0.1)
            ms = 1000 * np.array(latencies)
            print(
                f"{len(ms)} control actions during {args.during} ({busy()}): "
                f"median {np.median(ms):.1f} ms, p95 {np.percentile(ms, 95):.1f} ms, "
                f"p99 {np.percentile(ms, 99):.1f} ms, max {ms.max():.1f} ms"
            )
            if views:
                ms = 1000 * np.array(views)
                print(
                    f"{len(ms)} scale switches in the Experiments tab, until the view is on the "
                    f"page: median {np.median(ms):.0f} ms, max {ms.max():.0f} ms"
                )
        finally:
            dashboard.stop()
            server.stop()
    return 0


def start_experiment(dashboard: Dashboard) -> Callable[[], str]:
    """Start ch3-bs-rl at small scale (minutes of runs) from the Experiments tab; returns a
    description of how far it got."""
    tab = dashboard.experiments
    until(lambda: "ch3-bs-rl" in tab.entries)
    with dashboard.lock:
        set_value(tab.experiment, "ch3-bs-rl")
        set_value(tab.scale, "small")
        tab.select()
    dashboard.status.guarded(None, tab.start)
    until(lambda: "running on the Dask cluster" in tab.progress_text.content, 600.0)
    return lambda: tab.progress_text.content.splitlines()[0].split(" · ", 2)[-1].strip()


def switch_scale(dashboard: Dashboard) -> float:
    """Seconds from choosing the other scale to its view on the page."""
    tab = dashboard.experiments
    scale = "smoke" if tab.scale.value == "small" else "small"
    start = time.perf_counter()
    with dashboard.lock:
        set_value(tab.scale, scale)
        tab.select()
    until(lambda: tab.view is not None and tab.view.scale == scale)
    return time.perf_counter() - start


def until(condition: Callable[[], bool], seconds: float = 120.0) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        if time.monotonic() > deadline:
            raise TimeoutError("the dashboard never reached the state")
        time.sleep(0.005)


if __name__ == "__main__":
    sys.exit(main())
