"""The loop's compiled path, as the loop sees it: controllers that step with the world in one call.

A family whose controllers and the analytic world's stages are all numba functions may offer
them fused (`Controllers`' optional `fused`, a `FusedSteps`): k steps of the batch in one
compiled call, the same kernels on the same arrays in `Batch.step`'s order, so the same bits
(GNP's: `app.brains.gnp_fused`; tests/app/test_fused.py compares them step by step). Watched
steps (the trajectory recorder, the dashboard) also keep what each step saw, commanded, read and
earned, and the controllers' trace. A step in which a scheduled fault fires goes through the
stages one call at a time (`Batch.step`'s other path): both paths share all state, so they
interleave freely. This module holds the world's side only; it compiles nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

import sim


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
        traces=lambda s: None,
    )


def watched(filled: Watched, traces: Callable[[int], Any]) -> Watched:
    """`filled` after its compiled call: headings wrapped, with the controllers' traces."""
    return replace(filled, poses=sim.world.wrapped(filled.poses), traces=traces)


class FusedSteps(Protocol):
    """Controllers' compiled steps with an analytic world (see the module's docstring)."""

    def fits(self, second_stage: bool) -> bool:
        """Whether the compiled steps are the staged ones with `second_stage` as asked."""
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


def fused_steps(controllers: object) -> FusedSteps | None:
    """The controllers' compiled steps, if their family offers them."""
    fused: FusedSteps | None = getattr(controllers, "fused", None)
    return fused
