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

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, cast, overload

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from gnp.config import (
    JUDGMENT,
    NODE_COST,
    PROCESSING,
    SKIP_COST,
    START,
    STEP_BUDGET,
    GnpConfig,
    GnpError,
)
from gnp.population import Population
from gnp.rng import next_uniform, seed_states

METHOD_CODE = {"RL": 0, "BS": 1, "CS": 2}
_BS, _CS = 1, 2
_JUDGMENT_COST, _PROCESSING_COST = NODE_COST[JUDGMENT], NODE_COST[PROCESSING]


@dataclass(frozen=True)
class EngineState:
    """Mutable per-controller engine state, arrays with leading axis N.

    Attributes:
        node: (N,) current node (0 = start node: a new episode).
        wheels: (N, 2) wheel speeds as (left, right); each keeps its value until a processing
            node sets it.
        rng: (N,) uint64 splitmix64 state of each controller's own random stream.
        pending: (N, 5) the last visit (node, sub, branch, u, credit), awaiting its Q_SS/Q_CS
            update; node −1 when there is none.
        pending_bs: (N, 5) the visit before it, awaiting its Q_BS update (BS only).
    """

    node: np.ndarray
    wheels: np.ndarray
    rng: np.ndarray
    pending: np.ndarray
    pending_bs: np.ndarray

    @property
    def size(self) -> int:
        return int(self.node.shape[0])


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


def init_state(cfg: GnpConfig, n: int, seeds: np.ndarray | list[int]) -> EngineState:
    """State for n controllers at the start node, wheels at 0, streams seeded from `seeds`."""
    states = seed_states(seeds)
    if states.shape != (n,):
        raise GnpError(f"init_state: need {n} seeds, got {states.shape[0]}")
    return EngineState(
        node=np.zeros(n, np.int32),
        wheels=np.zeros((n, 2), np.float64),
        rng=states,
        pending=np.full((n, 5), -1, np.int32),
        pending_bs=np.full((n, 5), -1, np.int32),
    )


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
    state.node[:] = 0
    state.wheels[:] = 0.0
    state.pending[:] = -1
    state.pending_bs[:] = -1


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


# Stand-ins for the trace arrays when no trace is asked for (the kernel then writes none).
_NO_TRACE = np.empty((5, 0, 0), np.int32)
_NO_COUNT = np.empty(0, np.int32)


@overload
def step(
    cfg: GnpConfig,
    pop: Population,
    state: EngineState,
    observations: np.ndarray,
    reward: np.ndarray,
    epsilon: float | np.ndarray,
    alpha: float | np.ndarray,
    learn: bool = ...,
    trace: Literal[False] = ...,
) -> np.ndarray: ...


@overload
def step(
    cfg: GnpConfig,
    pop: Population,
    state: EngineState,
    observations: np.ndarray,
    reward: np.ndarray,
    epsilon: float | np.ndarray,
    alpha: float | np.ndarray,
    learn: bool,
    trace: Literal[True],
) -> tuple[np.ndarray, StepTrace]: ...


@overload
def step(
    cfg: GnpConfig,
    pop: Population,
    state: EngineState,
    observations: np.ndarray,
    reward: np.ndarray,
    epsilon: float | np.ndarray,
    alpha: float | np.ndarray,
    learn: bool = ...,
    *,
    trace: Literal[True],
) -> tuple[np.ndarray, StepTrace]: ...


