"""`check_family`: does a brain family keep the contract? Run it on your class (as Gymnasium's
`check_env`, scikit-learn's `check_estimator`).

Each check is named; a check that raises is a problem too, and the others still run. It takes
a tiny population through a few steps, so it is fast (seconds, a family's compiled code aside).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import Any

import numpy as np

import sim
from app.brains.contract import BrainFamily, BrainIO, checked_arrays
from app.settings import families
from app.settings.config import RunConfig

Arrays = dict[str, np.ndarray]

POPULATION = 4
"""Individuals of the default config's population."""
STEPS = 5
"""Steps the controllers take in each check of theirs."""
ROBOTS = 2
"""Robots the controllers' checks drive: the fewest a population has."""
TASK_IO = BrainIO(n_inputs=3, n_outputs=1, n_actions=2)
"""The inputs and outputs an `any_io` family is checked on beside the robot's: a small task's."""


class FamilyCheckError(AssertionError):
    """A family breaks the contract: `problems` names each broken check (one line each)."""

    def __init__(self, name: str, problems: list[str]) -> None:
        self.problems = problems
        lines = "".join(f"\n- {problem}" for problem in problems)
        super().__init__(f"brain family {name!r} breaks the contract:{lines}")


def tiny_config(family: type[BrainFamily]) -> RunConfig:
    """A config of `family` with a tiny population and short lives."""
    training = {"population": POPULATION, "generations": 2, "steps": STEPS}
    return RunConfig.model_validate({**family.selection(), "seed": 3, "training": training})


def same(a: Arrays, b: Arrays) -> bool:
    """Whether two dicts of arrays hold the same names, shapes, dtypes and values (NaN = NaN)."""
    return sorted(a) == sorted(b) and all(
        a[k].shape == b[k].shape
        and a[k].dtype == b[k].dtype
        and np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind in "fc")
        for k in a
    )


def check_family(family: type[BrainFamily], config: RunConfig | None = None) -> None:
    """Check `family` (a class) against the contract, bound to `config` (default: a tiny one,
    `tiny_config`) with the robot's inputs and outputs, and, a family that declares `any_io`,
    with a task's too (`TASK_IO`: its checks named "on TASK_IO: ...").

    Raises:
        FamilyCheckError: every problem found, each named by its check.
    """
    problems: list[str] = []

    def check(name: str, test: Callable[[], str | None]) -> None:
        try:
            problem = test()
        except Exception as error:  # a check that raises is a problem of the family
            problem = f"raised {type(error).__name__}: {error}"
        if problem:
            problems.append(f"{name}: {problem}")

    check("names agree", lambda: names_problem(family))
    for io, prefix in ((None, ""), (TASK_IO, "on TASK_IO: "))[: 2 if family.any_io else 1]:
        try:
            bound = family(config or tiny_config(family), *(() if io is None else (io,)))
        except Exception as error:
            problems.append(f"{prefix}binds to a config: {error}")
            continue
        for name, test in Checks(bound).all().items():
            check(prefix + name, test)
    if problems:
        raise FamilyCheckError(family.name, problems)


def names_problem(family: type[BrainFamily]) -> str | None:
    """Registry, class and settings model name the family alike."""
    name = family.name
    problems = families.disagreements(name, family)
    if name in families.names():
        registered = families.family_class(name)
        if registered is not family:
            problems.append(f"{name!r} is registered to {registered.__qualname__}")
    else:
        problems.append(f"no family is registered under {name!r}")
    return "; ".join(problems) or None


def is_learner(controllers: object) -> bool:
    """Whether `controllers` learn online (`app.loop.rollout.OnlineLearner`)."""
    from app.loop.rollout import OnlineLearner  # the loop: when a family's lives are checked

    return isinstance(controllers, OnlineLearner)


