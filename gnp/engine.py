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

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, NoReturn, cast, overload

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from gnp.config import (
    JUDGMENT,
    METHODS,
    NODE_COST,
    PROCESSING,
    SKIP_COST,
    STEP_BUDGET,
    GnpConfig,
    GnpError,
)
from gnp.population import CACHE_LINE, Population, record_dtype
from gnp.rng import next_uniform, seed_states

METHOD_CODE = {method: code for code, method in enumerate(METHODS)}
_BS, _CS = 1, 2
_JUDGMENT_COST, _PROCESSING_COST = NODE_COST[JUDGMENT], NODE_COST[PROCESSING]


@dataclass(frozen=True)
class EngineState:
    """Mutable per-controller engine state, arrays with leading axis N.

    Attributes:
        walk: (N, 11) int32, where each controller's walk through its graph stands: the
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
        return self.walk[:, 1:6]

    @property
    def pending_bs(self) -> np.ndarray:
        """(N, 5) the visit before it, awaiting its Q_BS update (BS only)."""
        return self.walk[:, 6:11]

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


TRACE_FIELDS = ("node", "sub", "branch", "u", "skipped", "count")
"""The fields of a `StepTrace`, in the store's order."""
TRACE_DTYPE = np.int32


def trace_shapes(cfg: GnpConfig) -> dict[str, tuple[int, ...]]:
    """Per-controller shape (without the leading N) of every `StepTrace` field."""
    visits = (cfg.max_visits_per_step,)
    return {field: () if field == "count" else visits for field in TRACE_FIELDS}


def init_state(cfg: GnpConfig, n: int, seeds: np.ndarray | list[int]) -> EngineState:
    """State for n controllers at the start node, wheels at 0, streams seeded from `seeds`."""
    states = seed_states(seeds)
    if states.shape != (n,):
        raise GnpError(f"init_state: need {n} seeds, got {states.shape[0]}")
    walk = np.full((n, 11), -1, np.int32)
    walk[:, 0] = 0
    return EngineState(walk=walk, wheels=np.zeros((n, 2), np.float64), rng=states)


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
    expected = (cfg.n_nodes, cfg.n_sub, 2, cfg.n_conn_branches)
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


_LAYOUT_FIELDS = (
    "q_ss", "q_bs", "q_cs", "mu_beta", "mu_alpha", "conn", "credit", "function", "speed"
)  # fmt: skip