@overload
def step(
    cfg: GnpConfig,
    pop: Population,
    state: EngineState,
    observations: np.ndarray,
    reward: np.ndarray,
    epsilon: float | np.ndarray,
    alpha: float | np.ndarray,
    learn: bool = ...,
    trace: bool = ...,
) -> np.ndarray | tuple[np.ndarray, StepTrace]: ...


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
) -> np.ndarray | tuple[np.ndarray, StepTrace]:
    """Advance N controllers by one world step.

    Args:
        cfg: the configuration `pop` was built for.
        pop: N individuals; their Q tables are updated in place when `learn`.
        state: engine state of the N controllers, updated in place.
        observations: (N, 8) sensor readings the controllers see, 0..1023.
        reward: (N,) reward of the previous world step, credited to that step's last visit.
        epsilon: ε of ε-greedy, scalar or (N,).
        alpha: learning rate α, scalar or (N,).
        learn: apply Sarsa updates.
        trace: also return a StepTrace.

    Returns:
        Wheel commands (N, 2) as (left, right) in −10..10, and the StepTrace if `trace`.
    """
    n = state.size
    if pop.size != n:
        raise GnpError(f"population has {pop.size} individuals, state {n} controllers")
    expected = (cfg.n_nodes, cfg.n_sub, 2, cfg.n_conn_branches)
    if pop.q_bs.shape[1:] != expected:
        raise GnpError(
            f"population does not match the config: q_bs has shape {pop.q_bs.shape[1:]} per "
            f"individual, expected {expected} (nodes, sub nodes, branches, connections)"
        )
    if not (
        pop.q_ss.flags.c_contiguous and pop.q_bs.flags.c_contiguous and pop.q_cs.flags.c_contiguous
    ):
        raise GnpError("the population's Q tables must be C-contiguous (learning writes them)")
    obs = np.ascontiguousarray(observations, dtype=np.float64)
    if obs.shape != (n, 8):
        raise GnpError(f"observations must have shape ({n}, 8), got {obs.shape}")
    rew = np.ascontiguousarray(reward, dtype=np.float64)
    if rew.shape != (n,):
        raise GnpError(f"reward must have shape ({n},), got {rew.shape}")
    rates = _rates(epsilon, alpha, n)
    if trace:
        visits = np.full((5, n, cfg.max_visits_per_step), -1, np.int32)
        count = np.zeros(n, np.int32)
    else:
        visits, count = _NO_TRACE, _NO_COUNT
    _step_kernel(
        METHOD_CODE[cfg.method],
        cfg.fuzzy,
        cfg.gamma,
        cfg.node_type,
        pop.function,
        pop.mu_beta,
        pop.mu_alpha,
        pop.speed,
        pop.conn,
        pop.credit,
        pop.q_ss,
        pop.q_bs,
        pop.q_cs,
        state.node,
        state.wheels,
        state.rng,
        state.pending,
        state.pending_bs,
        obs,
        rew,
        rates,
        learn,
        visits,
        count,
    )
    commands = state.wheels.copy()
    if trace:
        node, sub, branch, u, skipped = visits
        return commands, StepTrace(node, sub, branch, u, skipped, count)
    return commands


def _prefetch_typer(typingctx, array, index):
    """Hint the CPU to load array[index] (a tuple of ndim indices) into cache; no effect else.

    The engine is bound by memory latency: after a world step its genes and Q tables sit in
    the last-level cache, and each visit's loads wait on the Q_SS row that picks the sub node.
    Prefetching every sub node's genes as soon as the node is known overlaps those waits.
    """
    if not (isinstance(array, types.Array) and isinstance(index, types.BaseTuple)):
        return None
    if len(index) != array.ndim:
        return None

    def codegen(context, builder, signature, args):
        array_type, index_type = signature.args
        arr = context.make_array(array_type)(context, builder, args[0])
        indices = [
            context.cast(builder, i, t, types.intp)
            for i, t in zip(cgutils.unpack_tuple(builder, args[1]), index_type, strict=True)
        ]
        ptr = cgutils.get_item_pointer(context, builder, array_type, arr, indices, False)
        byte_ptr = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fn_type = ir.FunctionType(ir.VoidType(), [byte_ptr, i32, i32, i32])
        fn = cgutils.get_or_insert_function(builder.module, fn_type, "llvm.prefetch.p0i8")
        # read, highest temporal locality, data cache
        builder.call(fn, [builder.bitcast(ptr, byte_ptr), i32(0), i32(3), i32(1)])
        return context.get_dummy_value()

    return types.void(array, index), codegen


_prefetch = cast(Callable[[np.ndarray, tuple[int, ...]], None], intrinsic(_prefetch_typer))


