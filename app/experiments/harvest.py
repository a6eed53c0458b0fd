"""An experiment's results gathered from its run files (NaN where a run or condition is
missing), as the `ExperimentResults` the summary, the report and the dashboard read.
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np

from app.experiments.planning import Task, inspect, plan, work
from app.experiments.results import (
    CONVERGENCE_SHARE,
    ENV_STEPS_METRIC,
    PROTOCOL_METRICS,
    Condition,
    ExperimentResults,
)
from app.experiments.spec import ExperimentSpec
from app.store import RunReader


class Ledger(Protocol):
    """What `collect` needs of `app.experiments.ledger.Ledger` (which builds on `collect`)."""

    def fill(self, results: ExperimentResults) -> ExperimentResults: ...


def convergence_generation(best_fitness: np.ndarray) -> float:
    """The first generation (from 1) whose best fitness reaches CONVERGENCE_SHARE of the last."""
    final = best_fitness[-1]
    reached = np.flatnonzero(best_fitness >= CONVERGENCE_SHARE * final)
    return float(reached[0] + 1)


def _fault_effects(
    spec: ExperimentSpec,
    conditions: tuple[Condition, ...],
    scalars: dict[tuple[str, str, str], np.ndarray],
    curves: dict[tuple[str, str, str], np.ndarray],
) -> None:
    """fault_effect of every fault condition: its reward per step from the fault step on minus
    the control's over the same steps, run by run (NaN where either is missing); and
    relative_fault_effect, that difference over the control's level (NaN where it is 0)."""
    if spec.control is None:
        return
    for arm in spec.arms:
        control = curves[("reward_per_step", arm.name, spec.control)]
        for c in conditions:
            if c.fault_step is None:
                continue
            ours = curves[("reward_per_step", arm.name, c.name)][:, c.fault_step :].mean(axis=1)
            level = control[:, c.fault_step :].mean(axis=1)
            scalars[("fault_effect", arm.name, c.name)] = ours - level
            with np.errstate(divide="ignore", invalid="ignore"):
                relative = (ours - level) / level
            scalars[("relative_fault_effect", arm.name, c.name)] = np.where(
                level > 0, relative, np.nan
            )


def _task_results(
    spec: ExperimentSpec,
    tasks: list[Task],
    seed_list: tuple[int, ...],
    scalars: dict[tuple[str, str, str], np.ndarray],
    curves: dict[tuple[str, str, str], np.ndarray],
) -> None:
    """A task experiment's values: final best return, the final elite's mean test return (and
    per test protocol, for the runs whose files hold them: `PROTOCOL_METRICS`), the env-steps
    its training spent (`ENV_STEPS_METRIC`, likewise), and the best return per generation (as
    `best_fitness_curve`), from each run's file. A metric a run may lack has its columns only
    where a claim names it or a run holds it, so results of files before them are as they were."""
    from app.tasks.peer import read_peer

    n = len(seed_list)
    named = {m for c in spec.comparisons for m in (c.metric, c.metric_b) if m is not None}
    claimed = named & {*PROTOCOL_METRICS.values(), ENV_STEPS_METRIC}

    def held(metric: str, arm: str, row: int, value: float) -> None:
        for each in spec.arms:  # every arm's column once any run holds the metric
            scalars.setdefault((metric, each.name, ""), np.full(n, np.nan))
        scalars[(metric, arm, "")][row] = value

    for arm in spec.arms:
        for metric in ("final_best_return", "test_return", *sorted(claimed)):
            scalars[(metric, arm.name, "")] = np.full(n, np.nan)
    for task in tasks:
        key = ("best_fitness_curve", task.arm, "")
        if key not in curves:
            curves[key] = np.full((n, task.config.training.generations), np.nan)
        if not Path(task.path).exists():
            continue
        inspect(task)
        result = read_peer(task.path)
        row = seed_list.index(task.seed)
        curves[key][row, : result.best_curve.size] = result.best_curve
        if result.finished and result.test_returns is not None:
            scalars[("final_best_return", task.arm, "")][row] = result.best_curve[-1]
            scalars[("test_return", task.arm, "")][row] = float(np.mean(result.test_returns))
            for protocol, returns in (result.protocol_returns or {}).items():
                held(PROTOCOL_METRICS[protocol], task.arm, row, float(np.mean(returns)))
            if result.training_env_steps is not None:
                held(ENV_STEPS_METRIC, task.arm, row, float(result.training_env_steps))


