"""`TwinEnv` against `gymnasium.make`: step for step, and whole fracnetics runs on either env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from app.tasks.common import TaskError
from app.tasks.fracnetics_arm import documented, train_fracnetics
from app.tasks.twin_env import TwinEnv

TASKS = ["CartPole-v1", "MountainCar-v0", "Acrobot-v1"]


@pytest.mark.parametrize("task", TASKS)
def test_the_twin_steps_as_gymnasiums_env_across_seeded_and_unseeded_resets(task: str) -> None:
    twin, env = TwinEnv(task), gym.make(task)
    assert twin.observation_space == env.observation_space
    assert twin.action_space == env.action_space
    rng = np.random.default_rng(7)
    ends = {"terminated": 0, "truncated": 0}
    # an episode from a seed, then two from the same generator (reset() without a seed)
    for seed in (12345, None, None, 99, None):
        first, info = twin.reset(seed=seed)
        expected, _ = env.reset(seed=seed)
        assert first.dtype == expected.dtype == np.float32
        np.testing.assert_array_equal(first, expected)
        assert info == {}
        while True:
            action = int(rng.integers(0, twin.action_space.n))  # type: ignore[attr-defined]
            got = twin.step(action)
            want = env.step(action)
            np.testing.assert_array_equal(got[0], want[0])
            assert got[1:4] == want[1:4]
            assert isinstance(got[1], float) and isinstance(got[2], bool)
            if got[2] or got[3]:
                ends["terminated" if got[2] else "truncated"] += 1
                break
    assert sum(ends.values()) == 5


@pytest.mark.parametrize("task", TASKS)
def test_fracnetics_runs_the_same_on_the_twin_as_on_gymnasiums_env(task: str) -> None:
    settings = documented(task)
    runs = [
        train_fracnetics(task, settings, 20, 4, 31, 500, [1000000, 1000001, 1000002], twin=twin)
        for twin in (True, False)
    ]
    on_twin, on_gym = runs
    np.testing.assert_array_equal(on_twin.fitness, on_gym.fitness)
    np.testing.assert_array_equal(on_twin.test_returns, on_gym.test_returns)
    np.testing.assert_array_equal(on_twin.env_steps, on_gym.env_steps)
    np.testing.assert_array_equal(on_twin.test_lengths, on_gym.test_lengths)
    assert on_twin.env_steps.sum() > 20 * 4 * 9  # episodes were lived, not cut short


def test_the_twin_refuses_what_gymnasium_would_run_differently() -> None:
    twin = TwinEnv("CartPole-v1")
    with pytest.raises(TaskError, match="no live episode"):
        twin.step(0)
    with pytest.raises(TaskError, match="first reset needs a seed"):
        twin.reset()
    with pytest.raises(TaskError, match="options"):
        twin.reset(seed=1, options={"low": -0.1, "high": 0.1})
    twin.reset(seed=1)
    with pytest.raises(TaskError, match=r"action 2 is not one of 0\.\.1"):
        twin.step(2)
    while not any(twin.step(1)[2:4]):
        pass
    with pytest.raises(TaskError, match="no live episode"):
        twin.step(0)
    with pytest.raises(TaskError, match="no compiled single-env twin"):
        TwinEnv("Pendulum-v1")  # a Box action: its twin steps in batches only
    with pytest.raises(TaskError, match="no compiled single-env twin"):
        TwinEnv("LunarLander-v3")
