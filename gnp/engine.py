"""The batched node-transition engine with Sarsa learning (RL, BS, CS; crisp or fuzzy).

One call of `step` advances N controllers by one world step. A controller visits nodes from its
current node until it has spent the step's budget of 5 time units: a judgment node costs 1, a
processing node 5, a credit skip 1, the start node 0 (it runs once per episode). The cost is
charged before the node runs and the node that overshoots still runs, so a step ends right
after a processing node or after five unit-cost nodes in a row. The current node carries over.

Learning (docs/decisions.md has the equations). Every visit k chooses a sub node p_k by
ε-greedy on Q_SS, for CS also c_k ∈ {normal, credit} on Q_CS, runs, and for BS then chooses the
branch connection u_k on Q_BS of the branch it took. A visit's reward r_k is the world step's
reward if it was the step's last visit (and not a credit skip), else 0. When visit k+1 has
chosen its actions, visit k's Q_SS (and Q_CS) entries get the Sarsa update with r_k, and visit
k−1's Q_BS entry gets the update with r_k: a branch connection is judged by the reward of the
node it leads to (Eq. 3.2's r_{t+1}).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NoReturn, TypeAlias

import numpy as np
import numpy.typing as npt

from gnp.config import GnpConfig, GnpError
from gnp.kernel import record_layout, step_kernel
from gnp.methods import EMIT_FUNCTION, FIRST_STAGE_ONLY, SKIP_EARNS, TIE_FIRST, TRAITS
from gnp.population import Population, record_dtype
from gnp.rng import seed_states

VISIT_FIELDS = ("node", "sub", "branch", "u", "skipped")
"""What a `StepTrace` holds of each visit, in its fields' order (the store's and the kernel's)."""
_VISIT = len(VISIT_FIELDS)
WALK_WIDTH = 1 + 2 * _VISIT
"""Columns of `EngineState.walk`: the current node, then two visits as VISIT_FIELDS (a pending
visit's last column is its credit choice; the kernel reads the columns by number)."""
_PENDING = slice(1, 1 + _VISIT)
_PENDING_BS = slice(1 + _VISIT, WALK_WIDTH)


@dataclass(frozen=True)
class EngineState:
    """Mutable per-controller engine state, arrays with leading axis N.

    Attributes:
        walk: (N, WALK_WIDTH) int32, where each controller's walk through its graph stands: the
            current node (`node`), the last visit (`pending`) and the one before (`pending_bs`).
        wheels: (N, 2) wheel speeds as (left, right); each keeps its value until a processing
            node sets it.
        rng: (N,) uint64 splitmix64 state of each controller's own random stream.
    """

    walk: np.ndarray
    wheels: np.ndarray
    rng: np.ndarray

    @property
    def node(self) -> np.ndarray:
        """(N,) current node (0 = start node: a new episode)."""
        return self.walk[:, 0]

    @property
    def pending(self) -> np.ndarray:
        """(N, 5) the last visit (node, sub, branch, u, credit), awaiting its Q_SS/Q_CS
        update; node −1 when there is none."""
        return self.walk[:, _PENDING]

    @property
    def pending_bs(self) -> np.ndarray:
        """(N, 5) the visit before it, awaiting its Q_BS update (BS only)."""
        return self.walk[:, _PENDING_BS]

    @property
    def size(self) -> int:
        return int(self.walk.shape[0])


@dataclass(frozen=True)
class StepTrace:
    """What each controller did in one world step; (N, K) arrays padded with −1 after `count`.

    Attributes:
        node: nodes visited in order (the start node, 0, appears at an episode's first step).
        sub: sub node chosen.
        branch: judgment branch taken (A = 0, B = 1; 0 for processing and start nodes,
            −1 for a credit skip).
        u: branch connection chosen (0 unless BS; −1 for a credit skip).
        skipped: 1 if the visit was a credit skip (CS), else 0.
        count: (N,) number of visits in the step.
    """

    node: np.ndarray
    sub: np.ndarray
    branch: np.ndarray
    u: np.ndarray
    skipped: np.ndarray
    count: np.ndarray


