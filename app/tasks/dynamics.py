"""CartPole-v1, MountainCar-v0, Acrobot-v1 and Pendulum-v1 as compiled functions over a batch,
bit for bit Gymnasium's own environments (issues #34, #45).

Each discrete task is a numba function that advances row i of a float64 state array by one step
(`_cartpole`, `_mountain_car`, `_acrobot`: returns (reward, terminated)) and one that writes
row i's float32 observation, with Gymnasium's operations in Gymnasium's order (the same
float64 arithmetic, libm's `cos`/`sin`, which numpy's give bit for bit on this machine: tested
step for step against `gymnasium.make(id)` over whole episodes, tests/app/tasks/test_task_fast.py).
Pendulum-v1, whose action is a float32 torque (a Box), has its own module (`app.tasks.pendulum`).
`step_batch` steps a whole (N, d) batch of a discrete task; `starts` draws the start states of
seeds as the single env's `reset(seed=s)` does (`np.random.default_rng(s)`, Gymnasium's
`np_random`), first observations computed by numpy as Gymnasium computes them (Acrobot's first
one takes float32 `cos`/`sin` of its float32 start state). An episode also ends at its time
limit, `horizon` steps (Gymnasium's `TimeLimit`: truncated).

`FAST_TASKS` is the registry `app.tasks.lives` reads. GNP's lives on a discrete task there run
in `lives`: every individual's whole episode in one compiled call with GNP's own kernel
(`gnp.kernel.walk_kernel`), as `app.brains.gnp_fused` does for the robot ("fast" batch env).
Every other family's lives, and GNP's on Pendulum, step a batch env of twins ("twin"):
`step_live` steps every env of the batch in one compiled call, counting each one's steps to its
time limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypeAlias

import numpy as np
import numpy.typing as npt
from numba import njit

import gnp
from app.tasks import pendulum
from app.tasks.spaces import TaskAdapter
from gnp import config as gnp_config
from gnp import kernel, methods, rng
from gnp.config import SENSOR_MAX
from gnp.engine import check_population, kernel_arguments, method_code
from gnp.kernel import (
    LAYOUT_BRANCHES,
    Floats,
    Layout,
    Records,
    Streams,
    Traces,
    Walks,
    read_observed,
    records_part,
    walk_kernel,
)
from gnp.methods import BRANCH_SELECTION as _BS
from gnp.methods import CREDIT as _CS
from gnp.methods import SKIP_EARNS as _SKIP_EARNS
from sim.kernel_cache import drop_stale_cache, source_fingerprint

CARTPOLE, MOUNTAIN_CAR, ACROBOT, PENDULUM = 0, 1, 2, 3

Observations: TypeAlias = npt.NDArray[np.float32]
"""A batch's observations, (N, obs_dim) float32 as the envs return them."""

# CartPoleEnv's constants, as its __init__ computes them.
_CP_GRAVITY = 9.8
_CP_MASSPOLE = 0.1
_CP_TOTAL_MASS = _CP_MASSPOLE + 1.0
_CP_LENGTH = 0.5
_CP_POLEMASS_LENGTH = _CP_MASSPOLE * _CP_LENGTH
_CP_FORCE_MAG = 10.0
_CP_TAU = 0.02
_CP_THETA_LIMIT = 12 * 2 * math.pi / 360
_CP_X_LIMIT = 2.4


