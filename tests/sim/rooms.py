"""Arenas built in code for the world's tests."""

from __future__ import annotations

import sim
from sim.arena import ArenaSpec, StartPoseSpec, arena_from_spec


def box(width: float, height: float | None = None) -> sim.Arena:
    """An empty rectangular room (square when `height` is None), every start pose at its centre."""
    height = width if height is None else height
    spec = ArenaSpec(
        name="box",
        outer_wall=[(0, 0), (width, 0), (width, height), (0, height), (0, 0)],
        start_poses=[
            StartPoseSpec(name=f"p{i}", x=width / 2, y=height / 2, heading_deg=0) for i in range(10)
        ],
    )
    return arena_from_spec(spec)
