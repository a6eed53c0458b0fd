"""Observation faults on any task: the robot's broken sensors, as a Gymnasium wrapper.

A broken feature reads, from its fault's step on (steps counted from the episode's reset, the
reset's own observation being step 0): `dead` its low bound, `saturated` its high bound, `stuck`
the value it showed at the fault's step, `random` uniform in its bounds from the wrapper's own
seeded stream. The bounds are the ones the brain is scaled by (`TaskAdapter.obs_low/high`), so
a dead feature reads 0 and a saturated one 1023 to GNP, as a dead or saturated IR sensor does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from app.tasks.common import TaskError
from sim import FAULT_MODES, FaultMode


@dataclass(frozen=True)
class ObservationFault:
    """Features that break at `step` of every episode, reading as `mode` says."""

    step: int
    features: tuple[int, ...]
    mode: FaultMode = "dead"


class ObservationFaults(
    gym.ObservationWrapper[np.ndarray, Any, np.ndarray], gym.utils.RecordConstructorArgs
):
    """Breaks observation features on schedule (see the module docstring).

    Args:
        env: a task with a 1-D Box observation.
        faults: the schedule.
        low, high: (n,) finite bounds of each feature.
        seed: seed of the stream `random` draws from, restarted at every reset: from the
            last reset seed and the episodes since it (the Gymnasium way: the same seed, the
            same episodes after it), else from the episode's number, so an episode's draws
            never depend on the draws before.
    """

    def __init__(
        self,
        env: gym.Env,
        faults: Sequence[ObservationFault],
        low: np.ndarray,
        high: np.ndarray,
        seed: int = 0,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self, faults=tuple(faults), low=low, high=high, seed=seed
        )
        super().__init__(env)
        n = int(np.prod(env.observation_space.shape or (0,)))
        self._low = np.asarray(low, dtype=np.float64)
        self._high = np.asarray(high, dtype=np.float64)
        if self._low.shape != (n,) or self._high.shape != (n,):
            raise TaskError(f"fault bounds need shape ({n},)")
        if not (np.all(np.isfinite(self._low)) and np.all(np.isfinite(self._high))):
            raise TaskError("fault bounds must be finite")
        for fault in faults:
            if fault.mode not in FAULT_MODES:
                raise TaskError(f"unknown fault mode {fault.mode!r}; choose {FAULT_MODES}")
            if fault.step < 0:
                raise TaskError(f"a fault step must be ≥ 0, got {fault.step}")
            bad = [f for f in fault.features if not 0 <= f < n]
            if bad:
                raise TaskError(f"fault features {bad} outside 0..{n - 1}")
        self._faults = tuple(faults)
        self._seed = seed
        self._episode = -1
        self._base: int | None = None  # the last reset's seed, and the episodes since it
        self._since = 0
        self._t = 0
        self._stuck: dict[int, float] = {}
        self._rng = np.random.default_rng(seed)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        self._episode += 1
        self._t = 0
        self._stuck = {}
        if kwargs.get("seed") is not None:  # episodes from here on follow the reset's seed
            self._base, self._since = int(kwargs["seed"]), 0
        self._since += 1
        words = [self._seed, self._episode]
        if self._base is not None:
            words = [self._seed, self._base, self._since]
        self._rng = np.random.default_rng(words)
        return super().reset(**kwargs)

    def step(self, action: Any) -> tuple[np.ndarray, Any, bool, bool, dict[str, Any]]:
        self._t += 1
        return super().step(action)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        out = np.array(observation, copy=True)
        for fault in self._faults:
            if self._t < fault.step:
                continue
            for j in fault.features:
                if fault.mode == "dead":
                    out[j] = self._low[j]
                elif fault.mode == "saturated":
                    out[j] = self._high[j]
                elif fault.mode == "stuck":
                    out[j] = self._stuck.setdefault(j, float(observation[j]))
                else:  # random
                    out[j] = self._rng.uniform(self._low[j], self._high[j])
        return out
