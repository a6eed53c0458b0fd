"""GNP's compiled loop: k steps of a batch of GNP controllers in an analytic world, one call.

With GNP controllers and analytic physics, every stage of `app.loop.rollout.Batch.step` is a numba
function (`sim.loop` for the world, `gnp.kernel.walk_kernel` for the controllers); `steps` runs k
of them in one compiled call on the world's and the controllers' own arrays, in `Batch.step`'s
order: the same kernels on the same arrays, so the same bits. What the loop asks of it, and
when, is `app.loop.fused`'s (`GnpControllers.fused` offers it).
"""

from __future__ import annotations

import numpy as np
from numba import njit

import gnp
import sim
from app.loop.fused import Watched, watch_buffers, watched
from gnp import engine, kernel
from gnp.engine import TRACE_DTYPE, VISIT_FIELDS, check_population, kernel_arguments, method_code
from gnp.kernel import records_part, walk_kernel
from sim import analytic, drive, khepera, loop, noise, rays, reward, sensors
from sim.kernel_cache import drop_stale_cache, source_fingerprint
from sim.khepera import N_SENSORS

ROBOTS_PER_BLOCK = 64
"""Robots that live the k steps together before the next ones start. Robots share no data, so
any split gives the same bits. Measured (thesis-ch3, σ = 50, 300 and 500 robots): 64 is as fast
as the whole batch at 300 robots and 8% faster at 500; blocks of 16 or fewer lose up to 30%
(every stage's call and scratch arrays, and the engine's two lanes have fewer controllers to
overlap)."""


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
         term_sums, np.empty((n, len(sim.TERM_NAMES))), ROBOTS_PER_BLOCK, buffers.poses,
         buffers.observations, buffers.commands, buffers.readings, buffers.term_tables,
         visits, count)  # fmt: skip
    world.stepped(k)
    if not watch:
        return last, each, None
    return last, each, watched(buffers, lambda s: engine.step_trace(visits[s], count[s]))


@njit(cache=True)
def _run(
    world, brain, epsilon, alpha, learn, judge_observed, t0, reward, each, term_sums, table, block,
    poses_out, seen_out, commands_out, readings_out, table_out, visits_out, count_out,
):  # fmt: skip  # pragma: no cover - compiled
    """k = len(epsilon) steps of `Batch.step`: observe, act (and learn), step, sense, judge;
    block by block of robots; each step's arrays kept in the `_out` arrays when they have k
    rows (the trace when `visits_out` has robots)."""
    method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, records, layout, walk, wheels, rng = (
        brain
    )
    rates = np.empty((1, 2))  # one (ε, α) for every controller, as `gnp.step` passes them
    n = reward.shape[0]
    watch = seen_out.shape[0] > 0
    # Unwatched and judged from the true readings, a step's observations are only what its
    # judgment nodes read: each pair of sensors is drawn when first read (`loop.read_lazily`).
    lazy = not watch and not judge_observed
    drawn = np.zeros((n, N_SENSORS // 2), np.bool_)
    for lo in range(0, n, block):
        hi = min(n, lo + block)
        part = loop.part(world, lo, hi)
        part_records = records_part(records, n_nodes, layout, lo, hi)
        part_walk, part_wheels, part_rng = walk[lo:hi], wheels[lo:hi], rng[lo:hi]
        part_reward, part_table, part_drawn = reward[lo:hi], table[lo:hi], drawn[lo:hi]
        for s in range(epsilon.shape[0]):
            if lazy:
                part_drawn[:] = False
            else:
                if s == 0 or not judge_observed:  # else the last step's judge observed step s
                    loop.observe(part, t0 + s)
                part_drawn[:] = True
            rates[0, 0] = epsilon[s]
            rates[0, 1] = alpha[s]
            row = s if watch else 0
            _act(
                method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, part_records, layout,
                part_walk, part_wheels, part_rng, part.observed, part_reward, rates, learn,
                visits_out[row][:, lo:hi], count_out[row][lo:hi], (part, t0 + s, part_drawn),
            )  # fmt: skip
            if watch:
                seen_out[s, lo:hi] = part.observed
                commands_out[s, lo:hi] = part_wheels
            loop.step(part, part_wheels)
            loop.sense(part)
            if judge_observed:
                loop.observe(part, t0 + s + 1)
                loop.judge(part.observed, part_wheels, part_table)
            else:
                loop.judge(part.readings, part_wheels, part_table)
            if watch:
                poses_out[s, lo:hi] = part.poses
                readings_out[s, lo:hi] = part.readings
                table_out[s, lo:hi] = part_table
            for i in range(hi - lo):
                part_reward[i] = part_table[i, 0]
                each[s, lo + i] = part_table[i, 0]
                for j in range(part_table.shape[1]):
                    term_sums[lo + i, j] += part_table[i, j]


@njit(cache=True, _nrt=False)  # type: ignore[call-overload]
def _act(
    method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, records, layout, walk, wheels, rng,
    obs, reward, rates, learn, visits, count, source,
):  # fmt: skip  # pragma: no cover - compiled
    """`gnp.kernel.step_kernel` whose judgment nodes read through `sim.loop.read_lazily`
    (compiled without numba's reference counting, as `step_kernel` is)."""
    walk_kernel(
        method, fuzzy, gamma, n_nodes, n_judgment, n_sub, n_conn, records, layout, walk, wheels,
        rng, obs, reward, rates, learn, visits, count, loop.read_lazily, source,
    )  # fmt: skip


#: What this module's cached kernels were compiled against: the world's and the brain's kernel
#: modules it calls (sim.kernel_cache).
COMPILED_AGAINST = source_fingerprint(
    loop, analytic, drive, khepera, noise, rays, reward, sensors, kernel, engine
)


@njit(cache=True)
def _frozen_sources() -> np.ndarray:
    """``COMPILED_AGAINST`` as numba froze it into this module's cache."""
    return COMPILED_AGAINST.copy()


drop_stale_cache(globals(), _frozen_sources, COMPILED_AGAINST)
