"""An Optuna study of one brain on one task: its declaration, its storage file, its trials.

A trial draws settings from the brain's declared space (`app.tune.space`), trains one run per
tuning run seed at the study's population for the generations its env-step budget holds, and
scores the final generation's best individual on the validation episodes (greedy: ε = 0,
learning off; fracnetics' elite as it lives, deterministically). The study lives in an Optuna
RDB storage (SQLite) file: a cut study is continued by running the same command again, and
reruns give the same trials (each trial's sampler is seeded by the study's sampler seed and
the number of trials finished before it; see docs/tasks.md, "Tuning").
"""

from __future__ import annotations

import json
import sqlite3
import tempfile
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from app.tune.space import (
    MAX_RUN_SEEDS,
    MAX_VALIDATION_EPISODES,
    Brain,
    Param,
    TuneError,
    nested,
    run_seeds,
    settings_of,
    space,
    validation_seeds,
)

if TYPE_CHECKING:
    import optuna

    from app.tasks.config import TaskRunConfig, TaskSettings
    from app.tasks.fracnetics_arm import FracneticsSettings

MAX_BUDGET = 10**12
"""Most env-steps a study may give one training run."""
STARTUP_TRIALS = 10
"""Trials TPE draws at random before it models the finished ones (Optuna's default)."""
PRUNE_STARTUP_TRIALS = 5
"""Completed trials before the median pruner stops any."""


@dataclass(frozen=True)
class Declared:
    """A study's declaration: what its trials depend on. A study's storage keeps it, and a rerun
    that declares otherwise (but the trial count) is refused."""

    task: str
    brain: Brain
    name: str
    budget: int  # env-steps one training run may spend at most
    population: int
    steps: int  # a life's cap: one episode, at most this many steps
    seeds: int  # training runs per trial (run seeds run_seeds(seeds))
    validation: int  # validation episodes per run
    sampler_seed: int
    fixed: dict[str, Any] = field(default_factory=dict)  # the study's --set settings, flat
    discrete: bool = True  # the task's action is Discrete

    def __post_init__(self) -> None:
        if not 1 <= self.budget <= MAX_BUDGET:
            raise TuneError(f"--budget must be 1..{MAX_BUDGET} env-steps, got {self.budget}")
        if not 1 <= self.seeds <= MAX_RUN_SEEDS:
            raise TuneError(f"--seeds must be 1..{MAX_RUN_SEEDS}, got {self.seeds}")
        if not 1 <= self.validation <= MAX_VALIDATION_EPISODES:
            raise TuneError(
                f"--validation must be 1..{MAX_VALIDATION_EPISODES} episodes, got {self.validation}"
            )
        if not 0 <= self.sampler_seed < 2**32:
            raise TuneError(f"--sampler-seed must be 0..{2**32 - 1}, got {self.sampler_seed}")
        if self.generations < 1:
            raise TuneError(
                f"--budget {self.budget} env-steps holds no generation of {self.population} "
                f"lives of up to {self.steps} steps: give at least {self.population * self.steps}"
            )
        if self.generations > 1_000_000:
            raise TuneError(f"--budget {self.budget} is over 1,000,000 generations; give less")

    @property
    def generations(self) -> int:
        """The generations of every training run: as many as the budget holds when every life
        lasts its cap (so no run spends more than the budget)."""
        return self.budget // (self.population * self.steps)

    def params(self) -> list[Param]:
        method = self.fixed.get("controller.method")
        fuzzy = self.fixed.get("controller.fuzzy")
        if self.brain == "gnp" and (method is None or fuzzy is None):
            from app.brains.gnp_settings import ControllerSettings

            defaults = ControllerSettings()  # the lab's
            method = defaults.method if method is None else method
            fuzzy = defaults.fuzzy if fuzzy is None else fuzzy
        return space(self.brain, self.fixed, self.population, method, self.discrete, bool(fuzzy))

    def protocol(self) -> dict[str, Any]:
        """A GNP run's episode protocol (`app.tasks.common.EpisodeProtocol`): greedy tests
        unless the study sets `task.test_protocol`, the rest its defaults unless set."""
        from app.tasks.common import EpisodeProtocol

        given = {k: v for k, v in self.task_settings().items() if k in EpisodeProtocol.model_fields}
        return {"test_protocol": "greedy", **given}

    def task_settings(self) -> dict[str, Any]:
        """The study's `task.KEY` settings: the task's bounds and its runs' episode protocol."""
        return {k[len("task.") :]: v for k, v in self.fixed.items() if k.startswith("task.")}

    def run_settings(self) -> dict[str, Any]:
        """The study's fixed settings of the run config (not its protocol's)."""
        return {k: v for k, v in self.fixed.items() if not k.startswith("task.")}

    def json(self) -> str:
        """The declaration and the space it searches, as the study's storage keeps them."""
        space = [[p.name, p.kind, p.low, p.high, p.log, list(p.choices)] for p in self.params()]
        return json.dumps({**asdict(self), "space": space}, sort_keys=True)


