"""The implementation phase: a trained individual adapts online in an unseen arena.

The individual (default: the final elite, with the Q tables it learned) is cloned into
10 start poses × repeats trials. Each lives `steps` steps in the implementation arena with
online Sarsa and no evolution; the chosen sensors break at the fault step t'. ε/α are the fixed
values before t' and, with the "changing" schedule, follow Eq. 4.3-4.4 from t' on. Trial i
starts at start pose i mod 10 and draws from streams keyed by (seed, trial i) only, so results
do not depend on how trials are batched.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import numpy as np

import gnp
import sim
from app.config import ImplementationSettings
from app.recording import TrajectoryRecorder
from app.store import (
    Implementation,
    RunFileError,
    RunReader,
    add_implementation,
)

_TAG_TRIAL = 4
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,63}$")

StepProgress = Callable[[int, int], None]  # (steps done, total steps)


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
    else:
        fault = "no-fault"
    noise = f"-noise{settings.noise_sigma:g}" if settings.noise_sigma else ""
    return f"{fault}-{settings.schedule}{noise}"


def trial_seeds(seed: int, trials: int) -> tuple[np.ndarray, np.ndarray]:
    """(world seeds, engine seeds), (trials,) uint64 each, keyed by (seed, trial index)."""
    states = np.array(
        [
            np.random.SeedSequence([seed, _TAG_TRIAL, i]).generate_state(2, np.uint64)
            for i in range(trials)
        ],
        dtype=np.uint64,
    ).reshape(trials, 2)
    return states[:, 0] >> np.uint64(1), states[:, 1] >> np.uint64(1)


def epsilon_alpha_at(settings: ImplementationSettings, t: int) -> tuple[float, float]:
    """(ε, α) at step t: fixed before the fault step, then the configured schedule."""
    if settings.schedule == "fixed" or t < settings.fault_step:
        return settings.epsilon, settings.alpha
    eps_schedule, alpha_schedule = settings.schedules()
    return gnp.epsilon_alpha_after_fault(
        eps_schedule, alpha_schedule, t, settings.fault_step, settings.steps
    )


def run_implementation(
    cfg: gnp.GnpConfig,
    individual: gnp.Population,
    settings: ImplementationSettings,
    *,
    seed: int,
    control_period: float,
    name: str,
    generation: int,
    progress: StepProgress | None = None,
) -> Implementation:
    """Implement a 1-individual population; returns the results (nothing is written)."""
    arena = sim.load_arena(settings.arena)
    n_starts = len(arena.start_poses)
    trials = n_starts * settings.repeats
    start_index = np.arange(trials) % n_starts
    world_seeds, engine_seeds = trial_seeds(seed, trials)
    pop = gnp.take(individual, np.zeros(trials, dtype=np.int64))
    world = sim.World(
        arena,
        n=trials,
        seed=seed,
        noise_sigma=settings.noise_sigma,
        control_period=control_period,
    )
    world.reset(arena.start_poses[start_index], seeds=world_seeds)
    if settings.broken_sensors:
        world.schedule_faults(
            [
                sim.Fault(
                    step=settings.fault_step,
                    sensors=settings.broken_sensors,
                    mode=settings.fault_mode,
                )
            ]
        )
    state = gnp.init_state(cfg, trials, engine_seeds)
    k = min(settings.recorded_trials, trials)
    steps = settings.steps
    rewards = np.zeros((trials, steps))
    recorder = TrajectoryRecorder(k, steps, cfg.max_visits_per_step)
    reward = np.zeros(trials)
    for t in range(steps):
        epsilon, alpha = epsilon_alpha_at(settings, t)
        seen = world.observe()
        commands, trace = gnp.step(cfg, pop, state, seen, reward, epsilon, alpha, trace=True)
        world.step(commands)
        true_readings = world.sense()
        terms = sim.reward_terms(true_readings, commands)
        reward = terms["reward"]
        rewards[:, t] = reward
        if k:
            recorder.record(t, world.poses, true_readings, seen, commands, terms, trace)
        if progress is not None:
            progress(t + 1, steps)
    after = rewards[:, settings.fault_step :] if settings.fault_step < steps else rewards[:, :0]
    after_mean = after.mean(axis=1) if after.shape[1] else np.full(trials, np.nan)
    recorded = recorder.trajectory(start_index)
    return Implementation(
        name=name,
        settings=settings,
        generation=generation,
        reward_per_step=rewards.mean(axis=0),
        trial_mean_reward=rewards.mean(axis=1),
        trial_mean_after_fault=after_mean,
        start_index=start_index,
        mean_reward=float(rewards.mean()),
        mean_after_fault=float(after_mean.mean()),
        trials=recorded,
        recorded=np.arange(k),
    )


def implement(
    run_path: str | Path,
    settings: ImplementationSettings,
    name: str | None = None,
    progress: StepProgress | None = None,
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
        cfg, individual = run.best_genome(generation)
        seed = settings.seed if settings.seed is not None else run.seed
        control_period = run.config.training.control_period
    result = run_implementation(
        cfg,
        individual,
        settings,
        seed=seed,
        control_period=control_period,
        name=name,
        generation=generation,
        progress=progress,
    )
    add_implementation(run_path, result)
    return result
