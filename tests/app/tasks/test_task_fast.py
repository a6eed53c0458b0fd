"""The lab's compiled CartPole-v1, MountainCar-v0 and Acrobot-v1 (app.tasks.dynamics) against
Gymnasium's own envs, step for step, and the fast lives against the Gymnasium path."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import gymnasium as gym
import numpy as np
import pytest

from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, dynamics, read_task_run, train_task
from gnp import Schedule

TASKS = ["CartPole-v1", "MountainCar-v0", "Acrobot-v1", "CartPole-v0"]


def _policy(task: str, obs: np.ndarray, rng: np.random.Generator, greedy: bool) -> np.ndarray:
    """Random actions, or a crude controller that keeps episodes long (or reaches the goal)."""
    n = obs.shape[0]
    if not greedy:
        return np.asarray(rng.integers(0, 2 if task.startswith("CartPole") else 3, n))
    if task.startswith("CartPole"):
        return (obs[:, 2] + 0.5 * obs[:, 3] > 0).astype(np.int64)
    if task == "MountainCar-v0":
        return np.where(obs[:, 1] >= 0, 2, 0)
    return np.where(obs[:, 4] >= 0, 2, 0)


@pytest.mark.filterwarnings("ignore:.*CartPole-v0 is out of date")
@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("greedy", [False, True])
def test_the_batched_dynamics_are_gymnasiums_env_bit_for_bit(task: str, greedy: bool) -> None:
    fast = dynamics.FAST_TASKS[task]
    assert fast.horizon == gym.spec(task).max_episode_steps
    seeds = np.arange(24) * 7919 + 3
    state, obs = dynamics.starts(fast, seeds)
    envs = [gym.make(task) for _ in seeds]
    for env, seed, first in zip(envs, seeds, obs, strict=True):
        expected, _ = env.reset(seed=int(seed))
        np.testing.assert_array_equal(first, expected)
    rng = np.random.default_rng(int(greedy))
    live = np.ones(len(seeds), bool)
    ended = {"terminated": 0, "truncated": 0}
    for t in range(fast.horizon):
        actions = _policy(task, obs, rng, greedy)
        obs, reward, terminated = dynamics.step_batch(fast, state, actions)
        truncated = t + 1 >= fast.horizon
        for i in np.flatnonzero(live):
            o, r, term, trunc, _ = envs[i].step(int(actions[i]))
            assert o.dtype == obs.dtype
            np.testing.assert_array_equal(obs[i], o, err_msg=f"{task} seed {seeds[i]} step {t}")
            assert (reward[i], bool(terminated[i]), truncated) == (r, term, trunc)
            if term or trunc:
                live[i] = False
                ended["terminated" if term else "truncated"] += 1
        if not live.any():
            break
    assert not live.any()
    assert sum(ended.values()) == len(seeds)
    for env in envs:
        env.close()


@pytest.mark.parametrize("spread", [1.0, 40.0])
def test_the_pendulum_twin_is_gymnasiums_env_bit_for_bit(spread: float) -> None:
    """Whole episodes of many seeds under random float32 torques, most of them far outside ±2
    (clipped) when `spread` is 40: the same observations, rewards and truncation."""
    fast = dynamics.FAST_TASKS["Pendulum-v1"]
    assert fast.horizon == gym.spec("Pendulum-v1").max_episode_steps == 200 and fast.box
    seeds = np.arange(64) * 7919 + 3
    n = len(seeds)
    state, obs = dynamics.starts(fast, seeds)
    envs = [gym.make("Pendulum-v1") for _ in seeds]
    for env, seed, first in zip(envs, seeds, obs, strict=True):
        expected, _ = env.reset(seed=int(seed))
        np.testing.assert_array_equal(first, expected)
    rng = np.random.default_rng(int(spread))
    reward, terminated = np.empty(n), np.empty(n, np.bool_)
    done, elapsed = np.empty(n, np.bool_), np.zeros(n, np.int64)
    for t in range(fast.horizon):
        actions = (rng.normal(size=(n, 1)) * spread).astype(np.float32)
        dynamics.step_live(fast, state, actions, obs, reward, terminated, done, elapsed)
        for i in range(n):
            o, r, term, trunc, _ = envs[i].step(actions[i])
            assert o.dtype == obs.dtype and type(r) is np.float64
            np.testing.assert_array_equal(obs[i], o, err_msg=f"seed {seeds[i]} step {t}")
            assert (reward[i], bool(terminated[i]), bool(done[i])) == (r, term, trunc)
            assert trunc == (t + 1 == fast.horizon)
    assert done.all() and (elapsed == -1).all()
    for env in envs:
        env.close()


def _training(
    task: str, method: Literal["RL", "BS", "CS"], controller: dict[str, Any] | None = None
) -> TaskRunConfig:
    controller = controller or {}
    return TaskRunConfig(
        seed=3,
        task=TaskSettings(id=task),
        brain=GnpSettings(
            controller=ControllerSettings(method=method, fuzzy=method == "CS", **controller)
        ),
        training=TaskTraining(
            population=10, generations=3, steps=200, epsilon=Schedule.fixed(0.05)
        ),
    )


@pytest.mark.parametrize(
    ("task", "method", "controller"),
    [
        ("CartPole-v1", "RL", {}),
        ("MountainCar-v0", "BS", {}),
        ("Acrobot-v1", "CS", {}),
        # the settings made for tasks (#45), the terminal update's credit skip included
        ("Acrobot-v1", "CS", {"skip_reward": "step", "q0": -10.0, "tie_break": "first"}),
        ("CartPole-v1", "RL", {"processing_output": "function", "threshold_init": "midpoint"}),
        ("MountainCar-v0", "BS", {"judgment_branches": 3}),  # Q_BS's end of episode with k
    ],
)
def test_a_fast_training_is_the_gymnasium_training(
    task: str,
    method: Literal["RL", "BS", "CS"],
    controller: dict[str, Any],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    config = _training(task, method, controller)
    fast = read_task_run(train_task(config, tmp_path / "fast.h5"))
    monkeypatch.setattr(dynamics, "FAST_TASKS", {})
    slow = read_task_run(train_task(config, tmp_path / "gym.h5"))
    np.testing.assert_array_equal(fast.fitness, slow.fitness)
    for g in range(3):
        _, best_fast = fast.best_genome(g)
        _, best_slow = slow.best_genome(g)
        np.testing.assert_array_equal(best_fast.records, best_slow.records)
