"""The environments GNP drives on a Gymnasium task, observation faults included, pass
Gymnasium's own `check_env` (issue #34's target)."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from app.tasks.faults import ObservationFault, ObservationFaults
from sim import FAULT_MODES

#: Warnings check_env gives these envs on purpose: it is handed the lab's wrapper (not the
#: bare env), and CartPole's velocities are unbounded in its own space.
EXPECTED = ("is different from the unwrapped version", "value is -infinity", "value is infinity")


@pytest.mark.parametrize("task", ["CartPole-v1", "MountainCar-v0", "Acrobot-v1"])
@pytest.mark.parametrize("mode", FAULT_MODES)
@pytest.mark.parametrize("step", [0, 3])
def test_the_env_gnp_drives_passes_check_env(task: str, mode: str, step: int) -> None:
    env = gym.make(task).unwrapped
    space = env.observation_space
    assert isinstance(space, gym.spaces.Box)
    low = np.where(np.isfinite(space.low), space.low, -3.0)
    high = np.where(np.isfinite(space.high), space.high, 3.0)
    faulty = ObservationFaults(env, (ObservationFault(step, (0, 1), mode),), low, high, seed=7)  # type: ignore[arg-type]
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        check_env(faulty, skip_render_check=True)
    unexpected = [str(w.message) for w in seen if not any(e in str(w.message) for e in EXPECTED)]
    assert not unexpected


def test_a_reset_seed_fixes_the_random_readings_that_follow() -> None:
    def episodes(seed: int | None) -> list[np.ndarray]:
        env = gym.make("CartPole-v1").unwrapped
        low, high = np.full(4, -3.0), np.full(4, 3.0)
        faulty = ObservationFaults(env, (ObservationFault(0, (2,), "random"),), low, high, 5)
        faulty.reset(seed=11)  # an episode before: the ones after depend on its seed only
        return [faulty.reset(seed=seed)[0] for _ in range(2)] + [faulty.reset()[0]]

    a, b = episodes(3), episodes(3)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert a[0][2] == a[1][2]  # the same seed, the same draw
    assert a[2][2] != a[1][2]  # the next unseeded episode draws anew
    assert not np.array_equal(episodes(4)[0], a[0])