@functools.cache
def _layout(n_sub: int, n_conn_branches: int) -> tuple[int, ...]:
    """The record layout as the kernel reads it: the record's size in bytes, then where each
    field of `_LAYOUT_FIELDS` starts, in words of the field's own size."""
    fields = record_dtype(n_sub, n_conn_branches).fields
    assert fields is not None
    offsets = [fields[f][1] // fields[f][0].base.itemsize for f in _LAYOUT_FIELDS]
    return (record_dtype(n_sub, n_conn_branches).itemsize, *offsets)


# numba's option to compile without its reference-counting runtime (absent from its type
# stubs): the kernel allocates nothing, and the runtime's atomic reference counts on every
# array argument cost more than a third of a call for small batches.
_WITHOUT_NRT = {"_nrt": False}

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
    *,
    second_stage: bool = ...,
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
    *,
    second_stage: bool = ...,
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
    second_stage: bool = ...,
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
    *,
    second_stage: bool = ...,
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
    *,
    second_stage: bool = True,
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
        second_stage: the method's second stage on (default). Off, a BS controller takes the
            greedy branch connection (argmax of Q_BS, ties to the lowest u, no exploration)
            and leaves Q_BS alone; a CS controller never takes its credit branch and leaves
            Q_CS alone; RL has none (no effect). Q_SS learns either way.

    Returns:
        Wheel commands (N, 2) as (left, right) in −10..10, and the StepTrace if `trace`.
    """
    n = state.walk.shape[0]
    records = pop.records
    dtype = record_dtype(cfg.n_sub, cfg.n_conn_branches)
    if records.shape != (n, cfg.n_nodes) or (records.dtype is not dtype and records.dtype != dtype):
        _raise_mismatch(cfg, pop, n)
    obs = _floats(observations, (n, 8), "observations")
    rew = _floats(reward, (n,), "reward")
    rates = _rates(epsilon, alpha, n)
    if not second_stage and cfg.method != "RL":
        from gnp.first_stage import first_stage_only  # the live ablation: off the hot path

        return first_stage_only(cfg, pop, state, obs, rew, rates, learn, trace)
    if trace:
        visits = np.full((5, n, cfg.max_visits_per_step), -1, TRACE_DTYPE)
        count = np.zeros(n, TRACE_DTYPE)
    else:
        visits, count = _NO_TRACE, _NO_COUNT
    run_kernel(METHOD_CODE[cfg.method], cfg, pop, state, obs, rew, rates, learn, visits, count)
    commands = state.wheels.copy()
    if trace:
        node, sub, branch, u, skipped = visits
        return commands, StepTrace(node, sub, branch, u, skipped, count)
    return commands


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
    _step_kernel(
        method_code,
        cfg.fuzzy,
        cfg.gamma,
        cfg.n_nodes,
        cfg.n_judgment,
        cfg.n_sub,
        cfg.n_conn_branches,
        # One array for the whole population: every array argument costs the call time.
        pop.record_bytes,
        _layout(cfg.n_sub, cfg.n_conn_branches),
        state.walk,
        state.wheels,
        state.rng,
        obs,
        rew,
        rates,
        learn,
        visits,
        count,
    )


def _prefetch_typer(typingctx, array, index):
    """Hint the CPU to load array[index] (a tuple of ndim indices) into cache; no effect else.

    The engine is bound by memory latency: a world step evicts the population's records, and
    a visit's next node is known only at its end. Prefetching the next record while another
    controller runs overlaps those waits (see `_step_kernel`).
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
def _prefetch_record(words: np.ndarray, start: int, lines: int) -> None:
    """Prefetch the `lines` cache lines of a record that begins at float32 word `start`."""
    for i in range(lines):
        _prefetch(words, (start + i * (CACHE_LINE // 4),))


@njit(cache=True, inline="always")
def _ix(i):  # pragma: no cover - compiled
    """A flat index as unsigned: numba then skips its negative-index wraparound, two
    instructions on every one of a visit's ~25 loads and stores."""
    return np.uint64(i)


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
    best = q[_ix(start)]
    ties = 1
    for a in range(1, k):
        value = q[_ix(start + a)]
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
        if q[_ix(start + a)] == best:
            if pick == 0:
                return s, a
            pick -= 1
    return s, k - 1  # unreachable


# Positions in the `run` tuple the kernel hands its helpers.
_METHOD, _N_NODES, _WORDS32, _LAYOUT, _WALK, _COUNT = 0, 3, 7, 10, 11, 19


@njit(cache=True, inline="always")
def _visit(c, used, k, run):  # pragma: no cover - compiled
    """Controller c's next visit (after the start node, if it stands there): choose, learn,
    run, and move on. Its walk (`walk[c]`, `rng[c]`) is read from and written back to memory,
    so that controllers can take turns (see `_step_kernel`). Returns (used, k): the step's
    time units spent and visits made so far, the start node included."""
    (
        method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, words32, words16, words8,
        layout, walk, wheels, rng, obs, reward, rates, learn, visits, _,
    ) = run  # fmt: skip
    i = _ix(c)  # controller c's rows, indexed without numba's negative-index check
    record_bytes = layout[0]
    r32, r16 = record_bytes // 4, record_bytes // 2
    ss, bs, cs_, beta, alpha, cn, cr, fn_, sp = layout[1:]
    trace = visits.shape[1] > 0
    rate_row = 0 if rates.shape[0] == 1 else c
    eps, lr = rates[rate_row, 0], rates[rate_row, 1]
    s = rng[i]
    node = walk[i, 0]
    while node == 0:  # the start node: costs nothing, runs once per episode
        if trace:
            visits[0, c, k] = node
            visits[1:, c, k] = 0
        k += 1
        node = words16[_ix(c * n_nodes * r16 + cn)]
    # The last visit (awaiting its Q_SS/Q_CS update) and the one before it (awaiting its
    # Q_BS update): (node, sub, branch, u, credit), and where their Q values are.
    pn, pp, pb, pu, pc = walk[i, 1], walk[i, 2], walk[i, 3], walk[i, 4], walk[i, 5]
    bn, bp, bb, bu = walk[i, 6], walk[i, 7], walk[i, 8], walk[i, 9]
    # A step's first visit credits the previous step's reward to the visit before it, unless
    # that was a credit skip (reward 0, Eq. 5.3).
    pend_r = reward[i] if used == 0 and pn >= 0 and pc != 1 else 0.0
    record = c * n_nodes + node
    q, h, b = record * r32, record * r16, record * record_bytes
    s, p = _egreedy(words32, q + ss, n_sub, eps, s)
    cs = 0
    if method == _CS:
        s, cs = _egreedy(words32, q + cs_ + 2 * p, 2, eps, s)
    if learn and pn >= 0:
        last_q = (c * n_nodes + pn) * r32
        last_ss = last_q + ss + pp
        words32[_ix(last_ss)] += lr * (
            pend_r + gamma * words32[_ix(q + ss + p)] - words32[_ix(last_ss)]
        )
        if method == _CS:
            last_cs = last_q + cs_ + 2 * pp + pc
            target = pend_r + gamma * words32[_ix(q + cs_ + 2 * p + cs)]
            words32[_ix(last_cs)] += lr * (target - words32[_ix(last_cs)])
        if method == _BS and bn >= 0:
            last_bs = last_q + bs + (2 * pp + pb) * n_conn + pu
            before_bs = (c * n_nodes + bn) * r32 + bs + (2 * bp + bb) * n_conn + bu
            words32[_ix(before_bs)] += lr * (
                pend_r + gamma * words32[_ix(last_bs)] - words32[_ix(before_bs)]
            )
    if cs == 1:
        used += SKIP_COST
        branch = -1
        u = -1
        nxt = words16[_ix(h + cr + p)]
    else:
        fn = words8[_ix(b + fn_ + p)]
        if node <= n_judgment:  # nodes 1..n_judgment judge
            used += _JUDGMENT_COST
            x = obs[i, _ix(fn)]
            lo = words16[_ix(h + beta + p)]
            hi = words16[_ix(h + alpha + p)]
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
            # Function 0 is the right wheel (P0) and 1 the left (P1); wheels are stored as
            # (left, right).
            wheels[i, _ix(1 - fn)] = float(words8[_ix(b + sp + p)])
            branch = 0
        u = 0
        if method == _BS:
            s, u = _egreedy(words32, q + bs + (2 * p + branch) * n_conn, n_conn, eps, s)
        nxt = words16[_ix(h + cn + (2 * p + branch) * n_conn + u)]
    # The next record, loading while the other controller takes its turn.
    _prefetch_record(words32, (c * n_nodes + nxt) * r32, record_bytes // CACHE_LINE)
    if trace:
        visits[0, c, k] = node
        visits[1, c, k] = p
        visits[2, c, k] = branch
        visits[3, c, k] = u
        visits[4, c, k] = cs
    walk[i, 6], walk[i, 7], walk[i, 8], walk[i, 9], walk[i, 10] = pn, pp, pb, pu, pc
    walk[i, 1], walk[i, 2], walk[i, 3], walk[i, 4], walk[i, 5] = node, p, branch, u, cs
    walk[i, 0] = nxt
    rng[i] = s
    return used, k + 1


@njit(cache=True, inline="always")
def _turn(c, used, k, waiting, run):  # pragma: no cover - compiled
    """Lane of controller c: one visit; once c's step is done the lane takes the next waiting
    controller. A lane whose controller number reaches N is idle. Returns (c, used, k,
    waiting) for the lane's next turn."""
    walk, count = run[_WALK], run[_COUNT]
    n_ctrl = walk.shape[0]
    if c >= n_ctrl:
        return c, used, k, waiting
    used, k = _visit(c, used, k, run)
    if used >= STEP_BUDGET:
        if count.shape[0] > 0:
            count[c] = k
        c, used, k, waiting = waiting, 0, 0, waiting + 1
        if c < n_ctrl:
            _prefetch_walk(c, run)
    return c, used, k, waiting


@njit(cache=True, inline="always")
def _prefetch_walk(c, run):  # pragma: no cover - compiled
    """Prefetch what controller c's step starts with: its current node's record, and the Q
    values of its last two visits, which its first visit updates (the world step in between
    has evicted them). Q values lead a record, so their first line is prefetched, no more:
    every line the engine loads evicts one of the world's."""
    n_nodes, words32, layout, walk = run[_N_NODES], run[_WORDS32], run[_LAYOUT], run[_WALK]
    r32 = layout[0] // 4
    _prefetch_record(words32, (c * n_nodes + walk[c, 0]) * r32, layout[0] // CACHE_LINE)
    if walk[c, 1] >= 0:
        _prefetch_record(words32, (c * n_nodes + walk[c, 1]) * r32, 1)
    if walk[c, 6] >= 0 and run[_METHOD] == _BS:
        _prefetch_record(words32, (c * n_nodes + walk[c, 6]) * r32, 1)


@njit(cache=True, **_WITHOUT_NRT)  # type: ignore[call-overload]
def _step_kernel(
    method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, records, layout, walk, wheels, rng,
    obs, reward, rates, learn, visits, count,
):  # fmt: skip  # pragma: no cover - compiled
    """Run every controller's visits until its step's time units are spent.

    Two controllers take turns, a visit each: the record of a controller's next node is
    then fetched while the other one runs, instead of stalling the walk (the engine is bound by
    the latency of these loads, not by arithmetic). Controllers never share data, so the
    turns change nothing in what each one does.
    """
    words32, words16, words8 = (
        records.view(np.float32),
        records.view(np.int16),
        records.view(np.int8),
    )
    # Everything a visit reads, in one tuple (`_visit` unpacks it; `_METHOD` … name positions).
    run = (
        method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, words32, words16, words8,
        layout, walk, wheels, rng, obs, reward, rates, learn, visits, count,
    )  # fmt: skip
    n_ctrl = walk.shape[0]
    for c in range(min(n_ctrl, 2)):
        _prefetch_walk(c, run)
    a, b, waiting = 0, 1, 2
    used_a = used_b = k_a = k_b = 0
    while a < n_ctrl or b < n_ctrl:
        a, used_a, k_a, waiting = _turn(a, used_a, k_a, waiting, run)
        b, used_b, k_b, waiting = _turn(b, used_b, k_b, waiting, run)
