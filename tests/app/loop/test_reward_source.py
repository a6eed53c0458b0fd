"""`reward.c_from`: C of Eq. 2.7 judged from the true readings (the default, which changes
nothing) or from what the controller sees (noise, then faults), in both phases."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from lab_fixtures import assert_same_data, tiny_config

import gnp
import sim
from app.brains.gnp_brain import gnp_trace
from app.brains.gnp_controllers import gnp_batch, gnp_of
from app.cli.parser import build_parser
from app.cli.train import config_from_args
from app.loop.recording import TrajectoryRecorder
from app.loop.rollout import Batch, rollout
from app.phases.implementation import implement
from app.phases.training import train
from app.settings.config import CFrom, ConfigError, RunConfig
from app.settings.loading import build_config, stored_config
from app.store import RunReader

CFG = gnp.GnpConfig(method="RL", n_sub=2, fuzzy=False)
N, T = 6, 100


def near_wall(readings: np.ndarray) -> np.ndarray:
    """C of Eq. 2.7 over the last axis, written out: every reading < 1000, one > 100."""
    return ((readings < 1000.0).all(axis=-1) & (readings > 100.0).any(axis=-1)).astype(float)


def row(*values: float) -> np.ndarray:
    out = np.zeros(8)
    out[: len(values)] = values
    return out


# (true readings, what the controller sees, C from the true ones, C from the seen ones)
CASES = [
    (row(50.0), row(130.0), 0.0, 1.0),  # noise lifts a far sensor over 100: a wall "appears"
    (row(150.0), row(90.0), 1.0, 0.0),  # noise drops the only near sensor under 100
    (row(990.0, 300.0), row(1010.0, 300.0), 1.0, 0.0),  # noise pushes a reading to touching
    (row(1005.0), row(995.0), 0.0, 1.0),  # and back under 1000
    (row(300.0, 50.0), row(340.0, 20.0), 1.0, 1.0),  # noise crossing no threshold
    (row(50.0, 60.0), row(80.0, 99.0), 0.0, 0.0),
    (row(150.0, 0.0, 0.0, 80.0), row(150.0, 0.0, 0.0, 120.0), 1.0, 1.0),  # 100 crossed, C kept
    (row(150.0), row(0.0), 1.0, 0.0),  # the one near sensor is dead (reads 0)
    (row(150.0, 200.0), row(0.0, 200.0), 1.0, 1.0),  # dead, but another sensor is near
    (row(150.0), row(1023.0), 1.0, 0.0),  # saturated: reads "touching"
    (row(50.0), row(1023.0), 0.0, 0.0),
]


@pytest.mark.parametrize(("true", "seen", "c_true", "c_seen"), CASES)
def test_c_by_hand(true: np.ndarray, seen: np.ndarray, c_true: float, c_seen: float) -> None:
    full_ahead = np.array([[10.0, 10.0]])  # speed 1, straightness 1: the reward is C
    for readings, expected in ((true, c_true), (seen, c_seen)):
        table = sim.reward_table(readings[None], full_ahead)
        assert table[0, 3] == expected
        assert table[0, 0] == expected


def _batch(noise: float, c_from: CFrom, faults: Sequence[sim.Fault] = (), n: int = N) -> Batch:
    """n robots of one family (same genomes, start poses and streams for equal arguments)."""
    arena = sim.load_arena("training")
    pop = gnp.init_population(CFG, n, np.random.default_rng(3))
    world = sim.World(arena, n=n, seed=0, noise_sigma=noise)
    world.reset(arena.start_poses[np.arange(n) % 10], seeds=1000 + np.arange(n))
    world.schedule_faults(faults)
    return gnp_batch(world, CFG, pop, 2000 + np.arange(n), c_from)


def _live(batch: Batch, steps: int = T) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(true readings after each step, what the controllers see after each step, C paid)."""
    recorder = TrajectoryRecorder(batch.size, steps, gnp_trace(CFG))
    rollout(batch, steps, 0.1, 0.1, recorder=recorder)
    life = recorder.trajectory(np.zeros(batch.size, np.int64))
    # What the controllers saw before step t + 1 is what they see after step t (same draws).
    seen_after = np.concatenate([life.observations[:, 1:], batch.world.observe()[:, None]], axis=1)
    return life.readings, seen_after, life.terms["reward/near_wall"]


