"""The implementation phase: a trained individual adapts online in an unseen arena.

The individual (default: the final elite, with the Q tables it learned) is cloned into
10 start poses × repeats trials. Each lives `steps` steps in the implementation arena with
online Sarsa and no evolution; sensors break at the fault step t' (a fixed set, or k drawn per
trial). ε/α are the fixed values before t' and, with the "changing" schedule, follow Eq. 4.3-4.4
from t' on. Trial i starts at start pose i mod 10 and draws from streams keyed by (seed, trial i)
only, so a trial's life does not depend on its batch. Trials run in worlds of a fixed split
(`trial_worlds`), which worker processes share out: results are identical for any worker count.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

import sim
from app.brains.contract import BrainFamily
from app.brains.learning import learning as learning_of
from app.brains.registry import family_of
from app.loop.recording import Trajectory, TrajectoryRecorder, life_bytes
from app.loop.rollout import Batch, rollout
from app.loop.seeds import broken_sensor_draws, trial_seeds
from app.settings.arenas import arena_of, new_world
from app.settings.config import CFrom, ImplementationSettings
from app.store import (
    Implementation,
    RunFileError,
    RunReader,
    add_implementation,
)
from app.system.memory import check_memory
from app.system.workers import share_out

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,63}$")
TRIALS_PER_WORLD = 500
"""Trials simulated in one world: the unit of work a worker process takes."""
_PROGRESS_EVERY = 50  # steps between progress reports

StepProgress = Callable[[int, int], None]  # (trial-steps done, total trial-steps)


class ImplementationError(ValueError):
    """The implementation phase cannot run as asked (bad name, unfinished run, ...)."""


def check_name(name: str) -> str:
    """An implementation name: letters, digits, `_`, `.`, `-`, at most 64 characters."""
    if not _NAME.match(name):
        raise ImplementationError(
            f"implementation name {name!r} must be 1-64 letters, digits, '_', '.' or '-', "
            "starting with a letter or digit"
        )
    return name


def default_name(settings: ImplementationSettings) -> str:
    """A readable name such as `break-2-3-dead-fixed` or `no-fault-fixed`."""
    if settings.broken_sensors:
        sensors = "-".join(str(s) for s in settings.broken_sensors)
        fault = f"break-{sensors}-{settings.fault_mode}"
    elif settings.break_count:
        fault = f"break-{settings.break_count}-random-{settings.fault_mode}"
    else:
        fault = "no-fault"
    noise = f"-noise{settings.noise_sigma:g}" if settings.noise_sigma else ""
    return f"{fault}-{settings.schedule}{noise}"


def fault_text(sensors: Sequence[int] | int, mode: str, step: int | None) -> str:
    """How the lab words a fault, on the command line, in a replay and on the page:
    `sensors 2,3 broken (dead) since step 500`; k random sensors (an int): `2 random
    sensor(s) per trial broken (dead) since step 500`; no step: no `since`."""
    if isinstance(sensors, int):
        which = f"{sensors} random sensor(s) per trial"
    else:
        which = "sensors " + ",".join(str(s) for s in sensors)
    since = f" since step {step}" if step is not None else ""
    return f"{which} broken ({mode}){since}"


def describe_fault(settings: ImplementationSettings) -> str:
    """What breaks in an implementation: a fixed set, k random sensors per trial, or nothing."""
    if not settings.has_fault:
        return "no fault"
    sensors = settings.broken_sensors or settings.break_count
    return fault_text(sensors, settings.fault_mode, settings.fault_step)


def epsilon_alpha_per_step(settings: ImplementationSettings) -> tuple[np.ndarray, np.ndarray]:
    """(T,) ε and (T,) α of every step."""
    learning = learning_of(settings)
    rates = np.array([learning.rates(t, settings.fault_step) for t in range(settings.steps)])
    return rates[:, 0], rates[:, 1]


def faults(settings: ImplementationSettings, seed: int, trials: np.ndarray) -> list[sim.Fault]:
    """The scheduled faults of `trials` (indices into the phase's trials, one per robot)."""
    if settings.broken_sensors:
        return [sim.Fault(settings.fault_step, settings.broken_sensors, settings.fault_mode)]
    if not settings.break_count:
        return []
    draws = broken_sensor_draws(seed, trials, settings.break_count, sim.N_SENSORS)
    sets, robots = np.unique(draws, axis=0, return_inverse=True)
    return [
        sim.Fault(
            settings.fault_step,
            tuple(int(s) for s in sensors),
            settings.fault_mode,
            robots=tuple(int(r) for r in np.flatnonzero(robots.ravel() == i)),
        )
        for i, sensors in enumerate(sets)
    ]


def trial_count(settings: ImplementationSettings) -> int:
    """The trials of an implementation phase: its arena's start poses × repeats."""
    return len(arena_of(settings.arena).start_poses) * settings.repeats


def trial_worlds(trials: int, recorded: int) -> list[slice]:
    """The fixed split of the trials into worlds: the recorded ones (traced) on their own, the
    rest in worlds of at most TRIALS_PER_WORLD. It depends on the settings only."""
    parts = [slice(0, recorded)] if recorded else []
    rest = trials - recorded
    count = math.ceil(rest / TRIALS_PER_WORLD)
    bounds = recorded + np.linspace(0, rest, count + 1).round().astype(int)
    return parts + [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)]


