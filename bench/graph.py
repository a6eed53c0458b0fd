"""What the graph draws, full vs simplified: nodes, edges and line segments, and frame time.

    .venv/bin/python bench/graph.py [--run saved_runs/demo.h5] [--steps 600] [--frames 200]

A robot on show (the run's best individual, or an untrained random CS individual without a run)
lives `--steps` control steps; then the graph of a viser server (no browser attached) is drawn
from its snapshot in both views, side by side in one run: the nodes and edges on screen
(genome connections in the full view, transitions taken over the last 256 visits in the
simplified one), all the graph's line segments, and the wall time of `GraphView.update` — the
graph's part of a frame — as median and 95th percentile over `--frames` frames, the robot
stepping 3 control steps between frames (30 steps/s at 10 frames/s, the dashboard's default).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import viser

import gnp
import sim
from app import store
from app.brains.registry import family_of
from app.phases.live import LiveSession, RobotSpec
from app.settings.config import RunConfig, TrainingSettings
from app.views.genome import genome_view
from app.views.graph_counts import GRAPH_MODES
from app.views.graph_view import GraphView


def robot_spec(run: Path | None) -> RobotSpec:
    if run is not None and run.exists():
        with store.RunReader(run) as reader:
            family = family_of(reader.config)
            return RobotSpec(run.stem, family, family.best(reader))
    family = family_of(RunConfig(training=TrainingSettings(population=2)))
    return RobotSpec("random", family, family.take(family.first().individuals(), [0]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, default=Path("saved_runs/demo.h5"))
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--frames", type=int, default=200)
    args = parser.parse_args()
    spec = robot_spec(args.run)
    cfg, population = spec.family.graph_config, spec.population
    assert cfg is not None and isinstance(population, gnp.Population)  # GNP only
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        graph = GraphView(server, (0.0, -1.0), 1.0, 0.62)
        graph.set_genome(genome_view(cfg, population))
        print(
            f"{spec.label} ({cfg.method}, {cfg.n_nodes} nodes), after {args.steps} "
            f"steps; {args.frames} frames per view, 3 steps between frames"
        )
        print(
            f"  {'view':<11}{'nodes':>7}{'edges':>7}{'segments':>10}{'median ms':>11}{'p95 ms':>8}"
        )
        for mode in GRAPH_MODES:
            session = LiveSession(sim.load_arena("training"), [spec])
            session.step(args.steps)
            graph.set_mode(mode)
            times = []
            nodes = edges = segments = 0
            for _ in range(args.frames):
                session.step(3)
                snapshot = session.snapshot()[0]
                start = time.perf_counter()
                with server.atomic():
                    graph.update(snapshot)
                times.append(time.perf_counter() - start)
                drawn = graph.drawn()
                nodes += drawn.nodes
                edges += drawn.edges
                segments += drawn.segments
            median, p95 = 1e3 * np.percentile(times, [50, 95])
            f = args.frames
            print(
                f"  {mode:<11}{nodes / f:>7.1f}{edges / f:>7.1f}{segments / f:>10.1f}"
                f"{median:>11.2f}{p95:>8.2f}"
            )
    finally:
        server.stop()


if __name__ == "__main__":
    main()
