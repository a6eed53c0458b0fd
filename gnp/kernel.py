"""The compiled walk: numba code that runs every controller's visits for one world step.

`gnp.engine` checks the arguments and calls `step_kernel`; everything here runs compiled. A
population's records are one byte array (`gnp.population.record_dtype`), read through views
of its float32, int16 and int8 words at the offsets `record_layout` gives, which also gives
the judgment nodes' branch count k (`GnpConfig.judgment_branches`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, Final, TypeAlias, cast

import numpy as np
import numpy.typing as npt
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.core.base import BaseContext
from numba.core.typing import Context, Signature
from numba.extending import intrinsic

from gnp.config import JUDGMENT, NODE_COST, PROCESSING, SKIP_COST, SPEED_MAX, STEP_BUDGET
from gnp.methods import BRANCH_SELECTION as _BS  # `method` is `MethodTraits.kernel_code`
from gnp.methods import CREDIT as _CS
from gnp.methods import EMIT_FUNCTION as _EMIT_FUNCTION
from gnp.methods import SKIP_EARNS as _SKIP_EARNS
from gnp.methods import TIE_FIRST as _TIE_FIRST
from gnp.population import CACHE_LINE, record_dtype
from gnp.rng import next_uniform

_JUDGMENT_COST, _PROCESSING_COST = NODE_COST[JUDGMENT], NODE_COST[PROCESSING]

# The kernel's arrays, by dtype (numba reads no annotations: these are for mypy and readers).
Floats: TypeAlias = npt.NDArray[np.float64]
"""Observations, rewards, (ε, α) rates and wheel commands."""
Records: TypeAlias = npt.NDArray[np.uint8]
"""A population's records as one flat byte array (`Population.record_bytes`)."""
Walks: TypeAlias = npt.NDArray[np.int32]
"""The engine state's walk, (N, `gnp.engine.WALK_WIDTH`)."""
Streams: TypeAlias = npt.NDArray[np.uint64]
"""The engine state's random streams, (N,) splitmix64 states."""
Traces: TypeAlias = npt.NDArray[np.int32]
"""Trace arrays: visits (5, N, max visits) and counts (N,), `gnp.engine.TRACE_DTYPE`."""
Layout: TypeAlias = tuple[int, ...]
"""`record_layout`'s tuple."""
Reader: TypeAlias = Callable[[Floats, Any, np.uint64, np.uint64], float]
"""`read(obs, source, i, j)`: what controller i sees of sensor j (`read_observed`); `source` is
whatever the reader reads besides `obs` (Any: numba's `Dispatcher` type keeps no type variable)."""


_LAYOUT_FIELDS = (
    "q_ss", "q_bs", "q_cs", "mu_beta", "mu_alpha", "conn", "credit", "function", "speed"
)  # fmt: skip


#: Position of the branch count k in `record_layout`'s tuple (after the size and the offsets).
LAYOUT_BRANCHES: Final = 1 + len(_LAYOUT_FIELDS)


