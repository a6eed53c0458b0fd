"""The loop compiled: k steps of a batch in an analytic world, one call, the world's half here.

A family whose controllers are numba functions may offer them fused with the world
(`Controllers`' optional `fused`, a `FusedSteps`): k steps of the batch in one compiled call,
every stage of `app.loop.rollout.Batch.step` (`sim.loop` for the world, the family's kernel for
the controllers) on the world's and the controllers' own arrays in `Batch.step`'s order, so the
same bits (GNP's: `app.brains.gnp_fused`; tests/app/loop/test_fused.py compares them step by step).
`world_steps` is the world's half, inlined into the family's compiled call. Watched steps (the
trajectory recorder, the dashboard) also keep what each step saw, commanded, read and earned,
and the controllers' trace. A step in which a scheduled fault fires goes through the stages one
call at a time (`Batch.step`'s other path): both paths share all state, so they interleave
freely.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, TypeAlias

import numpy as np
import numpy.typing as npt
from numba import njit

import sim
from sim import loop
from sim.khepera import N_SENSORS
from sim.loop import WorldArrays

ROBOTS_PER_BLOCK = 64
"""Robots that live the k steps together before the next ones start. Robots share no data, so
any split gives the same bits. Measured (thesis-ch3, GNP, σ = 50, 300 and 500 robots): 64 is as
fast as the whole batch at 300 robots and 8% faster at 500; blocks of 16 or fewer lose up to 30%
(every stage's call and scratch arrays, and GNP's two lanes have fewer controllers to
overlap)."""


@dataclass(frozen=True)
class Watched:
    """What k watched steps did; arrays (k, N, ...), as `app.loop.rollout.StepRecord`'s per step."""

    poses: np.ndarray  # (k, N, 3) after each step, headings in [-π, π)
    observations: np.ndarray  # (k, N, 8)
    commands: np.ndarray  # (k, N, 2)
    readings: np.ndarray  # (k, N, 8) true readings after each step
    term_tables: np.ndarray  # (k, N, len(sim.TERM_NAMES))
    traces: Callable[[int], Any]  # step s -> the controllers' trace of it (their family's)

    def trace(self, s: int) -> Any:
        """The controllers' trace of step s (views)."""
        return self.traces(s)


def watch_buffers(k: int, n: int) -> Watched:
    """Empty arrays for k watched steps of n robots, for a compiled call to fill (no trace yet)."""
    return Watched(
        poses=np.empty((k, n, 3)),
        observations=np.empty((k, n, sim.N_SENSORS)),
        commands=np.empty((k, n, 2)),
        readings=np.empty((k, n, sim.N_SENSORS)),
        term_tables=np.empty((k, n, len(sim.TERM_NAMES))),
        traces=lambda _s: None,
    )


def watched(filled: Watched, traces: Callable[[int], Any]) -> Watched:
    """`filled` after its compiled call: headings wrapped, with the controllers' traces."""
    f = filled
    return Watched(sim.world.wrapped(f.poses), f.observations, f.commands, f.readings,
                   f.term_tables, traces)  # fmt: skip


class FusedSteps(Protocol):
    """Controllers' compiled steps with an analytic world (see the module's docstring)."""

    def fits(self) -> bool:
        """Whether the compiled steps are the staged ones as the controllers are set now."""
        ...

    def steps(
        self,
        world: sim.World,
        reward: np.ndarray,
        epsilon: np.ndarray,
        alpha: np.ndarray,
        *,
        learn: bool,
        judge_observed: bool,
        term_sums: np.ndarray,
        watch: bool,
    ) -> tuple[np.ndarray, np.ndarray, Watched | None]:
        """Advance the batch by len(epsilon) steps in one compiled call, no fault firing in
        them: the last step's reward (N,), each step's (k, N), and with `watch` what each step
        did. `reward` (N,) is the step before's; `term_sums` (N, len(sim.TERM_NAMES)) is added
        to in place; `judge_observed`: C judged from what the controllers see after a step."""
        ...


Floats: TypeAlias = npt.NDArray[np.float64]

LazySource: TypeAlias = tuple[WorldArrays, int, npt.NDArray[np.bool_]]
"""What `act` hands `sim.loop.read_lazily` to draw a reading: (the robots' part of the world,
the step t, which (robot, sensor pair) are drawn)."""

PartOf: TypeAlias = Callable[[Any, int, int], tuple[Any, Floats]]
"""`world_steps`' `part_of(brain, lo, hi)`. The controllers are the family's own (Any: numba's
`Dispatcher` type keeps no type variable)."""

ActPart: TypeAlias = Callable[
    [Any, Floats, Floats, Floats, bool, Any, int, int, int, LazySource], None
]
"""`world_steps`' `act(part, observations, reward, rates, learn, trace_out, row, lo, hi,
source)`, the part and trace the family's own."""


def fused_steps(controllers: object) -> FusedSteps | None:
    """The controllers' compiled steps, if their family offers them."""
    fused: FusedSteps | None = getattr(controllers, "fused", None)
    return fused


@njit(inline="always")
def world_steps(
    world: WorldArrays, brain: Any, part_of: PartOf, act: ActPart, epsilon: Floats,
    alpha: Floats, learn: bool, judge_observed: bool, t0: int, reward: Floats, each: Floats,
    term_sums: Floats, table: Floats, block: int, poses_out: Floats, seen_out: Floats,
    commands_out: Floats, readings_out: Floats, table_out: Floats, trace_out: Any,
) -> None:  # fmt: skip  # pragma: no cover - compiled
    """k = len(epsilon) steps of `Batch.step`: observe, act (and learn), step, sense, judge;
    block by block of robots; each step's arrays kept in the `_out` arrays when they have k
    rows. Inlined into a family's compiled call, which passes its own functions by name (the
    calls stay static, the caller cacheable):

    - `part_of(brain, lo, hi)`: (the controllers lo..hi − 1, their (hi − lo, 2) wheel commands),
      views of `brain`'s arrays;
    - `act(part, observations, reward, rates, learn, trace_out, row, lo, hi, source)`: one step
      of those controllers, (ε, α) in `rates` (1, 2), the commands in their wheels, the trace
      in row `row` of `trace_out` (when watched); judgment nodes read sensor j of controller i
      through `sim.loop.read_lazily(observations, source, i, j)`.
    """
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
        minds, part_wheels = part_of(brain, lo, hi)
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
            act(minds, part.observed, part_reward, rates, learn, trace_out, row, lo, hi,
                (part, t0 + s, part_drawn))  # fmt: skip
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
