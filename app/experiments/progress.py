"""The client's view of a running experiment: one bar over all its runs and a line per run.

Workers report each generation and condition done with `log_event` (topic `TOPIC`); the client
subscribes and feeds `Progress.event`, and marks a run complete when its task returns.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from app.experiments.planning import RunState, Task

TOPIC = "gnp-lab-progress"


@dataclass(frozen=True)
class Counts:
    """How far an experiment is: runs complete, generations and conditions done, and the
    runs under way as (run name, generations done, generations)."""

    runs_done: int
    runs: int
    generations_done: int
    generations: int
    conditions_done: int
    conditions: int
    under_way: tuple[tuple[str, int, int], ...]


@dataclass
class Progress:
    """One bar over the whole experiment, in work units (robot-steps of training generations
    and trial-steps of conditions), fed by worker events and finished tasks."""

    tasks: list[Task]
    states: dict[str, RunState]
    quiet: bool = False
    _generations: dict[str, int] = field(default_factory=dict)
    _planned: dict[str, int] = field(default_factory=dict)  # a task's generations in all
    _conditions: dict[str, set[str]] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _bar: Any = None

    def __post_init__(self) -> None:
        from tqdm import tqdm

        # Each task's generations, read once: a task's config is JSON, and parsing it for
        # every task at every event took 8% of a core in a 200-run experiment.
        self._planned.update({t.key: t.config.training.generations for t in self.tasks})
        for task in self.tasks:
            state = self.states[task.key]
            self._generations[task.key] = state.generations_done
            self._conditions[task.key] = set(state.conditions)
        total = sum(self._cost(t, self._planned[t.key], len(t.conditions)) for t in self.tasks)
        self._by_key = {t.key: t for t in self.tasks}
        self._bar = tqdm(
            total=total, initial=self._done(), unit="step", unit_scale=True,
            desc="experiment", disable=self.quiet, dynamic_ncols=True,
        )  # fmt: skip

    @staticmethod
    def _cost(task: Task, generations: int, conditions: int) -> int:
        return generations * task.generation_cost + conditions * task.condition_cost

    def _done(self) -> int:
        return sum(
            self._cost(t, self._generations[t.key], len(self._conditions[t.key]))
            for t in self.tasks
        )

    def _counts(self) -> Counts:
        done, under_way = 0, []
        for task in self.tasks:
            generations = self._generations[task.key]
            total = self._planned[task.key]
            conditions = len(self._conditions[task.key])
            if generations >= total and conditions == len(task.conditions):
                done += 1
            elif generations or conditions:
                under_way.append((task.name, generations, total))
        return Counts(
            runs_done=done,
            runs=len(self.tasks),
            generations_done=sum(self._generations.values()),
            generations=sum(self._planned.values()),
            conditions_done=sum(len(c) for c in self._conditions.values()),
            conditions=sum(len(t.conditions) for t in self.tasks),
            under_way=tuple(under_way),
        )

    def counts(self) -> Counts:
        """How far the experiment is now (safe to call from any thread)."""
        with self._lock:
            return self._counts()

    def _refresh(self) -> None:
        c = self._counts()
        self._bar.set_postfix_str(
            f"gen {c.generations_done}/{c.generations} cond {c.conditions_done}/{c.conditions}",
            refresh=False,
        )
        self._bar.update(self._done() - self._bar.n)

    def event(self, event: tuple[float, dict[str, Any]]) -> None:
        """A worker's `log_event` message: a generation or a condition done."""
        msg = event[1]
        key = msg.get("task")
        with self._lock:
            if key not in self._by_key:
                return
            if "generations" in msg:
                self._generations[key] = max(self._generations[key], int(msg["generations"]))
            if "condition" in msg:
                self._conditions[key].add(str(msg["condition"]))
            self._refresh()

    def finished(self, task: Task) -> None:
        with self._lock:
            self._generations[task.key] = self._planned[task.key]
            self._conditions[task.key] = {name for name, _ in task.conditions}
            self._refresh()

    def write(self, line: str) -> None:
        """Print a line above the bar (or alone when quiet)."""
        if self.quiet:
            print(line)
        else:
            self._bar.write(line)

    def close(self) -> None:
        self._bar.close()


def outcome_line(outcome: dict[str, Any]) -> str:
    """The live line printed when a run finishes."""
    if "test_return" in outcome:  # a task experiment's run: returns (and its env-steps)
        steps = outcome.get("training_env_steps")
        return (
            f"{outcome['arm']} seed {outcome['seed']}: final best return "
            f"{outcome['final_best_fitness']:.1f}; test return {outcome['test_return']:.1f}"
            + ("" if steps is None else f"; {steps:,} env-steps in training")
        )
    parts = [f"{outcome['arm']} seed {outcome['seed']}: final best fitness "]
    parts[0] += f"{outcome['final_best_fitness']:.4f}"
    for name, (mean, after) in outcome["conditions"].items():
        parts.append(f"{name} {mean:.4f} (after fault {after:.4f})")
    return "; ".join(parts)


Echo = Callable[[str], None]
"""Given each run's outcome line (or a failure's)."""
Watch = Callable[[Progress], None]
"""Given the live `Progress` once an experiment's tasks are submitted."""
