"""A Gymnasium task as a brain sees it (GNP's, a net's, any family's): observation features scaled
to the readings' range 0..1023 (GNP's judgment range, the robot's IR), commands (−10..10, GNP's
processing-node outputs, the robot's wheel range) read as actions.

Observation feature j in [low_j, high_j] maps linearly to 0..1023 and is clipped there. The
bounds are the observation space's, or those given in the settings, or, for a feature the space
leaves unbounded, a documented default of a known task (`KNOWN_BOUNDS`); an unbounded feature
with none of these is refused. Actions (docs/decisions.md, "GNP on Gymnasium tasks"):

- `Box(d)`: d outputs; output j's value v in −10..10 maps linearly to [low_j, high_j].
- `Discrete(n)`: one output; its value v in −10..10 falls into one of n equal bins of
  [−10, 10] (the top edge joins the last bin), bin k is action `start + k`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from gymnasium import spaces

from app.tasks.common import TaskError
from gnp.config import SENSOR_MAX, SPEED_MAX

#: Bounds for the features a shipped task leaves unbounded: {task id: {feature: (low, high)}}.
#: CartPole's cart velocity and pole angular velocity: a balancing pole stays well inside
#: ±3 m/s and ±3.5 rad/s (a policy that leaves them reads the bound, clipped).
KNOWN_BOUNDS: dict[str, dict[int, tuple[float, float]]] = {
    "CartPole-v0": {1: (-3.0, 3.0), 3: (-3.5, 3.5)},
    "CartPole-v1": {1: (-3.0, 3.0), 3: (-3.5, 3.5)},
}

#: The most inputs or outputs a genome can name (its function genes are int8).
MAX_FEATURES = 127

ActionKind = Literal["discrete", "box"]


@dataclass(frozen=True)
class TaskAdapter:
    """How a GNP brain reads one task's observations and emits its actions.

    Attributes:
        task: the Gymnasium id.
        obs_low, obs_high: (n_inputs,) finite bounds of each observation feature.
        kind: "discrete" or "box".
        n_actions: n of Discrete(n) (0 for Box).
        action_start: `start` of Discrete(n) (0 for Box).
        act_low, act_high: (n_outputs,) finite bounds of a Box action (empty for Discrete).
        action_dtype: dtype of the action space.
    """

    task: str
    obs_low: np.ndarray
    obs_high: np.ndarray
    kind: ActionKind
    n_actions: int
    action_start: int
    act_low: np.ndarray
    act_high: np.ndarray
    action_dtype: np.dtype

    @property
    def n_inputs(self) -> int:
        """Observation features: the inputs judgment nodes judge."""
        return int(self.obs_low.size)

    @property
    def n_outputs(self) -> int:
        """Outputs processing nodes set: 1 for Discrete, d for Box(d)."""
        return 1 if self.kind == "discrete" else int(self.act_low.size)

    def observe(self, obs: np.ndarray) -> np.ndarray:
        """(N, n_inputs) observations → (N, n_inputs) float64 readings in 0..1023."""
        x = np.asarray(obs, dtype=np.float64).reshape(-1, self.n_inputs)
        scaled = (x - self.obs_low) * (SENSOR_MAX / (self.obs_high - self.obs_low))
        return np.clip(scaled, 0.0, float(SENSOR_MAX))

    def outputs(self, commands: np.ndarray) -> np.ndarray:
        """`gnp.step`'s commands (output j in column k − 1 − j) as (N, k), output j in column j."""
        return np.asarray(commands, dtype=np.float64)[:, ::-1]

    def act(self, commands: np.ndarray) -> np.ndarray:
        """`gnp.step`'s (N, n_outputs) commands in −10..10 → N actions of the action space."""
        v = np.clip(self.outputs(commands), -SPEED_MAX, SPEED_MAX)
        share = (v + SPEED_MAX) / (2 * SPEED_MAX)  # 0..1
        if self.kind == "discrete":
            k = np.minimum(np.floor(share[:, 0] * self.n_actions), self.n_actions - 1)
            return (k.astype(np.int64) + self.action_start).astype(self.action_dtype)
        action = self.act_low + share * (self.act_high - self.act_low)
        return action.astype(self.action_dtype)


