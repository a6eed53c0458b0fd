"""One Gymnasium env of a task the lab has a compiled twin of (`dynamics.FAST_TASKS`, those with
a Discrete action: Pendulum's twin steps in batches only, `app.tasks.lives.BatchEnv`), stepped
from Python a step at a time: for fracnetics' arm, whose library steps the env it is handed.

`TwinEnv(id)` is `gymnasium.make(id)` bit for bit, seen from its caller: the same observations
(float32), rewards, `terminated` and `truncated` (its `TimeLimit`), and `reset(seed=s)` draws the
start from `np.random.default_rng(s)` as the env's `np_random` does (a `reset()` without a seed
draws the next start from the same generator). A step costs about 1 µs of compiled work where
Gymnasium's Python step costs 5-27 µs (Acrobot's RK4 the most); tests/app/tasks/test_twin_env.py
steps both side by side and runs whole fracnetics runs on both. It is stricter than Gymnasium in
four ways, all mistakes of a caller: a first `reset` needs a seed (the lab draws nothing from
unseeded entropy), a step after the episode ended (or before any reset) is refused, so is an
action outside the action space (Gymnasium asserts), and so are reset options (start bounds).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from app.tasks.common import TaskError
from app.tasks.dynamics import FAST_TASKS, start_states, step_row

TASKS = tuple(task for task, fast in FAST_TASKS.items() if not fast.box)
"""The tasks with a single-env twin: the discrete ones (Pendulum's steps in batches only)."""


class TwinEnv(gym.Env[np.ndarray, int]):
    """The compiled twin of `gymnasium.make(task)` as a single env (see the module)."""

    def __init__(self, task: str) -> None:
        if task not in TASKS:
            raise TaskError(
                f"{task!r} has no compiled single-env twin; the lab has {', '.join(TASKS)}"
            )
        self.task = task
        self._fast = FAST_TASKS[task]
        spaces = gym.make(task)  # its spaces, as a caller reads them from the env
        self.observation_space = spaces.observation_space
        self.action_space = spaces.action_space
        spaces.close()
        self._actions = int(self.action_space.n)  # type: ignore[attr-defined]
        self._state = np.zeros((1, self._fast.state_dim))
        self._obs = np.zeros((1, self._fast.obs_dim), np.float32)
        self._generator: np.random.Generator | None = None
        self._elapsed = 0
        self._live = False

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if options is not None:
            raise TaskError(f"{self.task} twin: reset options (start bounds) are not supported")
        if seed is not None:
            self._generator = np.random.default_rng(seed)
        if self._generator is None:
            raise TaskError(f"{self.task} twin: its first reset needs a seed")
        state, obs = start_states(self._fast, [self._generator])
        self._state[:] = state
        self._elapsed, self._live = 0, True
        return obs[0].copy(), {}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if not self._live:
            raise TaskError(f"{self.task} twin: a step with no live episode; reset first")
        if not 0 <= action < self._actions:
            raise TaskError(
                f"{self.task} twin: action {action} is not one of 0..{self._actions - 1}"
            )
        reward, terminated = step_row(self._fast.code, self._state, int(action), self._obs)
        self._elapsed += 1
        truncated = self._elapsed >= self._fast.horizon
        self._live = not (terminated or truncated)
        return self._obs[0].copy(), reward, terminated, truncated, {}