@functools.cache
def record_layout(n_sub: int, n_conn_branches: int, judgment_branches: int) -> Layout:
    """The record layout as the kernel reads it: the record's size in bytes, then where each
    field of `_LAYOUT_FIELDS` starts, in words of the field's own size, then the size k of
    the branch axis of `conn` and `q_bs` (`judgment_branches`)."""
    dtype = record_dtype(n_sub, n_conn_branches, judgment_branches)
    fields = dtype.fields
    assert fields is not None
    offsets = [fields[f][1] // fields[f][0].base.itemsize for f in _LAYOUT_FIELDS]
    return (dtype.itemsize, *offsets, judgment_branches)


# numba's option to compile without its reference-counting runtime (absent from its type
# stubs): the kernel allocates nothing, and the runtime's atomic reference counts on every
# array argument cost more than a third of a call for small batches.
_WITHOUT_NRT = {"_nrt": False}


def _prefetch_typer(
    _typingctx: Context, array: types.Type, index: types.Type
) -> tuple[Signature, Callable[[BaseContext, Any, Signature, list[Any]], Any]] | None:
    """Hint the CPU to load array[index] (a tuple of ndim indices) into cache; no effect else.

    The engine is bound by memory latency: a world step evicts the population's records, and
    a visit's next node is known only at its end. Prefetching the next record while another
    controller runs overlaps those waits (see `step_kernel`).
    """
    if not (isinstance(array, types.Array) and isinstance(index, types.BaseTuple)):
        return None
    if len(index) != array.ndim:
        return None

    def codegen(
        context: BaseContext, builder: ir.IRBuilder, signature: Signature, args: list[Any]
    ) -> Any:
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


_prefetch = cast(
    Callable[[npt.NDArray[np.float32], tuple[int, ...]], None], intrinsic(_prefetch_typer)
)


@njit(cache=True, inline="always")
def _prefetch_record(words: npt.NDArray[np.float32], start: int, lines: int) -> None:
    """Prefetch the `lines` cache lines of a record that begins at float32 word `start`."""
    for i in range(lines):
        _prefetch(words, (start + i * (CACHE_LINE // 4),))


@njit(cache=True, inline="always")
def _ix(i: int) -> np.uint64:  # pragma: no cover - compiled
    """A flat index as unsigned: numba then skips its negative-index wraparound, two
    instructions on every one of a visit's ~25 loads and stores."""
    return np.uint64(i)


@njit(cache=True, inline="always")
def _egreedy(
    q: npt.NDArray[np.float32], start: int, k: int, eps: float, s: np.uint64, first: int
) -> tuple[np.uint64, int]:
    """ε-greedy over the k action values q[start : start + k]: (new stream state, chosen index).

    Draw u; if u < ε pick uniformly among all actions, else uniformly among the maxima (one
    more draw only when there is a tie), or, when `first` is non-zero, the first maximum (no
    draw: `GnpConfig.tie_break` "first"). Reads by flat index rather than through a slice: a
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
    if ties > 1 and not first:
        s, v = next_uniform(s)
        pick = min(int(v * ties), ties - 1)
    for a in range(k):
        if q[_ix(start + a)] == best:
            if pick == 0:
                return s, a
            pick -= 1
    return s, k - 1  # unreachable


# Positions in the `run` tuple the kernel hands its helpers.
_METHOD: Final = 0
_N_NODES: Final = 3
_WORDS32: Final = 7
_LAYOUT: Final = 10
_WALK: Final = 11
_COUNT: Final = 19

Run: TypeAlias = tuple[
    int,  # method
    bool,  # fuzzy
    float,  # gamma
    int,  # n_nodes
    int,  # n_judgment
    int,  # n_sub
    int,  # n_conn
    npt.NDArray[np.float32],  # words32
    npt.NDArray[np.int16],  # words16
    npt.NDArray[np.int8],  # words8
    Layout,
    Walks,
    Floats,  # wheels
    Streams,
    Floats,  # obs
    Floats,  # reward
    Floats,  # rates
    bool,  # learn
    Traces,  # visits
    Traces,  # count
]
"""Everything a visit reads, in one tuple (`walk_kernel` builds it)."""


@njit(cache=True, inline="always")
def read_observed(
    obs: Floats, _source: object, i: np.uint64, j: np.uint64
) -> float:  # pragma: no cover - compiled
    """What controller i sees of sensor j: `obs[i, j]` (`step_kernel`'s reader; a caller of
    `walk_kernel` may draw each reading when a judgment node first reads it)."""
    return obs[i, j]


@njit(cache=True, inline="always")
def judged_bin(x: float, lo: float, hi: float, k: int) -> int:  # pragma: no cover - compiled
    """Which of k equal bins of [lo, hi] holds x: the number of inner edges lo + j(hi − lo)/k,
    j = 1..k−1, at or below x, compared as k(x − lo) ≥ j(hi − lo). x ≤ lo (below every edge)
    is bin 0 and x ≥ hi bin k − 1; an edge belongs to the bin above it, as the crisp two-way
    judgment's midpoint does (k = 2 is that judgment, which the walk keeps as it was written)."""
    scaled = k * (x - lo)
    width = hi - lo
    found = 0
    for j in range(1, k):
        if scaled >= j * width:
            found = j
    return found


@njit(cache=True, inline="always")
def _visit(
    c: int, used: int, k: int, run: Run, read: Reader, source: Any
) -> tuple[int, int]:  # pragma: no cover - compiled
    """Controller c's next visit (after the start node, if it stands there): choose, learn,
    run, and move on. Its walk (`walk[c]`, `rng[c]`) is read from and written back to memory,
    so that controllers can take turns (see `step_kernel`). Returns (used, k): the step's
    time units spent and visits made so far, the start node included."""
    (
        method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, words32, words16, words8,
        layout, walk, wheels, rng, obs, reward, rates, learn, visits, _,
    ) = run  # fmt: skip
    i = _ix(c)  # controller c's rows, indexed without numba's negative-index check
    record_bytes = layout[0]
    r32, r16 = record_bytes // 4, record_bytes // 2
    ss, bs, cs_, beta, alpha, cn, cr, fn_, sp = layout[1:LAYOUT_BRANCHES]
    n_way = layout[LAYOUT_BRANCHES]  # branches k of a judgment sub node (its connections: k × U)
    trace = visits.shape[1] > 0
    rate_row = 0 if rates.shape[0] == 1 else c
    eps, lr = rates[rate_row, 0], rates[rate_row, 1]
    s = rng[i]
    first = method & _TIE_FIRST
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
    # that was a credit skip (reward 0, Eq. 5.3; `GnpConfig.skip_reward` "step": it too).
    earns = pc != 1 or method & _SKIP_EARNS
    pend_r = reward[i] if used == 0 and pn >= 0 and earns else 0.0
    record = c * n_nodes + node
    q, h, b = record * r32, record * r16, record * record_bytes
    s, p = _egreedy(words32, q + ss, n_sub, eps, s, first)
    cs = 0
    if method & _CS:
        s, cs = _egreedy(words32, q + cs_ + 2 * p, 2, eps, s, first)
    if learn and pn >= 0:
        last_q = (c * n_nodes + pn) * r32
        last_ss = last_q + ss + pp
        words32[_ix(last_ss)] += lr * (
            pend_r + gamma * words32[_ix(q + ss + p)] - words32[_ix(last_ss)]
        )
        if method & _CS:
            last_cs = last_q + cs_ + 2 * pp + pc
            target = pend_r + gamma * words32[_ix(q + cs_ + 2 * p + cs)]
            words32[_ix(last_cs)] += lr * (target - words32[_ix(last_cs)])
        if method & _BS and bn >= 0:
            last_bs = last_q + bs + (n_way * pp + pb) * n_conn + pu
            before_bs = (c * n_nodes + bn) * r32 + bs + (n_way * bp + bb) * n_conn + bu
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
            x = read(obs, source, i, _ix(fn))
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
            elif n_way == 2:
                branch = 0 if x >= (lo + hi) / 2.0 else 1
            else:
                branch = n_way - 1 - judged_bin(x, lo, hi, n_way)
        else:
            used += _PROCESSING_COST
            # Function 0 is the right wheel (P0) and 1 the left (P1); wheels are stored as
            # (left, right): output fn of k sits in column k − 1 − fn.
            k_out = wheels.shape[1]
            if method & _EMIT_FUNCTION:  # output 0: the centre of bin fn of k in −10..10
                wheels[i, _ix(k_out - 1)] = (fn + 0.5) * (2.0 * SPEED_MAX) / k_out - SPEED_MAX
            else:
                wheels[i, _ix(k_out - 1 - fn)] = float(words8[_ix(b + sp + p)])
            branch = 0
        u = 0
        if method & _BS:
            s, u = _egreedy(words32, q + bs + (n_way * p + branch) * n_conn, n_conn, eps, s, first)
        nxt = words16[_ix(h + cn + (n_way * p + branch) * n_conn + u)]
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
def _turn(
    c: int, used: int, k: int, waiting: int, run: Run, read: Reader, source: Any
) -> tuple[int, int, int, int]:  # pragma: no cover - compiled
    """Lane of controller c: one visit; once c's step is done the lane takes the next waiting
    controller. A lane whose controller number reaches N is idle. Returns (c, used, k,
    waiting) for the lane's next turn."""
    walk, count = run[_WALK], run[_COUNT]
    n_ctrl = walk.shape[0]
    if c >= n_ctrl:
        return c, used, k, waiting
    used, k = _visit(c, used, k, run, read, source)
    if used >= STEP_BUDGET:
        if count.shape[0] > 0:
            count[c] = k
        c, used, k, waiting = waiting, 0, 0, waiting + 1
        if c < n_ctrl:
            _prefetch_walk(c, run)
    return c, used, k, waiting


@njit(cache=True, inline="always")
def _prefetch_walk(c: int, run: Run) -> None:  # pragma: no cover - compiled
    """Prefetch what controller c's step starts with: its current node's record, and the Q
    values of its last two visits, which its first visit updates (the world step in between
    has evicted them). Q values lead a record, so their first line is prefetched, no more:
    every line the engine loads evicts one of the world's."""
    n_nodes, words32, layout, walk = run[_N_NODES], run[_WORDS32], run[_LAYOUT], run[_WALK]
    r32 = layout[0] // 4
    _prefetch_record(words32, (c * n_nodes + walk[c, 0]) * r32, layout[0] // CACHE_LINE)
    if walk[c, 1] >= 0:
        _prefetch_record(words32, (c * n_nodes + walk[c, 1]) * r32, 1)
    if walk[c, 6] >= 0 and run[_METHOD] & _BS:
        _prefetch_record(words32, (c * n_nodes + walk[c, 6]) * r32, 1)


@njit(cache=True, inline="always")
def records_part(records: Records, n_nodes: int, layout: Layout, lo: int, hi: int) -> Records:
    """The records of controllers lo..hi − 1 (a view): `step_kernel` runs them as a population
    of their own, with the same rows of the engine state."""
    size = n_nodes * layout[0]
    return records[lo * size : hi * size]


@njit(cache=True, **_WITHOUT_NRT)  # type: ignore[call-overload]
def step_kernel(
    method: int, fuzzy: bool, gamma: float, n_nodes: int, n_judgment: int, n_sub: int,
    n_conn: int, records: Records, layout: Layout, walk: Walks, wheels: Floats, rng: Streams,
    obs: Floats, reward: Floats, rates: Floats, learn: bool, visits: Traces, count: Traces,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """Run every controller's visits until its step's time units are spent.

    Two controllers take turns, a visit each: the record of a controller's next node is
    then fetched while the other one runs, instead of stalling the walk (the engine is bound by
    the latency of these loads, not by arithmetic). Controllers never share data, so the
    turns change nothing in what each one does.
    """
    walk_kernel(
        method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, records, layout, walk, wheels,
        rng, obs, reward, rates, learn, visits, count, read_observed, obs,
    )  # fmt: skip


@njit(cache=True, inline="always")
def walk_kernel(
    method: int, fuzzy: bool, gamma: float, n_nodes: int, n_judgment: int, n_sub: int,
    n_conn: int, records: Records, layout: Layout, walk: Walks, wheels: Floats, rng: Streams,
    obs: Floats, reward: Floats, rates: Floats, learn: bool, visits: Traces, count: Traces,
    read: Reader, source: Any,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """`step_kernel`'s body, inlined into its caller, whose judgment nodes read sensor j of
    controller i as `read(obs, source, i, j)`: a compiled caller may pass a numba function
    that fills `obs` on demand (pass it by name in the call: inlined, the call is static and
    the caller stays cacheable)."""
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
        a, used_a, k_a, waiting = _turn(a, used_a, k_a, waiting, run, read, source)
        b, used_b, k_b, waiting = _turn(b, used_b, k_b, waiting, run, read, source)