def _bounds(
    name: str,
    task: str,
    space_low: np.ndarray,
    space_high: np.ndarray,
    low: Sequence[float | None] | None,
    high: Sequence[float | None] | None,
    defaults: dict[int, tuple[float, float]],
    setting: str,
) -> tuple[np.ndarray, np.ndarray]:
    n = space_low.size
    lo = space_low.astype(np.float64).copy()
    hi = space_high.astype(np.float64).copy()
    for j, (dlo, dhi) in defaults.items():
        if j < n:
            lo[j] = dlo if not np.isfinite(lo[j]) else lo[j]
            hi[j] = dhi if not np.isfinite(hi[j]) else hi[j]
    for given, target, side in ((low, lo, "low"), (high, hi, "high")):
        if given is None:
            continue
        if len(given) != n:
            raise TaskError(
                f"{task}: {setting}_{side} gives {len(given)} bounds, the {name} has {n}"
            )
        for j, value in enumerate(given):
            if value is not None:
                target[j] = float(value)
    for j in range(n):
        if not (math.isfinite(lo[j]) and math.isfinite(hi[j])):
            raise TaskError(
                f"{task}: {name} {j} is unbounded ({lo[j]}, {hi[j]}); give its bounds with "
                f"task.{setting}_low / task.{setting}_high"
            )
        if not lo[j] < hi[j]:
            raise TaskError(f"{task}: {name} {j} needs low < high, got [{lo[j]}, {hi[j]}]")
    return lo, hi


def task_adapter(
    task: str,
    observation_space: spaces.Space[Any],
    action_space: spaces.Space[Any],
    obs_low: Sequence[float | None] | None = None,
    obs_high: Sequence[float | None] | None = None,
    act_low: Sequence[float | None] | None = None,
    act_high: Sequence[float | None] | None = None,
) -> TaskAdapter:
    """The adapter of a task with these (single-env) spaces; `None` bounds come from the space.

    Raises:
        TaskError: a space GNP cannot judge (not a 1-D Box) or emit (not Discrete or a 1-D
            Box), too many features, or a feature left unbounded.
    """
    obs = observation_space
    if not isinstance(obs, spaces.Box) or len(obs.shape) != 1:
        raise TaskError(
            f"{task}: GNP judges a flat Box of features; the observation space is {obs}"
        )
    if not 1 <= obs.shape[0] <= MAX_FEATURES:
        raise TaskError(f"{task}: {obs.shape[0]} observation features; GNP judges 1..127")
    lo, hi = _bounds(
        "observation feature",
        task,
        np.asarray(obs.low),
        np.asarray(obs.high),
        obs_low,
        obs_high,
        KNOWN_BOUNDS.get(task, {}),
        "obs",
    )
    act = action_space
    empty = np.zeros(0)
    if isinstance(act, spaces.Discrete):
        if act_low is not None or act_high is not None:
            raise TaskError(f"{task}: action bounds apply to Box actions; the action is {act}")
        return TaskAdapter(
            task, lo, hi, "discrete", int(act.n), int(act.start), empty, empty, act.dtype
        )
    if isinstance(act, spaces.Box) and len(act.shape) == 1 and 1 <= act.shape[0] <= MAX_FEATURES:
        alo, ahi = _bounds(
            "action", task, np.asarray(act.low), np.asarray(act.high), act_low, act_high, {}, "act"
        )
        return TaskAdapter(task, lo, hi, "box", 0, 0, alo, ahi, act.dtype)
    raise TaskError(
        f"{task}: GNP emits a Discrete action or a flat Box of 1..127; the action space is {act}"
    )