@njit(cache=True, inline="always")
def _cartpole(
    state: Floats, i: int, action: int
) -> tuple[float, bool]:  # pragma: no cover - compiled
    """CartPoleEnv.step (euler) on row i: (reward, terminated)."""
    x, x_dot, theta, theta_dot = state[i, 0], state[i, 1], state[i, 2], state[i, 3]
    force = _CP_FORCE_MAG if action == 1 else -_CP_FORCE_MAG
    costheta = math.cos(theta)
    sintheta = math.sin(theta)
    temp = (force + _CP_POLEMASS_LENGTH * (theta_dot * theta_dot) * sintheta) / _CP_TOTAL_MASS
    thetaacc = (_CP_GRAVITY * sintheta - costheta * temp) / (
        _CP_LENGTH * (4.0 / 3.0 - _CP_MASSPOLE * (costheta * costheta) / _CP_TOTAL_MASS)
    )
    xacc = temp - _CP_POLEMASS_LENGTH * thetaacc * costheta / _CP_TOTAL_MASS
    x = x + _CP_TAU * x_dot
    x_dot = x_dot + _CP_TAU * xacc
    theta = theta + _CP_TAU * theta_dot
    theta_dot = theta_dot + _CP_TAU * thetaacc
    state[i, 0], state[i, 1], state[i, 2], state[i, 3] = x, x_dot, theta, theta_dot
    terminated = (
        x < -_CP_X_LIMIT or x > _CP_X_LIMIT or theta < -_CP_THETA_LIMIT or theta > _CP_THETA_LIMIT
    )
    return 1.0, terminated


_MC_MIN, _MC_MAX, _MC_SPEED, _MC_GOAL = -1.2, 0.6, 0.07, 0.5
_MC_FORCE, _MC_GRAVITY = 0.001, 0.0025


@njit(cache=True, inline="always")
def _mountain_car(
    state: Floats, i: int, action: int
) -> tuple[float, bool]:  # pragma: no cover - compiled
    """MountainCarEnv.step (goal velocity 0) on row i: (reward, terminated)."""
    position, velocity = state[i, 0], state[i, 1]
    velocity += (action - 1) * _MC_FORCE + math.cos(3 * position) * (-_MC_GRAVITY)
    velocity = min(max(velocity, -_MC_SPEED), _MC_SPEED)
    position += velocity
    position = min(max(position, _MC_MIN), _MC_MAX)
    if position == _MC_MIN and velocity < 0:
        velocity = 0.0
    state[i, 0], state[i, 1] = position, velocity
    return -1.0, position >= _MC_GOAL and velocity >= 0.0


_AC_MAX_VEL_1, _AC_MAX_VEL_2 = 4 * math.pi, 9 * math.pi


@njit(cache=True, inline="always")
def _acrobot_dsdt(
    t1: float, t2: float, dt1: float, dt2: float, a: float, two: float
) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    """AcrobotEnv._dsdt ("book"): (dθ1, dθ2, ddθ1, ddθ2), its operations in its order.

    Its `x**2` of a numpy float64 is libm's `pow(x, 2.0)`, which differs from x·x in the last
    bit for about one x in a thousand; LLVM rewrites a constant `pow(x, 2.0)` as x·x, so the
    exponent comes in as a run-time argument (`two` = 2.0) and the call stays libm's."""
    m1 = m2 = l1 = 1.0
    lc1 = lc2 = 0.5
    i1 = i2 = 1.0
    g = 9.8
    pi = math.pi
    d1 = m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * math.cos(t2)) + i1 + i2
    d2 = m2 * (lc2**2 + l1 * lc2 * math.cos(t2)) + i2
    phi2 = m2 * lc2 * g * math.cos(t1 + t2 - pi / 2.0)
    phi1 = (
        -m2 * l1 * lc2 * dt2**two * math.sin(t2)
        - 2 * m2 * l1 * lc2 * dt2 * dt1 * math.sin(t2)
        + (m1 * lc1 + m2 * l1) * g * math.cos(t1 - pi / 2)
        + phi2
    )
    ddt2 = (a + d2 / d1 * phi1 - m2 * l1 * lc2 * dt1**two * math.sin(t2) - phi2) / (
        m2 * lc2**2 + i2 - d2**two / d1
    )
    ddt1 = -(d2 * ddt2 + phi1) / d1
    return dt1, dt2, ddt1, ddt2


@njit(cache=True, inline="always")
def _wrap(x: float) -> float:  # pragma: no cover - compiled
    diff = math.pi - (-math.pi)
    while x > math.pi:
        x = x - diff
    while x < -math.pi:
        x = x + diff
    return x


