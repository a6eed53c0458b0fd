"""The batch of compiled twins (`BatchEnv` mode "twin") against Gymnasium's envs: step for step
as a batch env, and whole training runs of every brain family the same to the bit."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
import pytest
from lab_fixtures import assert_same_data

from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.settings.loading import build_config
from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, dynamics, read_task_run, train_task
from app.tasks.lives import BatchEnv, batch_env, idle_actions
from app.tasks.spaces import TaskAdapter
from gnp import Schedule

TASKS = ["CartPole-v1", "MountainCar-v0", "Acrobot-v1", "CartPole-v0", "Pendulum-v1"]


def task_adapter(task: str) -> TaskAdapter:
    return TaskRunConfig(task=TaskSettings(id=task)).adapter


def _actions(adapter: TaskAdapter, n: int, rng: np.random.Generator) -> np.ndarray:
    """Random actions of the task's space: a Box action anywhere in it (the adapter's range)."""
    if adapter.kind == "discrete":
        picked = rng.integers(0, adapter.n_actions, n) + adapter.action_start
        return picked.astype(adapter.action_dtype)
    low, high = adapter.act_low, adapter.act_high
    return (low + rng.random((n, 1)) * (high - low)).astype(adapter.action_dtype)


@pytest.mark.filterwarnings("ignore:.*CartPole-v0 is out of date")
@pytest.mark.parametrize("task", TASKS)
def test_a_batch_of_twins_steps_as_gymnasiums_batch_env(task: str) -> None:
    """Observations, rewards, terminated and done of every env while its episode lasts (done
    at its time limit too), over two resets of the same batch; an ended env stays ended."""
    adapter = task_adapter(task)
    n = 16
    twins = BatchEnv(task, n, adapter, fused=False)
    gym_env = BatchEnv(task, n, adapter, twins=False)
    assert (twins.mode, gym_env.mode) == (
        "twin",
        "vector_entry_point" if "Cart" in task else "sync",
    )
    horizon = dynamics.FAST_TASKS[task].horizon
    rng = np.random.default_rng(5)
    for seeds in (np.arange(n) * 31 + 2, np.arange(n) * 17 + 1000):
        np.testing.assert_array_equal(twins.reset(seeds), gym_env.reset(seeds))
        alive = np.ones(n, bool)
        actions = idle_actions(adapter, n)
        for t in range(horizon + 3):
            actions[alive] = _actions(adapter, n, rng)[alive]
            got, want = twins.step(actions), gym_env.step(actions)
            assert got[0].dtype == want[0].dtype == np.float32
            for a, b in zip(got, want, strict=True):
                np.testing.assert_array_equal(a[alive], b[alive], err_msg=f"{task} step {t}")
            assert got[3][~alive].all() and not got[1][~alive].any()  # ended: reward 0, done
            alive &= ~got[3]
        assert not alive.any()
    twins.close()
    gym_env.close()


def test_a_batch_of_twins_refuses_actions_gymnasium_would_not_take() -> None:
    adapter = task_adapter("Pendulum-v1")
    env = BatchEnv("Pendulum-v1", 2, adapter)
    env.reset(np.arange(2))
    with pytest.raises(ValueError, match="float32"):
        env.step(np.zeros((2, 1)))
    discrete = BatchEnv("Acrobot-v1", 2, task_adapter("Acrobot-v1"), fused=False)
    discrete.reset(np.arange(2))
    with pytest.raises(ValueError, match=r"actions in 0\.\.2"):
        discrete.step(np.array([0, 3]))


def _gnp(task: str, method: Literal["RL", "CS"], fuzzy: bool, steps: int) -> TaskRunConfig:
    return TaskRunConfig(
        seed=3,
        task=TaskSettings(id=task),
        brain=GnpSettings(controller=ControllerSettings(method=method, fuzzy=fuzzy)),
        training=TaskTraining(
            population=8, generations=3, steps=steps, epsilon=Schedule.fixed(0.05)
        ),
    )


def _net(family: str, task: str, steps: int) -> TaskRunConfig:
    sizes = {"population": 8, "generations": 3, "steps": steps}
    run = build_config({"seed": 5, "brain": {"family": family}, "training": sizes})
    return TaskRunConfig.from_run_config(run, TaskSettings(id=task))


RUNS = {
    # Pendulum's episodes end at its time limit (200 steps), before the cap
    "gnp-rl-crisp-pendulum": lambda: _gnp("Pendulum-v1", "RL", False, 250),
    "gnp-rl-fuzzy-pendulum": lambda: _gnp("Pendulum-v1", "RL", True, 250),
    "gnp-cs-fuzzy-pendulum": lambda: _gnp("Pendulum-v1", "CS", True, 250),
    "cmaes-pendulum": lambda: _net("cmaes", "Pendulum-v1", 250),
    "neat-pendulum": lambda: _net("neat", "Pendulum-v1", 250),
    "cmaes-cartpole": lambda: _net("cmaes", "CartPole-v1", 500),
    "cmaes-acrobot": lambda: _net("cmaes", "Acrobot-v1", 500),
    "neat-cartpole": lambda: _net("neat", "CartPole-v1", 500),
}


@pytest.mark.parametrize("run", sorted(RUNS))
def test_a_training_on_twins_is_the_gymnasium_training(
    run: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    config = RUNS[run]()
    n = config.training.population
    probe = batch_env(config.family, config.task.id, n, config.adapter)
    assert probe.mode == "twin"
    probe.close()
    twin = read_task_run(train_task(config, tmp_path / "twin.h5"))
    monkeypatch.setattr(dynamics, "FAST_TASKS", {})
    probe = batch_env(config.family, config.task.id, n, config.adapter)
    assert probe.mode == "sync" if "Cart" not in config.task.id else "vector_entry_point"
    probe.close()
    slow = read_task_run(train_task(config, tmp_path / "gym.h5"))
    assert twin.generation_done == slow.generation_done == 3
    np.testing.assert_array_equal(twin.fitness, slow.fitness)
    assert len(np.unique(twin.fitness)) > 1  # lives that differ
    assert_same_data(tmp_path / "twin.h5", tmp_path / "gym.h5")
