"""The lab's loop: observe → controller → world → readings → reward, for a batch of robots.

Every phase steps robots through this one loop: training lives, the implementation phase, the
dashboard's live robots and the experiments' conditions. A `Batch` pairs a `sim.World` of N robots
with N controllers (`Controllers`, a brain family's, see `app.brains`); `rollout` advances it T
steps with ε/α given per step (to the controllers that learn online), optionally recording the
first robots' lives.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, get_args, runtime_checkable

import numpy as np

import sim
from app.loop import fused
from app.loop.recording import TrajectoryRecorder
from app.settings.config import CFrom


@dataclass(frozen=True)
class StepRecord:
    """What one step of a batch did; arrays have the batch's leading axis N."""

    observations: np.ndarray  # (N, 8) what the controllers saw (noise, faults)
    commands: np.ndarray  # (N, 2) left, right wheel commands
    readings: np.ndarray  # (N, 8) true readings after the step
    term_table: np.ndarray  # (N, len(sim.TERM_NAMES)) reward terms, columns as TERM_NAMES
    trace: Any  # what each controller did (its family's trace), when traced

    @property
    def terms(self) -> dict[str, np.ndarray]:
        """Reward term name -> (N,)."""
        return {name: self.term_table[:, i] for i, name in enumerate(sim.TERM_NAMES)}

    @property
    def reward(self) -> np.ndarray:
        """(N,) reward of the step (Eq. 2.7)."""
        return self.term_table[:, 0]


class Controllers(Protocol):
    """N controllers, one per robot of a batch: the one place a brain family plugs in.

    Optional: a `fused` attribute (`app.loop.fused.FusedSteps`, or None), the controllers'
    steps compiled with the analytic world's; the loop takes them wherever it may (see
    `Batch.compiled`), else it calls `act` between the world's stages. Controllers that learn
    online are also an `OnlineLearner`.
    """

    @property
    def size(self) -> int: ...

    def act(
        self, observations: np.ndarray, reward: np.ndarray, *, trace: bool
    ) -> tuple[np.ndarray, Any]:
        """(N, 2) wheel commands (left, right) for (N, 8) observations, given the (N,) reward
        of the previous step; with the step's trace when `trace`, else None."""
        ...

    def reset_episode(self) -> None:
        """Start a new episode (what a controller keeps across episodes is its own choice)."""
        ...


@runtime_checkable
class OnlineLearner(Protocol):
    """Controllers that learn online (their family's `learns_online`): the loop gives them the
    rates of the steps to come (`Batch.set_rates`) whenever those change."""

    def set_rates(self, epsilon: float, alpha: float, learn: bool) -> None:
        """ε and α of the next steps; `learn`: online learning on."""
        ...


class Batch:
    """N robots in one world, each driven by its own controller (row i of the controllers).

    The reward of a step is fed to the controllers at the next one (Sarsa's r_t); a new episode
    resets it, with the controllers' walks, and keeps Q tables and random streams. Its C
    (Eq. 2.7) is judged from the readings after the step: the true ones (`c_from` "true"), or
    what the controllers see there ("observed": noise, then faults; the same draws they see at
    the next step).
    """

    def __init__(self, world: sim.World, controllers: Controllers, c_from: CFrom = "true") -> None:
        if controllers.size != world.n:
            raise ValueError(f"{controllers.size} controllers for {world.n} robots")
        if c_from not in get_args(CFrom):
            raise ValueError(f"c_from must be one of {get_args(CFrom)}, got {c_from!r}")
        self.world = world
        self.controllers = controllers
        self.reward = np.zeros(world.n)
        self.c_from = c_from
        self._learner = controllers if isinstance(controllers, OnlineLearner) else None
        self._rates: tuple[float, float, bool] | None = None

    @property
    def size(self) -> int:
        return self.world.n

    def new_episode(self, poses: np.ndarray) -> None:
        """Move every robot to `poses` (N, 3) and restart its controller at the start node."""
        self.world.place(poses)
        self.controllers.reset_episode()
        self.reward = np.zeros(self.size)

    def set_rates(self, epsilon: float, alpha: float, learn: bool) -> None:
        """Online learning's ε, α and switch for the next staged steps: given to controllers
        that learn online when they change (others have none)."""
        rates = (epsilon, alpha, learn)
        if self._learner is not None and rates != self._rates:
            self._learner.set_rates(*rates)
            self._rates = rates

    def compiled(self) -> bool:
        """Whether `step` and `rollout` may run this batch in compiled calls (`app.loop.fused`):
        analytic physics, controllers that offer them and whose compiled steps fit their
        staged ones as they are set (GNP's second stage)."""
        steps = fused.fused_steps(self.controllers)
        return self.world.physics == "analytic" and steps is not None and steps.fits()

    def step(
        self, epsilon: float, alpha: float, *, learn: bool = True, trace: bool = False
    ) -> StepRecord:
        """One control step of every robot; ε, α and `learn` reach controllers that learn
        online only."""
        if self.compiled() and compiled_steps(self.world, 0, 1, 0) == 1:
            _, watched = self.run_compiled(np.array([epsilon]), np.array([alpha]), learn, None)
            assert watched is not None
            return StepRecord(
                watched.observations[0],
                watched.commands[0],
                watched.readings[0],
                watched.term_tables[0],
                watched.trace(0) if trace else None,
            )
        return self.staged_step(epsilon, alpha, learn=learn, trace=trace)

    def staged_step(
        self, epsilon: float, alpha: float, *, learn: bool = True, trace: bool = False
    ) -> StepRecord:
        """`step` one stage at a time from Python, for any controllers and physics (the
        compiled path's oracle in the tests)."""
        self.set_rates(epsilon, alpha, learn)
        seen = self.world.observe()
        commands, step_trace = self.controllers.act(seen, self.reward, trace=trace)
        self.world.step(commands)
        readings = self.world.sense()
        judged = readings if self.c_from == "true" else self.world.observe()
        table = sim.reward_table(judged, commands)
        self.reward = table[:, 0]
        return StepRecord(seen, commands, readings, table, step_trace)

    def run_compiled(
        self, epsilon: np.ndarray, alpha: np.ndarray, learn: bool, term_sums: np.ndarray | None
    ) -> tuple[np.ndarray, fused.Watched | None]:
        """len(epsilon) steps in one compiled call (see `compiled`; no fault may fire in
        them): each step's reward (k, N), and what each step did unless `term_sums` (N, 4) is
        given to add the reward terms to."""
        steps = fused.fused_steps(self.controllers)
        assert steps is not None, "compiled steps of controllers that offer none"
        watch = term_sums is None
        if term_sums is None:
            term_sums = np.zeros((self.size, len(sim.TERM_NAMES)))
        self.reward, each, watched = steps.steps(
            self.world,
            self.reward,
            epsilon,
            alpha,
            learn=learn,
            judge_observed=self.c_from == "observed",
            term_sums=term_sums,
            watch=watch,
        )
        return each, watched