TRACE_FIELDS = (*VISIT_FIELDS, "count")
"""The fields of a `StepTrace`, in the store's order."""
TRACE_DTYPE = np.int32


StepResult: TypeAlias = tuple[np.ndarray, StepTrace | None]
"""What `step` returns, always: `commands, trace = gnp.step(...)`, the (N, 2) wheel commands
and the StepTrace when `step` was asked for it, else None. A plain tuple, as Gymnasium's
`Env.step` returns: building a named tuple added ~13% to a one-controller call."""


def step_trace(visits: np.ndarray, count: np.ndarray) -> StepTrace:
    """The StepTrace of the kernel's `visits` (one row per VISIT_FIELDS; views, not copies)."""
    return StepTrace(**dict(zip(VISIT_FIELDS, visits, strict=True)), count=count)


def trace_shapes(cfg: GnpConfig) -> dict[str, tuple[int, ...]]:
    """Per-controller shape (without the leading N) of every `StepTrace` field."""
    visits = (cfg.max_visits_per_step,)
    return {field: () if field == "count" else visits for field in TRACE_FIELDS}


def init_state(cfg: GnpConfig, n: int, seeds: np.ndarray | list[int]) -> EngineState:
    """State for n controllers at the start node, wheels at 0, streams seeded from `seeds`."""
    states = seed_states(seeds)
    if states.shape != (n,):
        raise GnpError(f"init_state: need {n} seeds, got {states.shape[0]}")
    walk = np.full((n, WALK_WIDTH), -1, np.int32)
    walk[:, 0] = 0
    return EngineState(walk=walk, wheels=np.zeros((n, cfg.n_outputs), np.float64), rng=states)


def reset_episode(state: EngineState, seeds: np.ndarray | list[int] | None = None) -> None:
    """Put every controller back at the start node (new episode); Q tables are untouched.

    Wheels stop, pending transitions are dropped (no terminal update). With `seeds` the random
    streams restart from them, otherwise they continue.
    """
    if seeds is not None:
        states = seed_states(seeds)
        if states.shape != state.rng.shape:
            raise GnpError(f"reset_episode: need {state.size} seeds, got {states.shape[0]}")
        state.rng[:] = states
    state.walk[:] = -1
    state.walk[:, 0] = 0
    state.wheels[:] = 0.0


def end_episode(
    cfg: GnpConfig,
    pop: Population,
    state: EngineState,
    reward: np.ndarray,
    alpha: float | np.ndarray,
    which: np.ndarray | None = None,
) -> None:
    """The terminal Sarsa update of an episode that ended (the task says so) after the last
    world step, for the controllers `which` ((N,) bool; all by default).

    The last step's last visit is credited `reward` with no successor: Q_SS (and Q_CS) of its
    sub node (and credit choice) move by α·(r − Q), r = 0 if the visit was a credit skip (unless
    `cfg.skip_reward` is "step"); for
    BS the visit before it gets its pending Q_BS update, α·(r + γ·Q_BS(last) − Q_BS(before)),
    as the next step's first visit would have made it. The last visit's own branch connection
    leads nowhere and is left alone. The pending visits are then dropped (the controller is
    at the end of its episode: `reset_episode` starts the next). Q values are computed in double
    precision and stored in single, as the kernel does. `gnp.step` never calls this: the
    robot's lives have no terminal state.
    """
    n = state.walk.shape[0]
    check_population(cfg, pop, state)
    rew = _floats(reward, (n,), "reward")
    lr = _per_controller(alpha, n, "alpha")
    mask = np.ones(n, bool) if which is None else np.asarray(which, dtype=bool)
    if mask.shape != (n,):
        raise GnpError(f"which must have shape ({n},), got {mask.shape}")
    walk = state.walk
    rows = np.flatnonzero(mask & (walk[:, 1] >= 0))
    pn, pp, pb, pu, pc = (walk[rows, j] for j in range(1, 6))
    r = rew[rows] if cfg.skip_reward == "step" else np.where(pc == 1, 0.0, rew[rows])
    a = lr[rows]
    q = pop.q_ss[rows, pn, pp].astype(np.float64)
    pop.q_ss[rows, pn, pp] = q + a * (r - q)
    if cfg.traits.credit:
        q = pop.q_cs[rows, pn, pp, pc].astype(np.float64)
        pop.q_cs[rows, pn, pp, pc] = q + a * (r - q)
    if cfg.traits.branch_selection:
        has = walk[rows, 6] >= 0
        c = rows[has]
        bn, bp, bb, bu = (walk[c, j] for j in range(6, 10))
        last = pop.q_bs[c, pn[has], pp[has], pb[has], pu[has]].astype(np.float64)
        q = pop.q_bs[c, bn, bp, bb, bu].astype(np.float64)
        pop.q_bs[c, bn, bp, bb, bu] = q + a[has] * (r[has] + cfg.gamma * last - q)
    walk[rows, 1:] = -1


