"""GNP's half of the compiled loop: k steps of GNP controllers in an analytic world, one call.

`steps` runs `app.loop.fused.world_steps` (the world's half) around GNP's walk
(`gnp.kernel.walk_kernel`) on the world's, the population's and the engine state's own arrays:
the same kernels as `Batch.step` staged, so the same bits. `GnpControllers.fused` offers it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

import gnp
import sim
from app.loop import fused
from app.loop.fused import Floats, LazySource, Watched, watch_buffers, watched, world_steps
from gnp import engine, kernel
from gnp.engine import (
    TRACE_DTYPE,
    VISIT_FIELDS,
    KernelArguments,
    check_population,
    kernel_arguments,
    method_code,
)
from gnp.kernel import Layout, Records, Streams, Traces, Walks, records_part, walk_kernel
from sim import analytic, drive, khepera, loop, noise, rays, reward, sensors
from sim.kernel_cache import drop_stale_cache, source_fingerprint
from sim.loop import WorldArrays


def steps(
    world: sim.World,
    cfg: gnp.GnpConfig,
    population: gnp.Population,
    state: gnp.EngineState,
    reward: np.ndarray,
    epsilon: np.ndarray,
    alpha: np.ndarray,
    *,
    learn: bool,
    judge_observed: bool,
    term_sums: np.ndarray,
    watch: bool = False,
) -> tuple[np.ndarray, np.ndarray, Watched | None]:
    """Advance the batch by len(epsilon) steps in one compiled call (see `Batch.step`).

    Args:
        world: an analytic world no fault fires in during these steps.
        cfg, population, state: the GNP controllers, updated in place.
        reward: (N,) reward of the step before, fed to the first step's controllers.
        epsilon, alpha: (k,) ε and α of each step, in [0, 1].
        learn: online Sarsa on.
        judge_observed: C of the reward judged from what the controllers see after the step
            (`c_from` "observed"), else from the true readings.
        term_sums: (N, len(sim.TERM_NAMES)) each reward term summed, added to in place.
        watch: also return what each step did (`Watched`).

    Returns:
        The last step's reward (N,), each step's reward (k, N), and with `watch` what each
        step did, else None.
    """
    epsilon = np.ascontiguousarray(epsilon, dtype=np.float64)
    alpha = np.ascontiguousarray(alpha, dtype=np.float64)
    for name, values in (("epsilon", epsilon), ("alpha", alpha)):
        if values.size and not (values.min() >= 0.0 and values.max() <= 1.0):
            raise gnp.GnpError(f"{name} must lie in [0, 1]")
    check_population(cfg, population, state)
    k, n = len(epsilon), world.n
    last = np.array(reward, dtype=np.float64)  # contiguous, and the caller's stays unchanged
    each = np.empty((k, n))
    kept = k if watch else 0
    buffers = watch_buffers(kept, n)
    visits = np.full((max(kept, 1), len(VISIT_FIELDS), n if watch else 0,
                      cfg.max_visits_per_step if watch else 0), -1, TRACE_DTYPE)  # fmt: skip
    count = np.zeros((max(kept, 1), n if watch else 0), TRACE_DTYPE)
    brain = kernel_arguments(method_code(cfg), cfg, population, state)
    _run(world.arrays(), brain, epsilon, alpha, learn, judge_observed, world.t, last, each,
         term_sums, np.empty((n, len(sim.TERM_NAMES))), fused.ROBOTS_PER_BLOCK, buffers.poses,
         buffers.observations, buffers.commands, buffers.readings, buffers.term_tables,
         visits, count)  # fmt: skip
    world.stepped(k)
    if not watch:
        return last, each, None
    return last, each, watched(buffers, lambda s: engine.step_trace(visits[s], count[s]))


@njit(cache=True)
def _run(
    world: WorldArrays, brain: KernelArguments, epsilon: Floats, alpha: Floats, learn: bool,
    judge_observed: bool, t0: int, reward: Floats, each: Floats, term_sums: Floats,
    table: Floats, block: int, poses_out: Floats, seen_out: Floats, commands_out: Floats,
    readings_out: Floats, table_out: Floats, visits_out: Traces, count_out: Traces,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """`app.loop.fused.world_steps` with GNP's controllers (`brain`: `kernel_arguments`), the
    trace kept in `visits_out`, `count_out` when they have robots."""
    world_steps(
        world, brain, _part, _act_part, epsilon, alpha, learn, judge_observed, t0, reward, each,
        term_sums, table, block, poses_out, seen_out, commands_out, readings_out, table_out,
        (visits_out, count_out),
    )  # fmt: skip


@njit(inline="always")
def _part(
    brain: KernelArguments, lo: int, hi: int
) -> tuple[KernelArguments, Floats]:  # pragma: no cover - compiled
    """Controllers lo..hi − 1 of `brain` (views) and their wheels."""
    method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, records, layout, walk, wheels, rng = (
        brain
    )
    part_wheels = wheels[lo:hi]
    part = (method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn,
            records_part(records, n_nodes, layout, lo, hi), layout, walk[lo:hi], part_wheels,
            rng[lo:hi])  # fmt: skip
    return part, part_wheels


@njit(inline="always")
def _act_part(
    part: KernelArguments, obs: Floats, reward: Floats, rates: Floats, learn: bool,
    trace_out: tuple[Traces, Traces], row: int, lo: int, hi: int, source: LazySource,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """One step of `_part`'s controllers, their trace in row `row` of `trace_out`."""
    method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, records, layout, walk, wheels, rng = (
        part
    )
    visits_out, count_out = trace_out
    _act(
        method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, records, layout, walk, wheels,
        rng, obs, reward, rates, learn, visits_out[row][:, lo:hi], count_out[row][lo:hi], source,
    )  # fmt: skip


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]
def _act(
    method: int, fuzzy: bool, gamma: float, n_nodes: int, n_judgment: int, n_sub: int,
    n_conn: int, records: Records, layout: Layout, walk: Walks, wheels: Floats, rng: Streams,
    obs: Floats, reward: Floats, rates: Floats, learn: bool, visits: Traces, count: Traces,
    source: LazySource,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """`gnp.kernel.step_kernel` whose judgment nodes read through `sim.loop.read_lazily`
    (compiled without numba's reference counting, as `step_kernel` is)."""
    walk_kernel(
        method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, records, layout, walk, wheels,
        rng, obs, reward, rates, learn, visits, count, loop.read_lazily, source,
    )  # fmt: skip


#: What this module's cached kernels were compiled against: the world's and the brain's kernel
#: modules it calls, the loop's world half inlined among them (sim.kernel_cache).
COMPILED_AGAINST = source_fingerprint(
    fused, loop, analytic, drive, khepera, noise, rays, reward, sensors, kernel, engine
)


@njit(cache=True)
def _frozen_sources() -> np.ndarray:
    """``COMPILED_AGAINST`` as numba froze it into this module's cache."""
    return COMPILED_AGAINST.copy()


drop_stale_cache(globals(), _frozen_sources, COMPILED_AGAINST)