@njit(cache=True, inline="always")
def _egreedy(q: np.ndarray, start: int, k: int, eps: float, s: np.uint64) -> tuple[np.uint64, int]:
    """ε-greedy over the k action values q[start : start + k]: (new stream state, chosen index).

    Draw u; if u < ε pick uniformly among all actions, else uniformly among the maxima (one
    more draw only when there is a tie). Reads by flat index rather than through a slice: a
    slice costs reference counting in the hot loop.
    """
    s, u = next_uniform(s)
    if u < eps:
        s, v = next_uniform(s)
        return s, min(int(v * k), k - 1)
    best = q[start]
    ties = 1
    for a in range(1, k):
        value = q[start + a]
        if value > best:
            best = value
            ties = 1
        elif value == best:
            ties += 1
    pick = 0
    if ties > 1:
        s, v = next_uniform(s)
        pick = min(int(v * ties), ties - 1)
    for a in range(k):
        if q[start + a] == best:
            if pick == 0:
                return s, a
            pick -= 1
    return s, k - 1  # unreachable


@njit(cache=True)
def _step_kernel(
    method,
    fuzzy,
    gamma,
    node_type,
    function,
    mu_beta,
    mu_alpha,
    speed,
    conn,
    credit,
    q_ss,
    q_bs,
    q_cs,
    cur_node,
    wheels,
    rng,
    pending,
    pending_bs,
    obs,
    reward,
    rates,
    learn,
    visits,
    count,
):  # pragma: no cover - compiled
    n_ctrl = cur_node.shape[0]
    n_nodes = q_ss.shape[1]
    n_sub = q_ss.shape[2]
    n_conn = q_bs.shape[4]
    trace = count.shape[0] > 0
    shared_rates = rates.shape[0] == 1
    # Flat views: an array's metadata (shape, strides) is one length, which keeps the loop's
    # state in registers. A sub node's genes sit at g = (c·V + node)·m + p in every (N, V, m)
    # array, its Q_CS pair at 2g, its branch connections and Q_BS row at (2g + branch)·U.
    function = function.reshape(function.size)
    mu_beta = mu_beta.reshape(mu_beta.size)
    mu_alpha = mu_alpha.reshape(mu_alpha.size)
    speed = speed.reshape(speed.size)
    conn = conn.reshape(conn.size)
    credit = credit.reshape(credit.size)
    q_ss = q_ss.reshape(q_ss.size)
    q_bs = q_bs.reshape(q_bs.size)
    q_cs = q_cs.reshape(q_cs.size)
    if n_ctrl > 0:
        _prefetch(q_ss, (cur_node[0] * n_sub,))
    for c in range(n_ctrl):
        if c + 1 < n_ctrl:  # the next controller's first node, while this one runs
            _prefetch(q_ss, (((c + 1) * n_nodes + cur_node[c + 1]) * n_sub,))
        s = rng[c]
        node = cur_node[c]
        rate_row = 0 if shared_rates else c
        eps = rates[rate_row, 0]
        lr = rates[rate_row, 1]
        # The last visit (awaiting its Q_SS/Q_CS update) and the one before it (awaiting its
        # Q_BS update): (node, sub, branch, u, credit), and the flat indices of their entries.
        pn, pp, pb, pu, pc = (
            pending[c, 0],
            pending[c, 1],
            pending[c, 2],
            pending[c, 3],
            pending[c, 4],
        )
        bn, bp, bb, bu, bc = (
            pending_bs[c, 0],
            pending_bs[c, 1],
            pending_bs[c, 2],
            pending_bs[c, 3],
            pending_bs[c, 4],
        )
        last_g = (c * n_nodes + pn) * n_sub + pp
        last_bs = (2 * last_g + pb) * n_conn + pu
        before_bs = (2 * ((c * n_nodes + bn) * n_sub + bp) + bb) * n_conn + bu
        # The last visit was the last of the previous world step: it earns that step's reward,
        # unless it was a credit skip (reward 0, Eq. 5.3).
        pend_r = reward[c] if pn >= 0 and pc != 1 else 0.0
        used = 0
        k = 0
        while used < STEP_BUDGET:
            if node_type[node] == START:
                if trace:
                    visits[0, c, k] = node
                    visits[1:, c, k] = 0
                k += 1
                node = conn[(c * n_nodes + node) * n_sub * 2 * n_conn]
                continue
            first = (c * n_nodes + node) * n_sub  # the node's first sub node
            # Every sub node's genes and Q values (the lines they span), fetched while Q_SS
            # picks the sub node.
            is_judgment = node_type[node] == JUDGMENT
            _prefetch(function, (first,))
            _prefetch(conn, (2 * first * n_conn,))
            _prefetch(conn, (2 * (first + n_sub) * n_conn - 1,))
            if is_judgment:
                _prefetch(mu_beta, (first,))
                _prefetch(mu_alpha, (first,))
            else:
                _prefetch(speed, (first,))
            if method == _BS:
                _prefetch(q_bs, (2 * first * n_conn,))
                _prefetch(q_bs, (2 * (first + n_sub) * n_conn - 1,))
            elif method == _CS:
                _prefetch(q_cs, (2 * first,))
                _prefetch(q_cs, (2 * (first + n_sub) - 1,))
                _prefetch(credit, (first,))
            s, p = _egreedy(q_ss, first, n_sub, eps, s)
            g = first + p
            cs = 0
            if method == _CS:
                s, cs = _egreedy(q_cs, 2 * g, 2, eps, s)
            if learn and pn >= 0:
                q_ss[last_g] += lr * (pend_r + gamma * q_ss[g] - q_ss[last_g])
                if method == _CS:
                    last_cs = 2 * last_g + pc
                    q_cs[last_cs] += lr * (pend_r + gamma * q_cs[2 * g + cs] - q_cs[last_cs])
                if method == _BS and bn >= 0:
                    q_bs[before_bs] += lr * (pend_r + gamma * q_bs[last_bs] - q_bs[before_bs])
            if cs == 1:
                used += SKIP_COST
                branch = -1
                u = -1
                nxt = credit[g]
            else:
                fn = function[g]
                if is_judgment:
                    used += _JUDGMENT_COST
                    x = obs[c, fn]
                    lo = mu_beta[g]
                    hi = mu_alpha[g]
                    if fuzzy:
                        if x >= hi:
                            mu = 1.0
                        elif x <= lo:
                            mu = 0.0
                        else:
                            mu = (x - lo) / (hi - lo)
                        s, v = next_uniform(s)
                        branch = 0 if v < mu else 1
                    else:
                        branch = 0 if x >= (lo + hi) / 2.0 else 1
                else:
                    used += _PROCESSING_COST
                    # Function 0 is the right wheel (P0) and 1 the left (P1); wheels are
                    # stored as (left, right).
                    wheels[c, 1 - fn] = float(speed[g])
                    branch = 0
                row = (2 * g + branch) * n_conn
                u = 0
                if method == _BS:
                    s, u = _egreedy(q_bs, row, n_conn, eps, s)
                nxt = conn[row + u]
                before_bs = last_bs
                last_bs = row + u
            if trace:
                visits[0, c, k] = node
                visits[1, c, k] = p
                visits[2, c, k] = branch
                visits[3, c, k] = u
                visits[4, c, k] = cs
            k += 1
            bn, bp, bb, bu, bc = pn, pp, pb, pu, pc
            pn, pp, pb, pu, pc = node, p, branch, u, cs
            last_g = g
            pend_r = 0.0
            node = nxt
        cur_node[c] = node
        rng[c] = s
        pending[c, 0], pending[c, 1], pending[c, 2], pending[c, 3], pending[c, 4] = (
            pn,
            pp,
            pb,
            pu,
            pc,
        )
        pending_bs[c, 0], pending_bs[c, 1], pending_bs[c, 2] = bn, bp, bb
        pending_bs[c, 3], pending_bs[c, 4] = bu, bc
        if trace:
            count[c] = k