@dataclass(frozen=True)
class _Part:
    """What the trials of one world earned."""

    step_reward_sums: np.ndarray  # (T,)
    trial_sums: np.ndarray  # (n,) reward summed over the whole life
    trial_sums_after: np.ndarray  # (n,) from the fault step on
    trajectory: Trajectory | None


def _live_trials(
    family: BrainFamily,
    individual: Any,
    settings: ImplementationSettings,
    seed: int,
    control_period: float,
    physics: sim.Physics,
    noise_stream: sim.NoiseStream,
    c_from: CFrom,
    part: slice,
    record: bool,
    progress: Callable[[int], None],
) -> _Part:
    """The lives of trials `part` in one world, C of the reward judged as `c_from` says."""
    arena = arena_of(settings.arena)
    trials = np.arange(part.start, part.stop)
    start_index = trials % len(arena.start_poses)
    world_seeds, engine_seeds = trial_seeds(seed, trials)
    world = new_world(
        arena,
        n=len(trials),
        seed=seed,
        noise_sigma=settings.noise_sigma,
        control_period=control_period,
        physics=physics,
        noise_stream=noise_stream,
    )
    world.reset(arena.start_poses[start_index], seeds=world_seeds)
    world.schedule_faults(faults(settings, seed, trials))
    controllers = family.controllers(family.copies(individual, len(trials)), engine_seeds)
    batch = Batch(world, controllers, c_from)
    steps = settings.steps
    recorder = TrajectoryRecorder(len(trials), steps, family.trace_layout) if record else None
    epsilon, alpha = epsilon_alpha_per_step(settings)
    fault_step = min(settings.fault_step, steps)
    bounds = sorted({*range(0, steps, _PROGRESS_EVERY), fault_step, steps})
    per_step = np.zeros(steps)
    before, after = np.zeros(len(trials)), np.zeros(len(trials))
    for a, b in itertools.pairwise(bounds):
        block = rollout(batch, b - a, epsilon[a:b], alpha[a:b], recorder=recorder)
        per_step[a:b] = block.step_reward_sums
        (before if b <= fault_step else after)[:] += block.term_sums[:, 0]
        progress((b - a) * len(trials))
    return _Part(
        step_reward_sums=per_step,
        trial_sums=before + after,
        trial_sums_after=after,
        trajectory=recorder.trajectory(start_index) if recorder is not None else None,
    )