def _per_controller(value: float | np.ndarray, n: int, name: str) -> np.ndarray:
    if np.ndim(value) == 0:
        v = float(value)
        if not 0.0 <= v <= 1.0:
            raise GnpError(f"{name} must lie in [0, 1], got {v}")
        return np.full(n, v)
    arr = np.ascontiguousarray(value, dtype=np.float64)
    if arr.shape != (n,):
        raise GnpError(f"{name} must be a scalar or shape ({n},), got {arr.shape}")
    if n and not (arr.min() >= 0.0 and arr.max() <= 1.0):
        raise GnpError(f"{name} must lie in [0, 1]")
    return arr


# (ε, α) pairs already validated, as the (1, 2) arrays the kernel reads for every controller:
# building and checking them costs more than the whole kernel call for small batches.
_SHARED_RATES: dict[tuple[object, object], np.ndarray] = {}


def _rates(epsilon: float | np.ndarray, alpha: float | np.ndarray, n: int) -> np.ndarray:
    """(ε, α) per controller as an (n, 2) array, or (1, 2) when both are scalars."""
    try:
        return _SHARED_RATES[epsilon, alpha]
    except (KeyError, TypeError):  # TypeError: an array is no dictionary key
        pass
    if np.ndim(epsilon) == 0 and np.ndim(alpha) == 0:
        eps = _per_controller(epsilon, 1, "epsilon")
        alp = _per_controller(alpha, 1, "alpha")
        shared = np.stack([eps, alp], axis=1)
        if len(_SHARED_RATES) < 1024:
            _SHARED_RATES[epsilon, alpha] = shared
        return shared
    return np.stack(
        [_per_controller(epsilon, n, "epsilon"), _per_controller(alpha, n, "alpha")], axis=1
    )


def _raise_mismatch(cfg: GnpConfig, pop: Population, n: int) -> NoReturn:
    if pop.size != n:
        raise GnpError(f"population has {pop.size} individuals, state {n} controllers")
    expected = (cfg.n_nodes, cfg.n_sub, cfg.judgment_branches, cfg.n_conn_branches)
    raise GnpError(
        f"population does not match the config: q_bs has shape {pop.q_bs.shape[1:]} per "
        f"individual, expected {expected} (nodes, sub nodes, branches, connections)"
    )


_FLOAT64 = np.dtype(np.float64)


def _floats(value: np.ndarray, shape: tuple[int, ...], name: str) -> np.ndarray:
    """`value` as a C-contiguous float64 array of `shape` (itself when it already is one)."""
    if not (
        type(value) is np.ndarray
        and value.dtype is _FLOAT64
        and value.shape == shape
        and value.flags.c_contiguous
    ):
        value = np.ascontiguousarray(value, dtype=np.float64)
        if value.shape != shape:
            raise GnpError(f"{name} must have shape {shape}, got {value.shape}")
    return value


# Each method's `MethodTraits.kernel_code`, looked up as cheaply as the hot path needs.
_KERNEL_CODE = {method: traits.kernel_code for method, traits in TRAITS.items()}
# Stand-ins for the trace arrays when no trace is asked for (the kernel then writes none).
_NO_TRACE = np.empty((_VISIT, 0, 0), TRACE_DTYPE)
_NO_COUNT = np.empty(0, np.int32)