@dataclass(frozen=True)
class Rollout:
    """What T steps of a batch earned."""

    term_sums: np.ndarray  # (N, len(sim.TERM_NAMES)) each reward term summed over the steps
    step_reward_sums: np.ndarray  # (T,) reward of each step summed over the batch


def per_step(value: float | np.ndarray, steps: int) -> np.ndarray:
    """ε or α of each of `steps` steps, from a constant or an array of one value per step."""
    return np.broadcast_to(np.asarray(value, dtype=np.float64), (steps,))


def rollout(
    batch: Batch,
    steps: int,
    epsilon: float | np.ndarray,
    alpha: float | np.ndarray,
    *,
    learn: bool = True,
    recorder: TrajectoryRecorder | None = None,
    episode_starts: np.ndarray | None = None,
    redraw_every: int = 0,
) -> Rollout:
    """Advance `batch` by `steps` control steps.

    Args:
        batch: the robots and controllers; their state carries on from call to call.
        steps: how many steps.
        epsilon, alpha: ε and α, constant or (steps,) per step (controllers that learn online
            take them, see `OnlineLearner`).
        learn: online learning on (GNP: Sarsa changes its Q tables in place).
        recorder: records the first `recorder.k` robots' steps (appended to what it holds).
        episode_starts: (N, S) start poses of each robot's episodes, with `redraw_every` > 0:
            every `redraw_every` steps the robots move to their next start pose.
        redraw_every: episode length in steps (0: one episode).
    """
    eps, alp = per_step(epsilon, steps), per_step(alpha, steps)
    sums = np.zeros((batch.size, len(sim.TERM_NAMES)))
    step_sums = np.zeros(steps)
    poses = batch.world.arena.start_poses
    compiled = batch.compiled()
    t = 0
    while t < steps:
        if redraw_every > 0 and t > 0 and t % redraw_every == 0:
            assert episode_starts is not None
            batch.new_episode(poses[episode_starts[:, t // redraw_every]])
        run = compiled_steps(batch.world, t, steps, redraw_every) if compiled else 0
        if run > 0 and recorder is None:  # `run` steps in one compiled call (see app.loop.fused)
            each, _ = batch.run_compiled(eps[t : t + run], alp[t : t + run], learn, sums)
            step_sums[t : t + run] = each.sum(axis=1)
            t += run
            continue
        if run > 0:  # watched: the recorder takes each step's arrays afterwards
            run = min(run, WATCHED_STEPS_PER_CALL)
            each, watched = batch.run_compiled(eps[t : t + run], alp[t : t + run], learn, None)
            assert watched is not None and recorder is not None
            for s in range(run):
                sums += watched.term_tables[s]
                recorder.record(
                    watched.poses[s],
                    watched.readings[s],
                    watched.observations[s],
                    watched.commands[s],
                    watched.term_tables[s],
                    watched.trace(s),
                )
            step_sums[t : t + run] = each.sum(axis=1)
            t += run
            continue
        record = batch.step(float(eps[t]), float(alp[t]), learn=learn, trace=recorder is not None)
        sums += record.term_table
        step_sums[t] = record.reward.sum()
        if recorder is not None:
            assert record.trace is not None
            recorder.record(
                batch.world.poses,
                record.readings,
                record.observations,
                record.commands,
                record.term_table,
                record.trace,
            )
        t += 1
    return Rollout(term_sums=sums, step_reward_sums=step_sums)


WATCHED_STEPS_PER_CALL = 256
"""Most steps of a watched compiled call: what it keeps of each step grows with them."""


def compiled_steps(world: sim.World, t: int, steps: int, redraw_every: int) -> int:
    """How many steps from step `t` of a rollout the compiled loop may take in one call: up
    to the next new episode or the end, and not the step in which a fault fires (0 if that
    is the first)."""
    end = steps if redraw_every <= 0 else min(steps, (t // redraw_every + 1) * redraw_every)
    fires = [s - world.t for s in world.fault_steps if world.t < s <= world.t + end - t]
    return min([end - t, *(f - 1 for f in fires)])
