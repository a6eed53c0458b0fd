"""Dask workers load numba's kernels when they start, not inside their first task."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from experiment_fixtures import write_tiny

from app.experiments.cluster import connect, warm_numba
from app.experiments.planning import plan
from app.experiments.spec_loading import load_file


def loaded() -> dict[str, bool]:
    """Which of the hot loop's kernels this process has compiled or loaded."""
    from gnp import kernel
    from sim import drive, noise, rays

    return {
        "ir_readings_grid": bool(rays.ir_readings_grid.signatures),
        "observe": bool(noise.observe.signatures),
        "drive_forces": bool(drive.drive_forces.signatures),
        "step_kernel": bool(kernel.step_kernel.signatures),
    }


@pytest.mark.slow
def test_workers_warm_at_start_and_when_they_join(tmp_path: Path) -> None:
    spec = load_file(write_tiny(tmp_path))
    tasks = plan(spec, "small", tmp_path / "runs", 1)
    with connect(workers=1) as client:
        (cold,) = client.run(loaded).values()
        assert not any(cold.values())  # a fresh worker has run no kernel yet
        warm_numba(tasks, client)
        (warm,) = client.run(loaded).values()
        assert all(warm.values()), warm
        client.cluster.scale(2)  # a worker that joins later warms up as it starts
        client.wait_for_workers(2)
        for _ in range(60):  # its plugin may still be setting up when the scheduler lists it
            joined = client.run(loaded).values()
            if all(all(w.values()) for w in joined):
                break
            time.sleep(0.5)
        assert len(joined) == 2 and all(all(w.values()) for w in joined), joined