def _crossed(true: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """Where some reading is on the other side of 100 or 1000 than its true value."""
    return (((true > 100.0) != (seen > 100.0)) | ((true < 1000.0) != (seen < 1000.0))).any(-1)


def test_observed_c_is_judged_from_the_noisy_readings() -> None:
    true, seen, c = _live(_batch(50.0, "observed"))
    assert np.array_equal(c, near_wall(seen))
    differ = c != near_wall(true)
    assert differ.sum() > 0  # σ = 50 moves readings across 100 at some of the 600 steps
    assert not np.any(differ & ~_crossed(true, seen))  # and only where a reading crossed


def test_true_c_ignores_noise() -> None:
    true, seen, c = _live(_batch(50.0, "true"))
    assert np.array_equal(c, near_wall(true))
    assert np.any(near_wall(seen) != c)  # the noise was there to be ignored


@pytest.mark.parametrize("sensor", [0, 5])
def test_a_dead_sensor_reads_zero_for_c(sensor: int) -> None:
    dead = [sim.Fault(0, (sensor,), "dead")]
    true, _, c = _live(_batch(0.0, "observed", dead))
    zeroed = true.copy()
    zeroed[..., sensor] = 0.0  # no noise: the controller sees the true readings, one at 0
    assert np.array_equal(c, near_wall(zeroed))
    assert np.any(c != near_wall(true))  # the sensor was the only near one at some steps
    true, _, c = _live(_batch(0.0, "true", dead))
    assert np.array_equal(c, near_wall(true))


def test_all_sensors_dead_earn_nothing_when_c_is_observed() -> None:
    dead = [sim.Fault(0, tuple(range(8)), "dead")]
    observed = rollout(_batch(0.0, "observed", dead), T, 0.1, 0.1)
    assert np.array_equal(observed.term_sums[:, 0], np.zeros(N))  # C = 0 at every step
    judged_true = rollout(_batch(0.0, "true", dead), T, 0.1, 0.1)
    assert np.any(judged_true.term_sums[:, 0] != 0.0)


def test_same_seed_same_lives() -> None:
    a, b = _batch(50.0, "observed"), _batch(50.0, "observed")
    first, second = rollout(a, T, 0.1, 0.1), rollout(b, T, 0.1, 0.1)
    assert np.array_equal(first.term_sums, second.term_sums)
    assert np.array_equal(gnp_of(a).population.q_ss, gnp_of(b).population.q_ss)
    assert np.array_equal(a.world.poses, b.world.poses)


def test_a_batch_refuses_an_unknown_source() -> None:
    with pytest.raises(ValueError, match="c_from must be one of"):
        _batch(0.0, "seen")  # type: ignore[arg-type]


# --- the setting: config, old files, CLI ------------------------------------------------------


def test_the_default_is_true_and_old_files_read_as_today() -> None:
    today = RunConfig()
    assert today.reward.c_from == "true"
    old = json.loads(today.model_dump_json())
    del old["reward"]  # a run file written before the setting existed
    assert stored_config(json.dumps(old)) == today
    observed = build_config({"reward": {"c_from": "observed"}})
    assert stored_config(observed.model_dump_json()) == observed != today


def test_the_cli_sets_it_and_names_a_bad_value() -> None:
    args = build_parser().parse_args(["train", "--set", "reward.c_from=observed"])
    assert config_from_args(args).reward.c_from == "observed"
    args = build_parser().parse_args(["train", "--set", "reward.c_from=seen"])
    with pytest.raises(ConfigError, match=r"reward\.c_from: .*'true'.*'observed'"):
        config_from_args(args)


# --- whole runs: training and implementation ---------------------------------------------------


def _observed_config() -> RunConfig:
    return build_config(
        tiny_config(noise_sigma=50.0).model_dump(), {"reward": {"c_from": "observed"}}
    )


def _seen_after(observations: np.ndarray) -> np.ndarray:
    """What a recorded robot saw after steps 0..T-2 (before steps 1..T-1)."""
    return observations[:, 1:]


def test_a_run_judges_c_from_what_its_robots_see_in_both_phases(tmp_path: Path) -> None:
    path = tmp_path / "observed.h5"
    train(_observed_config(), path, workers=1)
    implement(path, _observed_config().implementation.model_copy(), name="faulty")
    with RunReader(path) as run:
        assert run.config.reward.c_from == "observed"
        elite = run.elite()
        assert elite is not None
        trials = run.implementation("faulty").trials
    for life in (elite, trials):
        c = life.terms["reward/near_wall"][:, :-1]
        assert np.array_equal(c, near_wall(_seen_after(life.observations)))
        assert np.any(c != near_wall(life.readings[:, :-1]))
    # after the fault step (60), sensors 2 and 3 read 0 in what C is judged from
    assert np.all(trials.observations[:, 61:, 2:4] == 0.0)


def test_same_seed_same_run_for_any_worker_count(tmp_path: Path) -> None:
    one, two = tmp_path / "one.h5", tmp_path / "two.h5"
    train(_observed_config(), one, workers=1)
    train(_observed_config(), two, workers=2)
    assert_same_data(one, two)


def test_true_is_the_default_and_changes_nothing(tmp_path: Path, finished_run: Path) -> None:
    """A run that names c_from = "true" holds the same data as one that does not (the
    fixture, built as every run was before the setting existed), and its rewards are Eq. 2.7
    of the true readings. Without noise or faults (the fixture's training) the robots see the
    true readings, so "observed" changes nothing either."""
    for c_from in ("true", "observed"):
        named = tmp_path / f"{c_from}.h5"
        train(build_config(tiny_config().model_dump(), {"reward": {"c_from": c_from}}), named)
        assert_same_data(finished_run, named)
    with RunReader(tmp_path / "true.h5") as run:
        elite = run.elite()
        assert elite is not None
    assert np.array_equal(
        elite.terms["reward"][0],
        sim.reward_table(elite.readings[0], elite.commands[0])[:, 0],
    )