def task_step_cap(task: str, steps: int | None) -> int:
    """A life's cap: `steps`, no more than the task's own time limit (its default).

    Raises:
        TaskError: an unknown task.
    """
    from app.tasks.config import make_env

    env = make_env(task)
    try:
        limit = env.spec.max_episode_steps if env.spec is not None else None
    finally:
        env.close()
    if steps is not None and steps < 1:
        raise TuneError(f"--steps must be at least 1, got {steps}")
    caps = [c for c in (steps, limit) if c is not None]
    return min(caps) if caps else 1000


# --- storage ---------------------------------------------------------------------------------

_SQLITE_HEADER = b"SQLite format 3\x00"


def check_storage(path: Path) -> None:
    """An existing storage file is an SQLite database holding Optuna's tables (Optuna would
    otherwise create its tables in any database it is given).

    Raises:
        TuneError: not a regular file, not SQLite, or not an Optuna study's.
    """
    if not path.exists() or (path.is_file() and path.stat().st_size == 0):
        return
    if not path.is_file():
        raise TuneError(f"storage {path} is not a regular file")
    with path.open("rb") as handle:
        if handle.read(len(_SQLITE_HEADER)) != _SQLITE_HEADER:
            raise TuneError(f"storage {path} is not an Optuna study (not an SQLite file)")
    try:
        db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        try:
            tables = {row[0] for row in db.execute("SELECT name FROM sqlite_master")}
        finally:
            db.close()
    except sqlite3.Error as error:
        raise TuneError(f"storage {path} is corrupt: {error}") from None
    if not {"studies", "trials", "version_info"} <= tables:
        raise TuneError(f"storage {path} is an SQLite file but not an Optuna study's")


def open_study(path: Path, declared: Declared) -> optuna.Study:
    """The study in `path` (created with its declaration, or loaded and checked against it).

    Raises:
        TuneError: a corrupt or foreign file, or a study declared otherwise.
    """
    import optuna
    import sqlalchemy.exc

    check_storage(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    try:
        storage = optuna.storages.RDBStorage(f"sqlite:///{path}")
        study = optuna.create_study(
            storage=storage, study_name=declared.name, direction="maximize", load_if_exists=True
        )
    except (sqlalchemy.exc.SQLAlchemyError, RuntimeError, ValueError, KeyError) as error:
        text = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise TuneError(f"storage {path} cannot be opened as an Optuna study: {text}") from None
    stored = study.user_attrs.get("declared")
    if stored is None:
        study.set_user_attr("declared", declared.json())
    elif stored != declared.json():
        was = json.loads(stored)
        now = json.loads(declared.json())
        if was.pop("space", None) != now.pop("space") and was == now:
            raise TuneError(
                f"study {declared.name!r} in {path} searched another space than "
                f"{declared.brain}'s now (app/tune/space.py changed): give another --study"
            )
        diff = ", ".join(
            f"{k} {was.get(k)!r} (now {now[k]!r})" for k in now if was.get(k) != now[k]
        )
        raise TuneError(
            f"study {declared.name!r} in {path} was declared with {diff}; rerun it as it was "
            "declared, or give another --study"
        )
    return study


def close_stale(study: optuna.Study) -> None:
    """Trials left running by a killed process are failed: a study runs one trial at a time."""
    from optuna.trial import TrialState

    for trial in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        study._storage.set_trial_state_values(trial._trial_id, TrialState.FAIL)


def finished(study: optuna.Study) -> list[optuna.trial.FrozenTrial]:
    """The trials that count towards the declared number: complete or pruned."""
    from optuna.trial import TrialState

    return study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.PRUNED))


