"""Tuning seeds are disjoint from every seed an experiment uses: run seeds, fracnetics' episode
seeds (run seed + g) and test episode seeds, of every shipped spec at every scale; and the
tuner's own run, episode and validation seeds stay inside its declared range. The search space
is its table less what a study fixes. `gnp-lab --help` and `tune --help` import no Optuna."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from app.experiments.spec_loading import load_shipped, shipped_names
from app.tune.space import (
    FIRST_VALIDATION_SEED,
    MAX_RUN_SEEDS,
    MAX_VALIDATION_EPISODES,
    TUNING_SEEDS,
    run_seeds,
    settings_of,
    space,
    validation_seeds,
)

ROOT = Path(__file__).resolve().parents[3]
MAX_GENERATIONS = 1_000_000  # TaskTraining.generations' bound


def _experiment_seeds(name: str) -> set[range]:
    """Every seed range an experiment uses, at each of its scales."""
    spec = load_shipped(name)
    ranges = set()
    for scale in spec.scales:
        seeds = spec.seed_list(scale)
        ranges.add(range(seeds[0], seeds[-1] + 1))
        if spec.task is None:
            continue
        ranges.add(
            range(spec.task.first_test_seed, spec.task.first_test_seed + spec.task.test_seeds)
        )
        for arm in spec.arms:
            if arm.brain == "fracnetics":  # its episodes: run seed + g, g < generations
                generations = spec.run_config(arm.name, scale, seeds[0]).training.generations
                ranges.add(range(seeds[0], seeds[-1] + generations))
    return ranges


def _overlap(a: range, b: range) -> bool:
    return max(a.start, b.start) < min(a.stop, b.stop)


def test_tuning_seeds_are_no_experiments_seeds() -> None:
    checked = 0
    for name in shipped_names():
        for seeds in _experiment_seeds(name):
            assert not _overlap(seeds, TUNING_SEEDS), (name, seeds)
            checked += 1
    assert checked > len(shipped_names())


def test_the_tuners_seeds_stay_in_their_range() -> None:
    runs = run_seeds(MAX_RUN_SEEDS)
    fracnetics_episodes = range(runs[0], runs[-1] + MAX_GENERATIONS)
    validation = validation_seeds(MAX_VALIDATION_EPISODES)
    assert runs[0] == TUNING_SEEDS.start and validation[0] == FIRST_VALIDATION_SEED
    assert fracnetics_episodes.stop <= validation[0]  # episodes of training never validate
    assert validation[-1] < TUNING_SEEDS.stop
    assert TUNING_SEEDS.stop < 2**31 - MAX_GENERATIONS  # fracnetics' int episode seeds


def test_help_imports_no_optuna() -> None:
    probe = (
        "from app.cli import main\n"
        "for argv in (['--help'], ['tune', '--help']):\n"
        "    try:\n"
        "        main(argv)\n"
        "    except SystemExit:\n"
        "        pass\n"
        "import json, sys\n"
        "print(json.dumps([m for m in ('optuna', 'sqlalchemy', 'gymnasium', 'numba') "
        "if m in sys.modules]))"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.strip().splitlines()[-1]) == []


def test_the_space_is_its_table_less_what_the_study_fixes() -> None:
    full = {p.path for p in space("gnp")}
    assert {"evolution.p_mutation", "controller.q0", "controller.tie_break"} <= full
    assert {"controller.processing_output", "evolution.p_add_delete"} <= full
    (branches,) = [p for p in space("gnp") if p.path == "controller.judgment_branches"]
    assert (branches.kind, branches.low, branches.high) == ("int", 2, 4)
    fuzzy = {p.path for p in space("gnp", fuzzy=True)}
    assert fuzzy == full - {"controller.judgment_branches"}  # k > 2 judges crisply only
    fixed = {"training.epsilon": 0.01, "controller.n_sub": 2}
    less = {p.path for p in space("gnp", fixed, population=4, method="RL")}
    assert less == full - {"controller.n_sub", "controller.skip_reward"} - {
        p for p in full if p.startswith("training.")
    }  # skip_reward acts in CS only
    box = {p.path for p in space("gnp", discrete=False)}
    assert box == full - {"controller.processing_output"}  # a Box action takes parameters
    (tournament,) = [p for p in space("gnp", population=4) if p.name.endswith("tournament_size")]
    assert tournament.high == 4
    drawn = {"training.epsilon_max": 0.2, "training.epsilon_min_share": 0.5}
    assert settings_of(space("gnp"), drawn) == {
        "training.schedule": "changing",
        "training.epsilon_max": 0.2,
        "training.epsilon_min": 0.1,
    }


def test_the_shipped_tuned_presets_are_presets_of_tuning_seeds() -> None:
    """The presets task experiments copy their tuned arms from (app/experiments/shipped/tuned/):
    each a valid preset, tuned on tuning seeds, a GNP one a valid task run for its task."""
    from app.settings.loading import build_config
    from app.tune.preset import read_preset, train_layer, train_task_table

    presets = sorted((ROOT / "app" / "experiments" / "shipped" / "tuned").glob("*.toml"))
    for path in presets:
        _, record = read_preset(path)
        assert record is not None, path
        assert all(seed in TUNING_SEEDS for seed in record.run_seeds), path
        first = record.validation_first_seed
        assert range(first, first + record.validation_episodes)[-1] in TUNING_SEEDS, path
        if record.brain == "gnp":
            config = build_config(train_layer(str(path), record.task))
            assert config.training.generations == record.generations, path
            train_task_table(str(path))
