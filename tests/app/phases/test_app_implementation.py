"""The implementation phase: faults, schedules, per-trial independence, what is stored."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import gnp
from app.brains.registry import family_of
from app.phases.implementation import (
    ImplementationError,
    check_name,
    default_name,
    epsilon_alpha_per_step,
    implement,
    run_implementation,
)
from app.settings.config import ImplementationSettings
from app.store import RunFileError, RunReader


def test_epsilon_alpha_schedule_by_hand() -> None:
    changing = ImplementationSettings(
        schedule="changing", epsilon=0.01, alpha=0.1, steps=3000, fault_step=500
    )
    eps, alpha = epsilon_alpha_per_step(changing)
    assert eps.shape == alpha.shape == (3000,)
    assert (eps[0], alpha[0]) == (eps[499], alpha[499]) == (0.01, 0.1)  # fixed until t'
    assert (eps[500], alpha[500]) == pytest.approx((0.015, 0.15))  # Eq. 4.3-4.4: max at t'
    assert (eps[1750], alpha[1750]) == pytest.approx((0.0075, 0.075))  # halfway, n = 1
    assert (eps[2999], alpha[2999]) == pytest.approx((0.015 / 2500, 0.15 / 2500))  # min 0 at T
    squared = changing.model_copy(update={"schedule_n": 2.0})
    eps, alpha = epsilon_alpha_per_step(squared)
    assert (eps[1750], alpha[1750]) == pytest.approx((0.015 / 4, 0.15 / 4))
    eps, alpha = epsilon_alpha_per_step(ImplementationSettings(epsilon=0.01, alpha=0.1))
    assert np.all(eps == 0.01) and np.all(alpha == 0.1)


def test_names() -> None:
    assert check_name("break-2.dead_1") == "break-2.dead_1"
    for bad in ("", "a/b", "../x", ".hidden", "x" * 65, "sp ace"):
        with pytest.raises(ImplementationError):
            check_name(bad)
    assert default_name(ImplementationSettings(broken_sensors=(3, 2))) == "break-2-3-dead-fixed"
    assert default_name(ImplementationSettings(noise_sigma=50)) == "no-fault-fixed-noise50"


def _settings(**changes: object) -> ImplementationSettings:
    base = {
        "steps": 120,
        "repeats": 1,
        "fault_step": 60,
        "broken_sensors": (2, 3),
        "recorded_trials": 3,
    }
    base.update(changes)
    return ImplementationSettings.model_validate(base)


def test_dead_sensors_and_stored_results(tmp_path: Path, finished_run: Path) -> None:
    path = tmp_path / "run.h5"
    shutil.copy(finished_run, path)
    result = implement(path, _settings(), name="dead")
    with RunReader(path) as run:
        stored = run.implementation("dead")
        assert run.implementation_names() == ["dead"]
    assert stored.generation == 2  # the final elite
    assert stored.settings == _settings()
    trials = stored.trials
    assert trials.poses.shape == (3, 120, 3)
    assert np.array_equal(stored.start_index, np.arange(10))
    # dead sensors read 0 from the fault step on; before it they see walls somewhere
    assert np.all(trials.observations[:, 60:, [2, 3]] == 0)
    assert np.any(trials.observations[:, :60, [2, 3]] > 0)
    # without noise, a healthy sensor shows the controller the true reading after the last step
    healthy = [0, 1, 4, 5, 6, 7]
    assert np.array_equal(trials.observations[:, 1:, healthy], trials.readings[:, :-1, healthy])
    # means: per trial, per step, after the fault, agree with one another
    assert np.allclose(trials.reward.mean(axis=1), stored.trial_mean_reward[:3])
    assert np.allclose(trials.reward[:, 60:].mean(axis=1), stored.trial_mean_after_fault[:3])
    assert stored.mean_reward == pytest.approx(stored.reward_per_step.mean())
    assert stored.mean_after_fault == pytest.approx(stored.reward_per_step[60:].mean())
    assert stored.mean_reward == pytest.approx(result.mean_reward)
    assert trials.trace["node"].shape[:2] == (3, 120)


def test_trials_do_not_depend_on_the_batch(finished_run: Path) -> None:
    with RunReader(finished_run) as run:
        family = family_of(run.config)
        individual = family.best(run)
    common = {"seed": 5, "control_period": 0.064, "name": "x", "generation": 2}
    one = run_implementation(family, individual, _settings(repeats=1), **common)  # type: ignore[arg-type]
    two = run_implementation(family, individual, _settings(repeats=2), **common)  # type: ignore[arg-type]
    assert np.array_equal(one.trial_mean_reward, two.trial_mean_reward[:10])
    assert np.array_equal(one.trials.poses, two.trials.poses)


def test_refuses_unfinished_runs_and_taken_names(tmp_path: Path, finished_run: Path) -> None:
    path = tmp_path / "run.h5"
    shutil.copy(finished_run, path)
    implement(path, _settings(recorded_trials=0), name="first")
    before = path.read_bytes()
    with pytest.raises(RunFileError, match="already has an implementation named 'first'"):
        implement(path, _settings(), name="first")
    assert path.read_bytes() == before
    with RunReader(path) as run:
        assert run.implementation("first").trials.poses.shape == (0, 120, 3)


def test_an_open_reader_sees_a_new_implementation_after_refresh(
    tmp_path: Path, finished_run: Path
) -> None:
    path = tmp_path / "run.h5"
    shutil.copy(finished_run, path)
    with RunReader(path) as run:
        assert run.implementation_names() == []
        implement(path, _settings(recorded_trials=1), name="later")
        run.refresh()  # the file was replaced by a copy holding the result
        assert run.implementation_names() == ["later"]
        assert run.implementation("later").trials.poses.shape == (1, 120, 3)


@pytest.mark.slow
def test_results_are_identical_for_any_number_of_workers(
    finished_run: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import app.phases.implementation as phase

    monkeypatch.setattr(phase, "TRIALS_PER_WORLD", 6)  # 30 trials: 1 recorded + 5 worlds
    with RunReader(finished_run) as run:
        family = family_of(run.config)
        individual = family.best(run)
    settings = _settings(repeats=3, recorded_trials=1, break_count=2, broken_sensors=())
    common = {"seed": 5, "control_period": 0.064, "name": "x", "generation": 2}
    seen: list[tuple[int, int]] = []
    one = run_implementation(family, individual, settings, workers=1, **common)  # type: ignore[arg-type]
    two = run_implementation(
        family,
        individual,
        settings,
        workers=2,
        progress=lambda done, total: seen.append((done, total)),
        **common,  # type: ignore[arg-type]
    )
    for field in ("reward_per_step", "trial_mean_reward", "trial_mean_after_fault"):
        assert np.array_equal(getattr(one, field), getattr(two, field)), field
    assert np.array_equal(one.trials.poses, two.trials.poses)
    assert one.mean_reward == two.mean_reward
    assert seen[-1] == (30 * 120, 30 * 120)
    assert [done for done, _ in seen] == sorted(done for done, _ in seen)


def test_k_random_sensors_break_per_trial_the_same_for_every_individual(
    finished_run: Path,
) -> None:
    with RunReader(finished_run) as run:
        family = family_of(run.config)
        individual = family.best(run)
        cfg = family.graph_config
    settings = _settings(repeats=2, recorded_trials=20, break_count=3, broken_sensors=())
    result = run_implementation(
        family, individual, settings, seed=11, control_period=0.064, name="x", generation=2
    )
    dead_after = np.all(result.trials.observations[:, 61:] == 0, axis=1)  # (trials, 8)
    draws = phase_draws(11, 20, 3)
    expected = np.zeros((20, 8), bool)
    np.put_along_axis(expected, draws, True, axis=1)
    # Each trial's drawn sensors read 0 from the fault on (a healthy one sees a wall sometime).
    assert np.all(dead_after[expected])
    assert np.all(dead_after.sum(axis=1) >= 3)
    assert len({tuple(row) for row in draws}) > 5  # trials draw different sets
    # Another individual (another arm of an experiment) meets the same broken sensors.
    other = gnp.init_population(cfg, 1, np.random.default_rng(99))
    again = run_implementation(
        family, other, settings, seed=11, control_period=0.064, name="y", generation=0
    )
    assert np.all(np.all(again.trials.observations[:, 61:] == 0, axis=1)[expected])


def phase_draws(seed: int, trials: int, k: int) -> np.ndarray:
    from app.loop.seeds import broken_sensor_draws

    return broken_sensor_draws(seed, np.arange(trials), k, 8)


def test_a_fixed_set_and_k_random_sensors_exclude_each_other() -> None:
    with pytest.raises(ValueError, match="either broken_sensors"):
        _settings(break_count=2)
    assert default_name(_settings(broken_sensors=(), break_count=2)) == "break-2-random-dead-fixed"