# --- trials ----------------------------------------------------------------------------------


@dataclass
class Spent:
    """Env-steps a trial's training has spent (fracnetics': of the runs it finished)."""

    steps: int = 0


def _spent(trial: optuna.Trial, spent: Spent) -> None:
    if spent.steps:
        trial.set_user_attr("env_steps", spent.steps)


Report = Callable[[int, float], None]
"""A trial's intermediate result: (step, value); raises optuna.TrialPruned to stop the trial."""


def gnp_config(
    declared: Declared, task: TaskSettings, values: dict[str, Any], seed: int
) -> TaskRunConfig:
    """The task run of a trial (or of the preset: `values` the best trial's settings)."""
    from pydantic import ValidationError

    from app.settings.config import ConfigError
    from app.settings.loading import build_config
    from app.tasks.common import EpisodeProtocol
    from app.tasks.config import TaskRunConfig

    sizes = {
        "training": {
            "population": declared.population,
            "generations": declared.generations,
            "steps": declared.steps,
        }
    }
    layers = (nested(declared.run_settings()), nested(values), sizes, {"seed": seed})
    config = build_config(*layers, source=f"study {declared.name!r}")
    try:
        protocol = EpisodeProtocol(**declared.protocol())
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"])
        raise ConfigError(f"--set task.{where}: {first['msg']}") from None
    return TaskRunConfig.from_run_config(config, task, protocol)


def gnp_trial(
    declared: Declared, task: TaskSettings, values: dict[str, Any], report: Report, spent: Spent
) -> float:
    """Train a trial's GNP runs and score them: their mean validation return (`spent` counts
    their training env-steps as they are spent, a pruned trial's too).
    A run's final elite is the task run's (`elite_generation`: the last generation's best, or
    chosen on its own validation episodes), scored under its test protocol (greedy unless the
    study says otherwise) on the tuning validation episodes."""
    from app.tasks.training import elite_generation, protocol_episodes, train_task

    scores = []
    g_count = declared.generations
    with tempfile.TemporaryDirectory(prefix="gnp-lab-tune-") as folder:
        for r, seed in enumerate(run_seeds(declared.seeds)):
            config = gnp_config(declared, task, values, seed)
            path = Path(folder) / f"run-{r}.h5"

            def each(summary: Any, r: int = r) -> None:
                spent.steps += int(summary.steps)
                report(r * g_count + int(summary.generation), float(summary.best_fitness))

            train_task(config, path, progress=each)
            seeds = list(validation_seeds(declared.validation))
            elite = elite_generation(path)
            lives = protocol_episodes(path, seeds, elite, config.training.test_protocol)
            scores.append(float(np.mean(lives.returns)))
    return float(np.mean(scores))


def fracnetics_settings(declared: Declared, values: dict[str, Any]) -> FracneticsSettings:
    """fracnetics' documented settings of the task, with the study's and the trial's."""
    from app.tasks.fracnetics_arm import arm_settings

    if declared.task_settings():
        raise TuneError(
            "--set task.*: fracnetics lives and tests its episodes its own way, in the bounds "
            "it documents"
        )
    overlay = {}
    for path, value in {**declared.fixed, **values}.items():
        section, _, key = path.partition(".")
        if section != "fracnetics":
            raise TuneError(f"--set {path}: a fracnetics study sets fracnetics.KEY only")
        overlay[key] = value
    return arm_settings(declared.task, overlay)


def fracnetics_trial(
    declared: Declared, values: dict[str, Any], report: Report, spent: Spent
) -> float:
    """Train a trial's fracnetics runs and score their elites on the validation episodes
    (`spent` counts the training env-steps of each run it finishes)."""
    from app.tasks.fracnetics_arm import check_population, train_fracnetics

    settings = fracnetics_settings(declared, values)
    check_population(settings, declared.population)
    scores = []
    g_count = declared.generations
    for r, seed in enumerate(run_seeds(declared.seeds)):

        def each(generation: int, best: float, r: int = r) -> None:
            report(r * g_count + generation, best)

        result = train_fracnetics(
            declared.task, settings, declared.population, g_count, seed, declared.steps,
            validation_seeds(declared.validation), progress=each,
        )  # fmt: skip
        scores.append(float(np.mean(result.test_returns)))
        spent.steps += int(np.sum(result.env_steps))
    return float(np.mean(scores))


