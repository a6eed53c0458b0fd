"""Pendulum-v1 as a compiled function over a batch, bit for bit Gymnasium's `PendulumEnv`
(g = 10, m = l = 1, dt = 0.05, max speed 8, max torque 2; `TimeLimit` of 200 steps).

`_pendulum` advances row i of a float64 (N, 2) state [θ, θ̇] under a float32 torque with
`PendulumEnv.step`'s operations in its order and its dtypes under numpy 2's promotion rules
(NEP 50): the torque `u = np.clip(u, -2, 2)[0]` is a float32 scalar, so `0.001 * (u**2)` and
`3.0 / (m * l**2) * u` are float32 products (Python's floats taken as float32), promoted to
float64 only where they meet float64 terms; `x**2` of a numpy scalar is libm's `pow` (`powf`
for float32), which differs from x·x in the last bit now and then, so the exponent comes in as
a run-time argument and LLVM keeps the call; `angle_normalize`'s `%` is Python's float modulo
(numba's is too); `np.clip` lets a NaN through, as `_clip` does. The reward is `-costs`
(float64), the observation float32 [cos θ, sin θ, θ̇]; the env never terminates. Tested step for
step against `gymnasium.make("Pendulum-v1")`, tests/app/tasks/test_task_fast.py.

`step_live` steps a batch of such envs in one compiled call for `app.tasks.lives.BatchEnv`'s
"twin" mode, as `app.tasks.dynamics.step_live` does for the discrete tasks.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

Floats = npt.NDArray[np.float64]

_MAX_SPEED = 8.0
_MAX_TORQUE = np.float32(2.0)
_DT = 0.05
_G_TERM = 3 * 10.0 / (2 * 1.0)  # 3 * g / (2 * l), Python floats as the env computes it
_U_TERM = np.float32(3.0 / (1.0 * 1.0**2))  # 3.0 / (m * l**2), taken as float32 by `* u`
_U_COST = np.float32(0.001)  # taken as float32 by `* (u**2)`
_TWO_PI = 2 * math.pi


@njit(cache=True, inline="always")
def _pendulum(
    state: Floats, i: int, torque: np.float32, two: float, two32: np.float32
) -> float:  # pragma: no cover - compiled
    """PendulumEnv.step on row i under `torque`: the reward (`-costs`)."""
    th, thdot = state[i, 0], state[i, 1]
    u = torque
    if u < -_MAX_TORQUE:  # np.clip: NaN stays NaN
        u = -_MAX_TORQUE
    elif u > _MAX_TORQUE:
        u = _MAX_TORQUE
    normalized = ((th + math.pi) % _TWO_PI) - math.pi
    u_cost = _U_COST * (u**two32)  # float32
    costs = normalized**two + 0.1 * thdot**two + np.float64(u_cost)
    u_acc = np.float64(_U_TERM * u)  # float32, then promoted
    newthdot = thdot + (_G_TERM * math.sin(th) + u_acc) * _DT
    if newthdot < -_MAX_SPEED:
        newthdot = -_MAX_SPEED
    elif newthdot > _MAX_SPEED:
        newthdot = _MAX_SPEED
    state[i, 0] = th + newthdot * _DT
    state[i, 1] = newthdot
    return -costs


@njit(cache=True, inline="always")
def _observe(
    state: Floats, i: int, obs: npt.NDArray[np.float32]
) -> None:  # pragma: no cover - compiled
    """Row i's observation, float32 [cos θ, sin θ, θ̇], into obs[i]."""
    obs[i, 0] = np.float32(math.cos(state[i, 0]))
    obs[i, 1] = np.float32(math.sin(state[i, 0]))
    obs[i, 2] = np.float32(state[i, 1])


@njit(cache=True)
def _step_live(
    horizon: int,
    state: Floats,
    actions: npt.NDArray[np.float32],
    obs: npt.NDArray[np.float32],
    reward: Floats,
    terminated: npt.NDArray[np.bool_],
    done: npt.NDArray[np.bool_],
    elapsed: npt.NDArray[np.int64],
    two: float,
    two32: np.float32,
) -> None:  # pragma: no cover - compiled
    for i in range(state.shape[0]):
        terminated[i] = False
        if elapsed[i] < 0:  # its episode has ended: not stepped
            reward[i] = 0.0
            done[i] = True
            continue
        reward[i] = _pendulum(state, i, actions[i, 0], two, two32)
        _observe(state, i, obs)
        elapsed[i] += 1
        done[i] = elapsed[i] >= horizon
        if done[i]:
            elapsed[i] = -1


def step_live(
    horizon: int,
    state: Floats,
    actions: npt.NDArray[np.float32],
    obs: npt.NDArray[np.float32],
    reward: Floats,
    terminated: npt.NDArray[np.bool_],
    done: npt.NDArray[np.bool_],
    elapsed: npt.NDArray[np.int64],
) -> None:
    """`app.tasks.dynamics.step_live` for Pendulum: `actions` (N, 1) float32 torques."""
    _step_live(
        horizon, state, actions, obs, reward, terminated, done, elapsed, 2.0, np.float32(2.0)
    )


def start_states(rngs: list[np.random.Generator]) -> tuple[Floats, npt.NDArray[np.float32]]:
    """`PendulumEnv.reset()`'s start state of each generator (its `np_random`; the draws
    advance it): (N, 2) float64 states and (N, 3) float32 first observations."""
    high = np.array([np.pi, 1.0])
    state = np.array([r.uniform(low=-high, high=high) for r in rngs], np.float64).reshape(-1, 2)
    obs = np.array([[np.cos(th), np.sin(th), thdot] for th, thdot in state], np.float32).reshape(
        -1, 3
    )
    return state, obs