def step(
    cfg: GnpConfig,
    pop: Population,
    state: EngineState,
    observations: np.ndarray,
    reward: np.ndarray,
    epsilon: float | np.ndarray,
    alpha: float | np.ndarray,
    learn: bool = True,
    trace: bool = False,
    *,
    second_stage: bool = True,
) -> StepResult:
    """Advance N controllers by one world step.

    Args:
        cfg: the configuration `pop` was built for.
        pop: N individuals; their Q tables are updated in place when `learn`.
        state: engine state of the N controllers, updated in place.
        observations: (N, cfg.n_inputs) sensor readings the controllers see, 0..1023 (the
            robot's 8 by default).
        reward: (N,) reward of the previous world step, credited to that step's last visit.
        epsilon: ε of ε-greedy, scalar or (N,).
        alpha: learning rate α, scalar or (N,).
        learn: apply Sarsa updates.
        trace: also return what each controller did (else None in its place).
        second_stage: the method's second stage on (default). Off, a BS controller takes the
            greedy branch connection (argmax of Q_BS, ties to the lowest u, no exploration)
            and leaves Q_BS alone; a CS controller never takes its credit branch and leaves
            Q_CS alone; RL has none (no effect). Q_SS learns either way.

    Returns:
        (commands, trace): wheel commands (N, 2) as (left, right) in −10..10, and the
        StepTrace if `trace`, else None. With `cfg.n_outputs` = k the commands are (N, k),
        output j (processing function j) in column k − 1 − j: the robot's order, reversed.
    """
    n = state.walk.shape[0]
    check_population(cfg, pop, state)
    obs = _floats(observations, (n, cfg.n_inputs), "observations")
    rew = _floats(reward, (n,), "reward")
    rates = _rates(epsilon, alpha, n)
    if not second_stage and cfg.traits.two_stage:
        return _first_stage_only(cfg, pop, state, obs, rew, rates, learn, trace)
    if trace:
        visits = np.full((_VISIT, n, cfg.max_visits_per_step), -1, TRACE_DTYPE)
        count = np.zeros(n, TRACE_DTYPE)
    else:
        visits, count = _NO_TRACE, _NO_COUNT
    run_kernel(method_code(cfg), cfg, pop, state, obs, rew, rates, learn, visits, count)
    if trace:
        return state.wheels.copy(), step_trace(visits, count)
    return state.wheels.copy(), None


KernelArguments: TypeAlias = tuple[
    int,
    bool,
    float,
    int,
    int,
    int,
    int,
    npt.NDArray[np.uint8],
    tuple[int, ...],
    npt.NDArray[np.int32],
    npt.NDArray[np.float64],
    npt.NDArray[np.uint64],
]
"""`kernel_arguments`' tuple: method code, fuzzy, γ, the four sizes, the record bytes, the record
layout, and the state's walk, wheels and rng."""


def kernel_arguments(
    method_code: int, cfg: GnpConfig, pop: Population, state: EngineState
) -> KernelArguments:
    """`step_kernel`'s leading arguments, those that stay the same from step to step: the
    method, the config's sizes, the population's records and the engine state (arrays are the
    population's and the state's own, so a compiled loop that calls `step_kernel` with them
    learns in place)."""
    return (
        method_code,
        cfg.fuzzy,
        cfg.gamma,
        cfg.n_nodes,
        cfg.n_judgment,
        cfg.n_sub,
        cfg.n_conn_branches,
        # One array for the whole population: every array argument costs the call time.
        pop.record_bytes,
        record_layout(cfg.n_sub, cfg.n_conn_branches, cfg.judgment_branches),
        state.walk,
        state.wheels,
        state.rng,
    )


def method_code(cfg: GnpConfig) -> int:
    """The kernel's code of `cfg`'s method, both stages on, with its tie-break's flag."""
    return _KERNEL_CODE[cfg.method] | _flags(cfg)