@njit(cache=True, inline="always")
def _acrobot(
    state: Floats, i: int, action: int, two: float
) -> tuple[float, bool]:  # pragma: no cover - compiled
    """AcrobotEnv.step (no torque noise) on row i: one RK4 step of 0.2 s, (reward, terminated)."""
    a = -1.0 if action == 0 else (0.0 if action == 1 else 1.0)
    y0, y1, y2, y3 = state[i, 0], state[i, 1], state[i, 2], state[i, 3]
    dt, dt2 = 0.2, 0.1
    k10, k11, k12, k13 = _acrobot_dsdt(y0, y1, y2, y3, a, two)
    k20, k21, k22, k23 = _acrobot_dsdt(
        y0 + dt2 * k10, y1 + dt2 * k11, y2 + dt2 * k12, y3 + dt2 * k13, a + dt2 * 0.0, two
    )
    k30, k31, k32, k33 = _acrobot_dsdt(
        y0 + dt2 * k20, y1 + dt2 * k21, y2 + dt2 * k22, y3 + dt2 * k23, a + dt2 * 0.0, two
    )
    k40, k41, k42, k43 = _acrobot_dsdt(
        y0 + dt * k30, y1 + dt * k31, y2 + dt * k32, y3 + dt * k33, a + dt * 0.0, two
    )
    h = dt / 6.0
    n0 = y0 + h * (k10 + 2 * k20 + 2 * k30 + k40)
    n1 = y1 + h * (k11 + 2 * k21 + 2 * k31 + k41)
    n2 = y2 + h * (k12 + 2 * k22 + 2 * k32 + k42)
    n3 = y3 + h * (k13 + 2 * k23 + 2 * k33 + k43)
    n0 = _wrap(n0)
    n1 = _wrap(n1)
    n2 = min(max(n2, -_AC_MAX_VEL_1), _AC_MAX_VEL_1)
    n3 = min(max(n3, -_AC_MAX_VEL_2), _AC_MAX_VEL_2)
    state[i, 0], state[i, 1], state[i, 2], state[i, 3] = n0, n1, n2, n3
    terminated = -math.cos(n0) - math.cos(n1 + n0) > 1.0
    return (0.0 if terminated else -1.0), terminated


@njit(cache=True, inline="always")
def _step(
    task: int, state: Floats, i: int, action: int, two: float
) -> tuple[float, bool]:  # pragma: no cover - compiled
    if task == CARTPOLE:
        return _cartpole(state, i, action)
    if task == MOUNTAIN_CAR:
        return _mountain_car(state, i, action)
    return _acrobot(state, i, action, two)


@njit(cache=True, inline="always")
def _observe(
    task: int, state: Floats, i: int, obs: Observations, j: int
) -> None:  # pragma: no cover - compiled
    """Row i's observation (float32, as the env returns it) into obs[j]."""
    if task == ACROBOT:
        obs[j, 0] = np.float32(math.cos(state[i, 0]))
        obs[j, 1] = np.float32(math.sin(state[i, 0]))
        obs[j, 2] = np.float32(math.cos(state[i, 1]))
        obs[j, 3] = np.float32(math.sin(state[i, 1]))
        obs[j, 4] = np.float32(state[i, 2])
        obs[j, 5] = np.float32(state[i, 3])
    else:
        for k in range(state.shape[1]):
            obs[j, k] = np.float32(state[i, k])


@njit(cache=True)
def _step_batch(
    task: int,
    state: Floats,
    actions: npt.NDArray[np.int64],
    obs: Observations,
    reward: Floats,
    terminated: npt.NDArray[np.bool_],
    two: float,
) -> None:  # pragma: no cover - compiled
    for i in range(state.shape[0]):
        reward[i], terminated[i] = _step(task, state, i, actions[i], two)
        _observe(task, state, i, obs, i)