def collect(
    spec: ExperimentSpec,
    scale: str,
    runs_dir: str | Path,
    seeds: int | None = None,
    looks: tuple[int, ...] = (),
    ledger: Ledger | None = None,
) -> ExperimentResults:
    """The experiment's results from its run files (NaN where a run or condition is missing),
    and from `ledger`'s values for the runs it holds that have no run file here.

    `looks` are the seeds per arm at each planned look of an adaptive run (see `run_adaptive`).
    """
    tasks = plan(spec, scale, runs_dir, seeds)
    seed_list = spec.seed_list(scale, seeds)  # type: ignore[arg-type]
    n = len(seed_list)
    conditions = spec.conditions_info(scale)
    scalars: dict[tuple[str, str, str], np.ndarray] = {}
    curves: dict[tuple[str, str, str], np.ndarray] = {}
    fault_steps = {c.name: c.steps if c.fault_step is None else c.fault_step for c in conditions}
    if spec.task is not None:
        _task_results(spec, tasks, seed_list, scalars, curves)
    for arm in spec.arms if spec.task is None else ():
        generations = spec.run_config(arm.name, scale, 0).training.generations
        scalars[("final_best_fitness", arm.name, "")] = np.full(n, np.nan)
        scalars[("convergence_generation", arm.name, "")] = np.full(n, np.nan)
        curves[("best_fitness_curve", arm.name, "")] = np.full((n, generations), np.nan)
        for c in conditions:
            for metric in ("mean_reward", "mean_reward_before_fault", "mean_reward_after_fault"):
                scalars[(metric, arm.name, c.name)] = np.full(n, np.nan)
            curves[("reward_per_step", arm.name, c.name)] = np.full((n, c.steps), np.nan)
    for task in tasks if spec.task is None else ():
        row = seed_list.index(task.seed)
        state = inspect(task)
        if not Path(task.path).exists():
            continue
        with RunReader(task.path) as run:
            history = run.history()
            curves[("best_fitness_curve", task.arm, "")][row, : len(history.best_fitness)] = (
                history.best_fitness
            )
            if state.finished:
                scalars[("final_best_fitness", task.arm, "")][row] = history.best_fitness[-1]
                scalars[("convergence_generation", task.arm, "")][row] = convergence_generation(
                    np.asarray(history.best_fitness)
                )
            for name in state.conditions:
                result = run.implementation(name, recorded=False)
                scalars[("mean_reward", task.arm, name)][row] = result.mean_reward
                before = result.reward_per_step[: fault_steps[name]]  # every trial is as long
                scalars[("mean_reward_before_fault", task.arm, name)][row] = (
                    before.mean() if len(before) else np.nan  # a fault at step 0: no before
                )
                scalars[("mean_reward_after_fault", task.arm, name)][row] = result.mean_after_fault
                curves[("reward_per_step", task.arm, name)][row] = result.reward_per_step
    _fault_effects(spec, conditions, scalars, curves)
    cost = work(spec, scale)
    results = ExperimentResults(
        name=spec.name,
        description=spec.description,
        source=spec.source,
        scale=scale,
        arms=spec.arms_info(),
        seeds=seed_list,
        conditions=conditions,
        comparisons=spec.comparisons_info(),
        thesis=spec.thesis_info(),
        control=spec.control,
        looks=looks,
        steps_per_run=(cost.robot_steps + cost.trial_steps) / cost.runs,
        scalars=scalars,
        curves=curves,
    )
    return results if ledger is None else ledger.fill(results)