def _flags(cfg: GnpConfig) -> int:
    """The kernel's flags of `cfg.tie_break` (`TIE_FIRST` for "first"), `cfg.skip_reward`
    (`SKIP_EARNS` for "step") and `cfg.processing_output` (`EMIT_FUNCTION` for "function"), 0
    for the defaults."""
    return (
        (TIE_FIRST if cfg.tie_break == "first" else 0)
        | (SKIP_EARNS if cfg.skip_reward == "step" else 0)
        | (EMIT_FUNCTION if cfg.processing_output == "function" else 0)
    )


def check_population(cfg: GnpConfig, pop: Population, state: EngineState) -> None:
    """Raise GnpError unless `pop` is built for `cfg` and has one individual per controller."""
    n = state.walk.shape[0]
    records = pop.records
    dtype = record_dtype(cfg.n_sub, cfg.n_conn_branches, cfg.judgment_branches)
    if records.shape != (n, cfg.n_nodes) or (records.dtype is not dtype and records.dtype != dtype):
        _raise_mismatch(cfg, pop, n)


def run_kernel(
    method_code: int,
    cfg: GnpConfig,
    pop: Population,
    state: EngineState,
    obs: np.ndarray,
    rew: np.ndarray,
    rates: np.ndarray,
    learn: bool,
    visits: np.ndarray,
    count: np.ndarray,
) -> None:
    """One call of the compiled kernel on checked arguments (see `step`)."""
    step_kernel(
        *kernel_arguments(method_code, cfg, pop, state), obs, rew, rates, learn, visits, count
    )


# The live ablation (docs/decisions.md, "Live ablation"): a step with the method's second
# stage off, on the unchanged kernel.
def _first_stage_only(
    cfg: GnpConfig,
    pop: Population,
    state: EngineState,
    obs: np.ndarray,
    rew: np.ndarray,
    rates: np.ndarray,
    learn: bool,
    trace: bool,
) -> StepResult:
    """`step` with the second stage off, for BS and CS, on the unchanged kernel.

    Both run as RL (sub node selection and Q_SS only: no credit choice, no Q_BS or Q_CS
    update, no draw for either). CS then is RL on its genome. For BS the kernel, which follows
    branch connection 0 in RL mode, finds in that slot, for the call, the greedy connection
    (argmax of Q_BS, ties to the lowest u; Q_BS cannot change during the call); afterwards the
    trace and the pending visits get the u they took, so that Q_BS updates resume correctly
    once the second stage is back on.
    """
    n = state.walk.shape[0]
    visits = np.full((_VISIT, n, cfg.max_visits_per_step), -1, TRACE_DTYPE)
    count = np.zeros(n, TRACE_DTYPE)
    bs = cfg.traits.branch_selection
    conn = pop.conn  # a view into the records the kernel reads
    if bs:
        greedy = np.argmax(pop.q_bs, axis=-1)  # (N, V, m, 2): the first maximum
        greedy[:, 0] = 0  # the start node follows connection 0
        first = conn[..., 0].copy()
        conn[..., 0] = np.take_along_axis(conn, greedy[..., None], axis=-1)[..., 0]
    try:
        code = FIRST_STAGE_ONLY | _flags(cfg)
        run_kernel(code, cfg, pop, state, obs, rew, rates, learn, visits, count)
    finally:
        if bs:
            conn[..., 0] = first
    steps = step_trace(visits, count)
    if bs:
        node, sub, branch, u = steps.node, steps.sub, steps.branch, steps.u
        c, k = np.nonzero(node > 0)
        u[c, k] = greedy[c, node[c, k], sub[c, k], branch[c, k]]
        # The last visit is always this step's; the one before it when the step made two.
        walk = state.walk
        rows = np.arange(n)
        last = walk[:, 1] > 0
        walk[last, 4] = greedy[rows[last], walk[last, 1], walk[last, 2], walk[last, 3]]
        before = (walk[:, 6] > 0) & (np.count_nonzero(node > 0, axis=1) >= 2)
        walk[before, 9] = greedy[rows[before], walk[before, 6], walk[before, 7], walk[before, 8]]
    return state.wheels.copy(), steps if trace else None