def draw(trial: optuna.Trial, params: list[Param]) -> dict[str, Any]:
    """A trial's settings (flat paths), drawn from `params`."""
    drawn: dict[str, Any] = {}
    for p in params:
        if p.kind == "float":
            drawn[p.name] = trial.suggest_float(p.name, p.low, p.high, log=p.log)
        elif p.kind == "int":
            drawn[p.name] = trial.suggest_int(p.name, int(p.low), int(p.high), log=p.log)
        elif p.kind == "share":
            drawn[p.name] = trial.suggest_float(p.name, 0.0, 1.0)
        else:
            drawn[p.name] = trial.suggest_categorical(p.name, list(p.choices))
    return settings_of(params, drawn)


def trial_sampler(declared: Declared, done: int) -> optuna.samplers.BaseSampler:
    """TPE seeded by (sampler seed, trials finished): the trials a study draws are a function of
    its finished trials, however often it was cut."""
    import optuna

    seed = int(np.random.SeedSequence([declared.sampler_seed, done]).generate_state(1)[0])
    return optuna.samplers.TPESampler(seed=seed, n_startup_trials=STARTUP_TRIALS)


def pruner(declared: Declared) -> optuna.pruners.BasePruner:
    """The median rule: a trial whose generation's best training return falls below the median
    of the completed trials' at the same generation is stopped, after PRUNE_STARTUP_TRIALS
    completed trials and the first third of its first run."""
    import optuna

    return optuna.pruners.MedianPruner(
        n_startup_trials=PRUNE_STARTUP_TRIALS, n_warmup_steps=declared.generations // 3
    )


@dataclass
class Outcome:
    """A finished trial, as the progress bar shows it."""

    number: int
    state: str  # "complete" | "pruned"
    value: float | None
    best: float | None


class _Reporter:
    """A trial's intermediate results, each step once (a run may say its last generation again
    as it stops), and the pruner's word after each."""

    def __init__(self, trial: optuna.Trial, hook: Callable[[int, int], None] | None) -> None:
        self.trial, self.hook, self.steps = trial, hook, set[int]()

    def __call__(self, step: int, value: float) -> None:
        import optuna

        if step not in self.steps:
            self.steps.add(step)
            if self.hook is not None:
                self.hook(self.trial.number, step)
            self.trial.report(value, step)
        if self.trial.should_prune():
            raise optuna.TrialPruned()


def run_trials(
    study: optuna.Study,
    declared: Declared,
    task: TaskSettings,
    trials: int,
    each: Callable[[Outcome], None] | None = None,
    report_hook: Callable[[int, int], None] | None = None,
) -> None:
    """Run trials until `trials` are finished (complete or pruned). A trial cut by Ctrl-C or
    SIGTERM is marked failed (it does not count) and the interruption raised again.

    `report_hook(trial number, step)` is called at every intermediate result (tests cut a
    study there)."""
    import optuna
    from optuna.trial import TrialState

    close_stale(study)
    params = declared.params()
    study.pruner = pruner(declared)
    while (done := len(finished(study))) < trials:
        study.sampler = trial_sampler(declared, done)
        trial, spent = study.ask(), Spent()
        report = _Reporter(trial, report_hook)
        try:
            values = draw(trial, params)
            trial.set_user_attr("settings", json.dumps(values, sort_keys=True))
            if declared.brain == "gnp":
                value = gnp_trial(declared, task, values, report, spent)
            else:
                value = fracnetics_trial(declared, values, report, spent)
        except optuna.TrialPruned:
            _spent(trial, spent)
            study.tell(trial, state=TrialState.PRUNED)
            state, value = "pruned", None
        except BaseException:  # Ctrl-C, SIGTERM (Interrupted), an error: it does not count
            study.tell(trial, state=TrialState.FAIL)
            raise
        else:
            _spent(trial, spent)
            study.tell(trial, value)
            state = "complete"
        if each is not None:
            each(Outcome(trial.number, state, value, best_value(study)))


def best_value(study: optuna.Study) -> float | None:
    """The best complete trial's value, None before any."""
    from optuna.trial import TrialState

    complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    return max(float(t.value) for t in complete if t.value is not None) if complete else None