@njit(cache=True)
def _step_live(
    task: int,
    horizon: int,
    state: Floats,
    actions: npt.NDArray[np.int64],
    obs: Observations,
    reward: Floats,
    terminated: npt.NDArray[np.bool_],
    done: npt.NDArray[np.bool_],
    elapsed: npt.NDArray[np.int64],
    two: float,
) -> None:  # pragma: no cover - compiled
    for i in range(state.shape[0]):
        if elapsed[i] < 0:  # its episode has ended: not stepped
            reward[i], terminated[i], done[i] = 0.0, False, True
            continue
        reward[i], terminated[i] = _step(task, state, i, actions[i], two)
        _observe(task, state, i, obs, i)
        elapsed[i] += 1
        done[i] = terminated[i] or elapsed[i] >= horizon
        if done[i]:
            elapsed[i] = -1


@dataclass(frozen=True)
class FastTask:
    """A task the lab steps itself: its kernel code, state and observation widths, its
    episode's time limit (Gymnasium's `max_episode_steps`), and whether its action is a Box
    (float32 rows; `app.tasks.pendulum`) rather than a Discrete one."""

    code: int
    state_dim: int
    obs_dim: int
    horizon: int
    box: bool = False


#: Task id → the lab's compiled twin of its Gymnasium env: GNP's fused lives step the discrete
#: ones ("fast"), every other family's lives and GNP's on Pendulum a batch of twins ("twin").
FAST_TASKS: dict[str, FastTask] = {
    "CartPole-v0": FastTask(CARTPOLE, 4, 4, 200),
    "CartPole-v1": FastTask(CARTPOLE, 4, 4, 500),
    "MountainCar-v0": FastTask(MOUNTAIN_CAR, 2, 2, 200),
    "Acrobot-v1": FastTask(ACROBOT, 4, 6, 500),
    "Pendulum-v1": FastTask(PENDULUM, 2, 3, 200, box=True),
}


