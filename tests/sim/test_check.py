"""The world's contract checker, over every shipped arena."""

import numpy as np
import pytest

import sim


@pytest.mark.parametrize("physics", sim.PHYSICS)
@pytest.mark.parametrize("name", sim.ARENA_NAMES)
def test_check_world_passes_on_every_shipped_arena(name: str, physics: sim.Physics) -> None:
    sim.check_world(sim.load_arena(name), n=20, steps=300, seed=1, physics=physics)


def test_check_world_catches_a_nondeterministic_world(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = {"n": 0}
    original = sim.World.sense

    def drifting(self: sim.World) -> np.ndarray:
        calls["n"] += 1
        return original(self) + (calls["n"] % 2) * 1e-9

    monkeypatch.setattr(sim.World, "sense", drifting)
    with pytest.raises(AssertionError, match="true readings differ"):
        sim.check_world(sim.load_arena("training"), n=2, steps=3)