class Checks:
    """The checks of one bound family, by name."""

    def __init__(self, family: BrainFamily) -> None:
        self.family = family
        self.layout = family.genome_layout
        self.rng = np.random.default_rng(0)

    def all(self) -> dict[str, Callable[[], str | None]]:
        return {
            "generation 0 is a function of the seed": self.first_is_seeded,
            "generation 0 has the genome layout": self.first_has_layout,
            "arrays -> from_arrays round trip": self.round_trip,
            "take/concat keep rows": self.rows_kept,
            "run_template builds": self.template,
            "act: (N, n_outputs) finite commands in range": self.commands,
            "size counts the individuals": self.counted,
            "act: rows independent": self.rows_independent,
            "reset_episode works": self.reset,
            "a traced step matches trace_layout": self.traced,
            "online learning declared as done": self.online,
            "advance gives the genome layout": self.advanced,
            "rebuild(1, ...) resumes to the bit": self.resumed,
            "controller_document is JSON": self.document,
            "tracer records a traced step": self.tracer,
        }

    # --- individuals --------------------------------------------------------------------------

    def arrays(self) -> Arrays:
        evolution = self.family.first()
        return evolution.arrays(evolution.individuals())

    def first_is_seeded(self) -> str | None:
        return None if same(self.arrays(), self.arrays()) else "two first() differ"

    def first_has_layout(self) -> str | None:
        checked_arrays(self.layout, self.arrays())
        return None

    def round_trip(self) -> str | None:
        evolution = self.family.first()
        arrays = evolution.arrays(evolution.individuals())
        again = evolution.arrays(self.family.from_arrays(arrays))
        return None if same(arrays, again) else "arrays(from_arrays(a)) differ from a"

    def rows_kept(self) -> str | None:
        family, evolution = self.family, self.family.first()
        individuals = evolution.individuals()
        arrays = evolution.arrays(individuals)
        n = len(next(iter(arrays.values())))
        rows = [n - 1, 0, *range(1, n - 1)]
        parts = [family.take(individuals, rows[:2]), family.take(individuals, rows[2:])]
        expected = {k: v[rows] for k, v in arrays.items()}
        if not same(evolution.arrays(family.concat(parts)), expected):
            return "concat(take(rows)) is not the rows"
        copies = evolution.arrays(family.copies(family.take(individuals, [1]), 3))
        if not same(copies, {k: v[[1, 1, 1]] for k, v in arrays.items()}):
            return "copies(one, 3) are not three of it"
        return None

    def counted(self) -> str | None:
        evolution = self.family.first()
        n = len(next(iter(evolution.arrays(evolution.individuals()).values())))
        size = self.family.size(evolution.individuals())
        return None if size == n else f"size() gives {size} for {n} individuals"

    def template(self) -> str | None:
        self.family.run_template()
        return None

    # --- lives --------------------------------------------------------------------------------

    def controllers(self, n: int = ROBOTS) -> Any:
        """Controllers of generation 0's first `n` individuals (copies), rates set."""
        family = self.family
        individuals = family.for_life(family.take(family.first().individuals(), list(range(n))))
        controllers: Any = family.controllers(individuals, 100 + np.arange(n, dtype=np.int64))
        if is_learner(controllers):
            controllers.set_rates(0.1, 0.1, True)
        return controllers

    def observations(self, n: int) -> np.ndarray:
        return self.rng.uniform(0.0, sim.IR_MAX, (n, self.family.io.n_inputs))

    def wrong_commands(self, commands: Any, n: int) -> str | None:
        commands = np.asarray(commands)
        outputs = self.family.io.n_outputs
        if commands.shape != (n, outputs):
            return f"commands are {commands.shape}, not ({n}, {outputs})"
        if not np.all(np.isfinite(commands)):
            return "non-finite commands"
        if np.any(np.abs(commands) > sim.MAX_COMMAND):
            return f"commands beyond ±{sim.MAX_COMMAND}"
        return None

    def commands(self) -> str | None:
        controllers = self.controllers()
        if controllers.size != ROBOTS:
            return f"controllers of {ROBOTS} individuals have size {controllers.size}"
        for _ in range(STEPS):
            commands, _ = controllers.act(self.observations(ROBOTS), np.ones(ROBOTS), trace=False)
            wrong = self.wrong_commands(commands, ROBOTS)
            if wrong:
                return wrong
        return None

    def rows_independent(self) -> str | None:
        a, b = self.controllers(), self.controllers()
        for _ in range(STEPS):
            seen = self.observations(ROBOTS)
            other = seen.copy()
            other[1:] = self.observations(ROBOTS - 1)
            mine, _ = a.act(seen, np.ones(ROBOTS), trace=False)
            theirs, _ = b.act(other, np.ones(ROBOTS), trace=False)
            if not np.array_equal(np.asarray(mine)[0], np.asarray(theirs)[0]):
                return "robot 0's commands depend on the others' observations"
        return None

    def reset(self) -> str | None:
        controllers = self.controllers()
        controllers.act(self.observations(ROBOTS), np.ones(ROBOTS), trace=False)
        controllers.reset_episode()
        commands, _ = controllers.act(self.observations(ROBOTS), np.zeros(ROBOTS), trace=False)
        return self.wrong_commands(commands, ROBOTS)

    def traced(self) -> str | None:
        _, trace = self.controllers().act(self.observations(ROBOTS), np.ones(ROBOTS), trace=True)
        for name, (shape, dtype) in self.family.trace_layout.items():
            value = np.asarray(getattr(trace, name))
            if value.shape != (ROBOTS, *shape) or value.dtype != np.dtype(dtype):
                return (
                    f"trace {name} is {value.shape} {value.dtype}, not {(ROBOTS, *shape)} {dtype}"
                )
        return None

    def online(self) -> str | None:
        learner = is_learner(self.controllers())
        if learner != self.family.learns_online:
            word = "are" if learner else "are not"
            return f"learns_online is {self.family.learns_online}; its controllers {word} learners"
        rates = self.family.first().epsilon_alpha(0)
        if not self.family.learns_online and not all(math.isnan(r) for r in rates):
            return f"a family that does not learn online gives ε, α {rates}, not NaN"
        return None

    # --- evolution ----------------------------------------------------------------------------

    def advanced(self) -> str | None:
        evolution = self.family.first()
        arrays = evolution.arrays(evolution.individuals())
        n = len(next(iter(arrays.values())))
        learned = self.family.for_life(evolution.individuals())
        after = evolution.advance(learned, self.rng.uniform(0, 1, n), 0)
        checked_arrays(self.layout, after)
        if len(next(iter(after.values()))) != n:
            return "the next generation has another size"
        if not same(after, evolution.arrays(evolution.individuals())):
            return "advance's arrays are not the next generation's individuals"
        return None

    def resumed(self) -> str | None:
        family, went = self.family, self.family.first()
        n = len(next(iter(went.arrays(went.individuals()).values())))
        fitness = self.rng.uniform(0, 1, (2, n))
        first = went.advance(family.for_life(went.individuals()), fitness[0], 0)
        second = went.advance(family.for_life(went.individuals()), fitness[1], 1)
        back = family.rebuild(1, first, fitness[:1])
        if not same(back.arrays(back.individuals()), first):
            return "the rebuilt generation is not the checkpoint's"
        again = back.advance(family.for_life(back.individuals()), fitness[1], 1)
        return None if same(again, second) else "the rebuilt family evolves otherwise"

    # --- export and views ---------------------------------------------------------------------

    def document(self) -> str | None:
        one = self.family.take(self.family.first().individuals(), [0])
        settings = {"run": "check", "generation": 0, "seed": self.family.config.seed}
        json.dumps(self.family.controller_document(one, settings))
        return None

    def tracer(self) -> str | None:
        _, trace = self.controllers(1).act(self.observations(1), np.ones(1), trace=True)
        tracer = self.family.tracer()
        tracer.record(trace)
        view = tracer.view()
        return None if isinstance(view, dict) else f"view() gives {type(view).__name__}"