def starts(task: FastTask, seeds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The start states (N, state_dim) float64 and first observations (N, obs_dim) float32 of
    the single env's `reset(seed=s)` for each s of `seeds`."""
    return start_states(task, [np.random.default_rng(int(s)) for s in seeds])


def start_states(task: FastTask, rngs: list[np.random.Generator]) -> tuple[np.ndarray, np.ndarray]:
    """`starts`, each start drawn from its env's own generator (`np_random`), as its
    `reset()` draws it: the draws advance the generators."""
    n = len(rngs)
    if task.code == PENDULUM:
        return pendulum.start_states(rngs)
    if task.code == CARTPOLE:
        state = np.array([r.uniform(-0.05, 0.05, size=(4,)) for r in rngs]).reshape(n, 4)
        return state, state.astype(np.float32)
    if task.code == MOUNTAIN_CAR:
        state = np.zeros((n, 2))
        state[:, 0] = [r.uniform(low=-0.6, high=-0.4) for r in rngs]
        return state, state.astype(np.float32)
    single = np.array([r.uniform(-0.1, 0.1, size=(4,)) for r in rngs], np.float64)
    s32 = single.reshape(n, 4).astype(np.float32)  # AcrobotEnv keeps its start as float32
    obs = np.stack(
        [np.cos(s32[:, 0]), np.sin(s32[:, 0]), np.cos(s32[:, 1]), np.sin(s32[:, 1]),
         s32[:, 2], s32[:, 3]], axis=1,
    ).astype(np.float32)  # fmt: skip
    return s32.astype(np.float64), obs


def step_batch(
    task: FastTask, state: np.ndarray, actions: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step of every row of `state` ((N, state_dim) float64, updated in place) under
    `actions` (N,): (observations (N, obs_dim) float32, rewards (N,), terminated (N,)). A
    discrete task's (Pendulum's batch steps through `step_live`)."""
    if task.box:
        raise ValueError(f"task code {task.code} takes Box actions: step it with step_live")
    n = state.shape[0]
    obs = np.empty((n, task.obs_dim), np.float32)
    reward = np.empty(n)
    terminated = np.empty(n, np.bool_)
    _step_batch(task.code, state, np.asarray(actions, np.int64), obs, reward, terminated, 2.0)
    return obs, reward, terminated


def step_live(
    task: FastTask,
    state: Floats,
    actions: np.ndarray,
    obs: Observations,
    reward: Floats,
    terminated: npt.NDArray[np.bool_],
    done: npt.NDArray[np.bool_],
    elapsed: npt.NDArray[np.int64],
) -> None:
    """One step of every env of a batch still in its episode, in one compiled call: row i of
    `state` ((N, state_dim) float64) under `actions[i]` ((N,) int64, or (N, 1) float32 for a Box
    task), its observation into `obs[i]`, its reward, `terminated` and `done` (terminated, or
    truncated at the `horizon`-th step as Gymnasium's `TimeLimit` truncates) into theirs, and
    `elapsed[i]` (its steps since its reset) counted on. An env whose episode has ended
    (`elapsed[i]` set to -1 when it ended) is not stepped: it keeps its observation and gives
    reward 0, not terminated, done (where Gymnasium's vector env would start a new episode,
    which the lives ignore)."""
    if task.box:
        pendulum.step_live(task.horizon, state, actions, obs, reward, terminated, done, elapsed)
    else:
        _step_live(
            task.code, task.horizon, state, actions, obs, reward, terminated, done, elapsed, 2.0
        )


@njit(cache=True)
def step_row(
    task: int, state: Floats, action: int, obs: Observations
) -> tuple[float, bool]:  # pragma: no cover - compiled
    """One step of row 0 of `state` under `action`, its observation into `obs[0]`: (reward,
    terminated). One env stepped from Python (`app.tasks.twin_env`)."""
    reward, terminated = _step(task, state, 0, action, 2.0)
    _observe(task, state, 0, obs, 0)
    return reward, terminated


_NO_TRACE = np.empty((5, 0, 0), np.int32)
_NO_COUNT = np.empty(0, np.int32)


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]
def _act(
    method: int, fuzzy: bool, gamma: float, n_nodes: int, n_judgment: int, n_sub: int,
    n_conn: int, records: Records, layout: Layout, walk: Walks, wheels: Floats, rng: Streams,
    obs: Floats, reward: Floats, rates: Floats, learn: bool, visits: Traces, count: Traces,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """`gnp.kernel.step_kernel`, compiled here (without reference counting, as it is)."""
    walk_kernel(
        method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, records, layout, walk, wheels,
        rng, obs, reward, rates, learn, visits, count, read_observed, obs,
    )  # fmt: skip


@njit(cache=True)
def _end_episode(
    method: int, gamma: float, n_nodes: int, n_conn: int, layout: Layout,
    words32: npt.NDArray[np.float32], walk: Walks, c: int, reward: float, lr: float,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """`gnp.end_episode` of controller c (its walk row `walk[0]`), in its arithmetic."""
    pn = walk[0, 1]
    if pn < 0:
        return
    pp, pb, pu, pc = walk[0, 2], walk[0, 3], walk[0, 4], walk[0, 5]
    r32 = layout[0] // 4
    ss, bs, cs_ = layout[1], layout[2], layout[3]
    r = 0.0 if pc == 1 and not method & _SKIP_EARNS else reward
    last_q = (c * n_nodes + pn) * r32
    q = np.float64(words32[last_q + ss + pp])
    words32[last_q + ss + pp] = q + lr * (r - q)
    if method & _CS:
        q = np.float64(words32[last_q + cs_ + 2 * pp + pc])
        words32[last_q + cs_ + 2 * pp + pc] = q + lr * (r - q)
    if method & _BS and walk[0, 6] >= 0:
        bn, bp, bb, bu = walk[0, 6], walk[0, 7], walk[0, 8], walk[0, 9]
        n_way = layout[LAYOUT_BRANCHES]
        last = np.float64(words32[last_q + bs + (n_way * pp + pb) * n_conn + pu])
        before = (c * n_nodes + bn) * r32 + bs + (n_way * bp + bb) * n_conn + bu
        q = np.float64(words32[before])
        words32[before] = q + lr * (r + gamma * last - q)
    walk[0, 1:] = -1


@njit(cache=True)
def _lives(
    task: int, horizon: int, state: Floats, obs: Observations, low: Floats, scale: Floats,
    n_actions: int, action_start: int, method: int, fuzzy: bool, gamma: float, n_nodes: int,
    n_judgment: int, n_sub: int, n_conn: int, records: Records, layout: Layout, walk: Walks,
    wheels: Floats, rng: Streams, rates: Floats, learn: bool, max_steps: int, returns: Floats,
    lengths: npt.NDArray[np.int64], visits: Traces, count: Traces, two: float,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """Every individual's episode, one after the other (they share nothing, so the order
    changes no bit), each step as `app.tasks.lives.live` takes it: read, `step_kernel`, act,
    the env's step, and the terminal Sarsa update when the task terminates."""
    words32 = records.view(np.float32)
    n, d = obs.shape
    readings = np.empty((1, d))
    reward = np.zeros(1)
    k_out = wheels.shape[1]
    for c in range(n):
        part = records_part(records, n_nodes, layout, c, c + 1)
        part_walk, part_wheels, part_rng = walk[c : c + 1], wheels[c : c + 1], rng[c : c + 1]
        reward[0] = 0.0
        for t in range(max_steps):
            for j in range(d):
                x = (np.float64(obs[c, j]) - low[j]) * scale[j]
                readings[0, j] = min(max(x, 0.0), 1023.0)
            _act(
                method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, part, layout,
                part_walk, part_wheels, part_rng, readings, reward, rates, learn, visits, count,
            )  # fmt: skip
            v = min(max(part_wheels[0, k_out - 1], -10.0), 10.0)
            share = (v + 10.0) / 20.0
            action = min(math.floor(share * n_actions), n_actions - 1) + action_start
            r, terminated = _step(task, state, c, action, two)
            _observe(task, state, c, obs, c)
            returns[c] += r
            lengths[c] += 1
            reward[0] = r
            if terminated:
                if learn:
                    _end_episode(
                        method, gamma, n_nodes, n_conn, layout, words32, part_walk, c, r,
                        rates[0, 1],
                    )  # fmt: skip
                break
            if t + 1 >= horizon:
                break


def lives(
    task: FastTask,
    cfg: gnp.GnpConfig,
    adapter: TaskAdapter,
    pop: gnp.Population,
    state: gnp.EngineState,
    seeds: np.ndarray,
    epsilon: float,
    alpha: float,
    max_steps: int,
    learn: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """One episode of each of `pop`'s individuals (learning in place) with `state`'s
    controllers, the episode of individual i from `seeds[i]`: (returns, lengths)."""
    n = pop.size
    env_state, obs = starts(task, seeds)
    returns = np.zeros(n)
    lengths = np.zeros(n, np.int64)
    check_population(cfg, pop, state)
    for name, value in (("epsilon", epsilon), ("alpha", alpha)):
        if not 0.0 <= value <= 1.0:
            raise gnp.GnpError(f"{name} must lie in [0, 1], got {value}")
    rates = np.array([[epsilon, alpha]], np.float64)  # one (ε, α) for all, as `gnp.step`'s
    low = np.ascontiguousarray(adapter.obs_low, np.float64)
    scale = SENSOR_MAX / (adapter.obs_high - adapter.obs_low)
    brain = kernel_arguments(method_code(cfg), cfg, pop, state)
    _lives(
        task.code, task.horizon, env_state, obs, low, np.ascontiguousarray(scale, np.float64),
        adapter.n_actions, adapter.action_start, *brain, rates, learn, max_steps, returns,
        lengths, _NO_TRACE, _NO_COUNT, 2.0,
    )  # fmt: skip
    return returns, lengths


#: What this module's cached kernels were compiled against: gnp's walk, which `_lives` inlines,
#: and the constants and flags numba freezes into it (sim.kernel_cache; without it a changed
#: `gnp/kernel.py` left this module running the old walk from its cache).
COMPILED_AGAINST = source_fingerprint(kernel, methods, rng, gnp_config)


@njit(cache=True)
def _frozen_sources() -> np.ndarray:  # pragma: no cover - compiled
    """``COMPILED_AGAINST`` as numba froze it into this module's cache."""
    return COMPILED_AGAINST.copy()


drop_stale_cache(globals(), _frozen_sources, COMPILED_AGAINST)