def run_implementation(
    family: BrainFamily,
    individual: Any,
    settings: ImplementationSettings,
    *,
    seed: int,
    control_period: float,
    name: str,
    generation: int,
    workers: int = 1,
    progress: StepProgress | None = None,
    c_from: CFrom = "true",
    physics: sim.Physics = sim.DEFAULT_PHYSICS,
    noise_stream: sim.NoiseStream = sim.DEFAULT_NOISE_STREAM,
) -> Implementation:
    """Implement one individual of `family` (with a leading axis of 1); returns the results
    (nothing is written).

    `workers` > 1 shares the trial worlds out over that many processes (not from a daemon
    process, such as a Dask worker); results are identical for any count. `c_from`: the
    readings the reward's C is judged from, the run's `reward.c_from`; `physics` and
    `noise_stream` are the worlds' (a run's `training.physics` and `training.noise_stream`).
    """
    arena = arena_of(settings.arena)
    n_starts = len(arena.start_poses)
    trials = trial_count(settings)
    recorded = min(settings.recorded_trials, trials)
    life = life_bytes(recorded, settings.steps, family.trace_layout)
    check_memory(
        life, f"recording {recorded} trials of {settings.steps} steps", ImplementationError
    )
    parts = trial_worlds(trials, recorded)
    report = progress or (lambda _done, _total: None)
    total = parts[-1].stop * settings.steps
    calls = [
        (family, individual, settings, seed, control_period, physics, noise_stream, c_from, part,
         part.start == 0 and recorded > 0)
        for part in parts
    ]  # fmt: skip
    # every world's trials, in this process and `workers` − 1 more
    results = share_out(_live_trials, calls, workers, lambda done: report(done, total))
    report(total, total)
    steps = settings.steps
    after_steps = steps - min(settings.fault_step, steps)
    trial_mean = np.concatenate([r.trial_sums for r in results]) / steps
    after_mean = (
        np.concatenate([r.trial_sums_after for r in results]) / after_steps
        if after_steps
        else np.full(trials, np.nan)
    )
    per_step = np.zeros(steps)
    for result in results:  # in the fixed order of the worlds: the same sums for any workers
        per_step += result.step_reward_sums
    trajectory = results[0].trajectory if recorded else None
    if trajectory is None:
        trajectory = TrajectoryRecorder(0, steps, family.trace_layout).trajectory(
            np.zeros(0, np.int64)
        )
    return Implementation(
        name=name,
        settings=settings,
        generation=generation,
        reward_per_step=per_step / trials,
        trial_mean_reward=trial_mean,
        trial_mean_after_fault=after_mean,
        start_index=np.arange(trials) % n_starts,
        mean_reward=float(trial_mean.mean()),
        mean_after_fault=float(after_mean.mean()),
        trials=trajectory,
        recorded=np.arange(recorded),
    )


def implement(
    run_path: str | Path,
    settings: ImplementationSettings,
    name: str | None = None,
    progress: StepProgress | None = None,
    workers: int = 1,
) -> Implementation:
    """Implement a run's trained individual and store the result as `implementation/<name>`.

    Raises:
        RunFileError: the run is missing, foreign, unfinished, or the name is taken.
        ImplementationError: a bad name.
    """
    run_path = Path(run_path)
    name = check_name(name if name is not None else default_name(settings))
    with RunReader(run_path) as run:
        if not run.finished:
            raise RunFileError(
                f"{run_path.name} has not finished training "
                f"({run.generations_done} of {run.config.training.generations} generations)"
            )
        if name in run.implementation_names():
            raise RunFileError(
                f"{run_path.name} already has an implementation named {name!r}; "
                "choose another --name"
            )
        generation = (
            settings.generation if settings.generation is not None else run.generations_done - 1
        )
        seed = settings.seed if settings.seed is not None else run.seed
        phase = implementation_of(run, settings, generation, seed=seed, name=name)
    result = phase(workers=workers, progress=progress)
    add_implementation(run_path, result)
    return result


def implementation_of(
    run: RunReader, settings: ImplementationSettings, generation: int, *, seed: int, name: str
) -> partial[Implementation]:
    """`run_implementation` of `run`'s best of `generation` in the run's own worlds: its
    control period, physics, noise stream and reward's C, read from the run's config here only (for
    `implement` and the dashboard alike). Call it once the file is closed (`workers`,
    `progress` may be given then)."""
    config = run.config
    family = family_of(config)
    return partial(
        run_implementation,
        family,
        family.best(run, generation),
        settings,
        seed=seed,
        control_period=config.training.control_period,
        physics=config.training.physics,
        noise_stream=config.training.noise_stream,
        c_from=config.reward.c_from,
        name=name,
        generation=generation,
    )
