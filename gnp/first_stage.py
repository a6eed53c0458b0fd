"""The live ablation: a step with the method's second stage off, on the unchanged kernel.

See `gnp.step(..., second_stage=False)` and docs/decisions.md ("Live ablation").
"""

from __future__ import annotations

import numpy as np

from gnp.config import GnpConfig
from gnp.engine import TRACE_DTYPE, EngineState, StepResult, StepTrace, run_kernel
from gnp.methods import FIRST_STAGE_ONLY
from gnp.population import Population


def first_stage_only(
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
    visits = np.full((5, n, cfg.max_visits_per_step), -1, TRACE_DTYPE)
    count = np.zeros(n, TRACE_DTYPE)
    bs = cfg.traits.branch_selection
    conn = pop.conn  # a view into the records the kernel reads
    if bs:
        greedy = np.argmax(pop.q_bs, axis=-1)  # (N, V, m, 2): the first maximum
        greedy[:, 0] = 0  # the start node follows connection 0
        first = conn[..., 0].copy()
        conn[..., 0] = np.take_along_axis(conn, greedy[..., None], axis=-1)[..., 0]
    try:
        run_kernel(FIRST_STAGE_ONLY, cfg, pop, state, obs, rew, rates, learn, visits, count)
    finally:
        if bs:
            conn[..., 0] = first
    node, sub, branch, u, skipped = visits
    if bs:
        c, k = np.nonzero(node > 0)
        u[c, k] = greedy[c, node[c, k], sub[c, k], branch[c, k]]
        # The last visit is always this step's; the one before it when the step made two.
        walk = state.walk
        rows = np.arange(n)
        last = walk[:, 1] > 0
        walk[last, 4] = greedy[rows[last], walk[last, 1], walk[last, 2], walk[last, 3]]
        before = (walk[:, 6] > 0) & (np.count_nonzero(node > 0, axis=1) >= 2)
        walk[before, 9] = greedy[rows[before], walk[before, 6], walk[before, 7], walk[before, 8]]
    steps = StepTrace(node, sub, branch, u, skipped, count) if trace else None
    return state.wheels.copy(), steps
