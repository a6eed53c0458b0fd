"""GNP on Gymnasium tasks: scaling, action mapping, faults, batched lives, training, CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import h5py
import numpy as np
import pytest
from gymnasium import spaces

import gnp
from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.cli import main
from app.phases.generations import Interrupted
from app.store import TASK, RunReader
from app.tasks import (
    BatchEnv,
    ObservationFault,
    ObservationFaults,
    TaskError,
    TaskRunConfig,
    TaskSettings,
    TaskTraining,
    read_task_run,
    replay_episodes,
    replay_task,
    resume_task,
    task_adapter,
    train_task,
)
from app.tasks.gnp_lives import live
from app.tasks.training import first_population
from gnp import Schedule

BOX4 = spaces.Box(-1.0, 1.0, (4,), np.float32)


# --- scaling and actions, by hand -------------------------------------------------------------


def test_cartpole_features_scale_by_the_space_and_the_documented_velocity_bounds() -> None:
    env = gym.make("CartPole-v1")
    adapter = task_adapter("CartPole-v1", env.observation_space, env.action_space)
    assert (adapter.n_inputs, adapter.n_outputs, adapter.kind) == (4, 1, "discrete")
    np.testing.assert_allclose(adapter.obs_low, [-4.8, -3.0, -0.41887903, -3.5], rtol=1e-6)
    obs = np.array([[0.0, 1.5, 0.41887903, -9.0], [4.8, -3.0, -0.2094395, 3.5]])
    np.testing.assert_allclose(
        adapter.observe(obs),
        [[511.5, 767.25, 1023.0, 0.0], [1023.0, 0.0, 1023 / 4, 1023.0]],
        rtol=1e-6,
    )


def test_given_bounds_replace_the_space_and_unbounded_features_are_refused() -> None:
    space = spaces.Box(-np.inf, np.inf, (2,), np.float64)
    with pytest.raises(TaskError, match=r"^Foo-v0: observation feature 0 is unbounded"):
        task_adapter("Foo-v0", space, spaces.Discrete(2))
    adapter = task_adapter("Foo-v0", space, spaces.Discrete(2), (-2.0, 0.0), (2.0, 10.0))
    np.testing.assert_allclose(adapter.observe(np.array([[1.0, 5.0]])), [[767.25, 511.5]])
    half = task_adapter("Foo-v0", BOX4, spaces.Discrete(2), (None, 0.0, None, None), None)
    np.testing.assert_allclose(
        half.observe(np.array([[0.0, 0.5, 0.0, 1.0]])), [[511.5] * 3 + [1023]]
    )
    with pytest.raises(TaskError, match="obs_low gives 1 bounds, the observation feature has 4"):
        task_adapter("Foo-v0", BOX4, spaces.Discrete(2), (0.0,))
    with pytest.raises(TaskError, match="needs low < high"):
        task_adapter("Foo-v0", BOX4, spaces.Discrete(2), None, (-2.0, 1.0, 1.0, 1.0))


def test_discrete_actions_are_equal_bins_of_the_output() -> None:
    two = task_adapter("T", BOX4, spaces.Discrete(2))
    commands = np.array([[-10.0], [-0.5], [0.0], [10.0]])
    np.testing.assert_array_equal(two.act(commands), [0, 0, 1, 1])
    three = task_adapter("T", BOX4, spaces.Discrete(3, start=-1))
    commands = np.array([[-10.0], [-4.0], [0.0], [3.4], [10.0]])
    np.testing.assert_array_equal(three.act(commands), [-1, -1, 0, 1, 1])


def test_box_actions_map_each_output_to_its_bounds_in_function_order() -> None:
    low, high = np.array([-2.0, 0.0], np.float32), np.array([2.0, 1.0], np.float32)
    action = spaces.Box(low, high, dtype=np.float32)
    adapter = task_adapter("T", BOX4, action)
    assert adapter.n_outputs == 2
    # gnp.step's column k − 1 − j holds output j: [[output 1, output 0]].
    got = adapter.act(np.array([[10.0, -10.0], [0.0, 5.0], [-5.0, 0.0]]))
    np.testing.assert_allclose(got, [[-2.0, 1.0], [1.0, 0.5], [0.0, 0.25]])
    assert got.dtype == np.float32
    with pytest.raises(TaskError, match="action 0 is unbounded"):
        task_adapter("T", BOX4, spaces.Box(-np.inf, np.inf, (1,)))


@pytest.mark.parametrize(
    ("obs", "act", "says"),
    [
        (spaces.Box(0, 255, (8, 8, 3), np.uint8), spaces.Discrete(2), "flat Box of features"),
        (spaces.Dict({"a": BOX4}), spaces.Discrete(2), "flat Box of features"),
        (BOX4, spaces.MultiDiscrete([2, 3]), "Discrete action or a flat Box"),
        (BOX4, spaces.Box(-1, 1, (2, 2)), "Discrete action or a flat Box"),
        (spaces.Box(-1, 1, (200,)), spaces.Discrete(2), "200 observation features"),
    ],
)
def test_spaces_gnp_cannot_judge_or_emit_are_one_line(
    obs: spaces.Space, act: spaces.Space, says: str
) -> None:
    with pytest.raises(TaskError, match=says) as error:
        task_adapter("T", obs, act)
    assert "\n" not in str(error.value)


# --- observation faults -----------------------------------------------------------------------


@pytest.mark.parametrize("mode", ["dead", "saturated", "stuck", "random"])
def test_observation_faults_break_features_from_their_step(mode: str) -> None:
    env = gym.make("CartPole-v1")
    low, high = np.array([-4.8, -3.0, -0.42, -3.5]), np.array([4.8, 3.0, 0.42, 3.5])
    fault = ObservationFault(step=2, features=(1, 3), mode=mode)  # type: ignore[arg-type]
    broken = ObservationFaults(gym.make("CartPole-v1"), [fault], low, high, seed=7)
    true, _ = env.reset(seed=3)
    seen, _ = broken.reset(seed=3)
    rows = [(true, seen)]
    for _ in range(4):
        true = env.step(1)[0]
        seen = broken.step(1)[0]
        rows.append((true, seen))
    for t, (x, y) in enumerate(rows):
        np.testing.assert_array_equal(y[[0, 2]], x[[0, 2]])  # healthy features
        if t < 2:
            np.testing.assert_array_equal(y, x)
        elif mode == "dead":
            np.testing.assert_array_equal(y[[1, 3]], np.float32(low[[1, 3]]))
        elif mode == "saturated":
            np.testing.assert_array_equal(y[[1, 3]], np.float32(high[[1, 3]]))
        elif mode == "stuck":
            np.testing.assert_array_equal(y[[1, 3]], rows[2][0][[1, 3]])
        else:
            assert np.all((y[[1, 3]] >= low[[1, 3]]) & (y[[1, 3]] <= high[[1, 3]]))
            assert y[1] != rows[2][1][1] or t == 2
    again = ObservationFaults(gym.make("CartPole-v1"), [fault], low, high, seed=7)
    again.reset(seed=3)
    later = [again.step(1)[0] for _ in range(4)]
    np.testing.assert_array_equal(later[-1], rows[-1][1])  # seeded: the same draws


def test_a_replay_is_seeded_and_faults_reach_the_brain(tmp_path: Path) -> None:
    run = train_task(_config(generations=2), tmp_path / "f.h5")
    healthy = [replay_task(run, seed) for seed in range(6)]
    assert healthy == [replay_task(run, seed) for seed in range(6)]
    dead = (ObservationFault(step=0, features=(0, 1, 2, 3), mode="saturated"),)
    broken = [replay_task(run, seed, faults=dead) for seed in range(6)]
    assert broken == [replay_task(run, seed, faults=dead) for seed in range(6)]
    assert broken != healthy
    batch = replay_episodes(run, list(range(6)), faults=dead)
    assert batch.returns.tolist() == [r.episode_return for r in broken]
    assert batch.lengths.tolist() == [r.length for r in broken]


def test_fault_settings_are_checked() -> None:
    low, high = -np.ones(4), np.ones(4)
    with pytest.raises(TaskError, match=r"fault features \[4\] outside 0..3"):
        ObservationFaults(gym.make("CartPole-v1"), [ObservationFault(0, (4,))], low, high)


# --- batched lives ----------------------------------------------------------------------------


def _one_by_one(
    task: str, cfg: gnp.GnpConfig, pop: gnp.Population, seeds: list[int], max_steps: int
) -> tuple[np.ndarray, np.ndarray, gnp.Population]:
    """Each individual alone with the plain single env: the oracle of a batch."""
    returns, lengths, learned = [], [], []
    for i, seed in enumerate(seeds):
        env = gym.make(task)
        adapter = task_adapter(task, env.observation_space, env.action_space)
        one = gnp.take(pop, [i])
        state = gnp.init_state(cfg, 1, [seed + 1])
        obs, _ = env.reset(seed=seed)
        total, steps, reward = 0.0, 0, np.zeros(1)
        for _ in range(max_steps):
            readings = adapter.observe(np.asarray(obs)[None])
            commands, _ = gnp.step(cfg, one, state, readings, reward, 0.1, 0.1)
            obs, r, terminated, truncated, _ = env.step(adapter.act(commands)[0])
            total += float(r)
            steps += 1
            reward = np.array([float(r)])
            if terminated:
                gnp.end_episode(cfg, one, state, reward, 0.1)
            if terminated or truncated:
                break
        returns.append(total)
        lengths.append(steps)
        learned.append(one)
    return np.array(returns), np.array(lengths), gnp.concat(learned)


@pytest.mark.parametrize(
    ("task", "mode", "max_steps"),
    [
        ("CartPole-v1", "fast", 500),
        ("MountainCar-v0", "fast", 200),
        ("Acrobot-v1", "fast", 500),
        ("CartPole-v1", "vector_entry_point", 500),
        ("MountainCar-v0", "sync", 60),
        ("Acrobot-v1", "sync", 40),
        ("Pendulum-v1", "sync", 40),
        ("Pendulum-v1", "twin", 250),  # GNP on a Box action: a batch of twins
    ],
)
def test_a_batch_lives_as_each_individual_alone_with_the_single_env(
    task: str, mode: str, max_steps: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    if mode not in ("fast", "twin"):  # the Gymnasium path
        monkeypatch.setattr("app.tasks.dynamics.FAST_TASKS", {})
    config = TaskRunConfig(
        seed=4, task=TaskSettings(id=task), training=TaskTraining(population=12, steps=max_steps)
    )
    cfg, adapter = config.gnp_config(), config.adapter
    pop = first_population(config)
    seeds = [int(s) for s in np.arange(12) * 101 + 5]
    env = BatchEnv(task, 12, adapter)
    assert env.mode == mode
    got = live(cfg, adapter, env, pop, seeds, [s + 1 for s in seeds], 0.1, 0.1, max_steps)
    returns, lengths, learned = _one_by_one(task, cfg, pop, seeds, max_steps)
    np.testing.assert_array_equal(got.returns, returns)
    np.testing.assert_array_equal(got.lengths, lengths)
    for name, value in gnp.population_to_arrays(learned).items():
        np.testing.assert_array_equal(getattr(got.learned, name), value, err_msg=name)
    assert len(set(lengths.tolist())) > 1 or task != "CartPole-v1"  # episodes end apart
    assert not np.array_equal(got.learned.q_ss, pop.q_ss)  # it learned; pop is left alone
    assert not pop.q_ss.any()


# --- training ---------------------------------------------------------------------------------


def _config(generations: int = 3, population: int = 20, seed: int = 5) -> TaskRunConfig:
    return TaskRunConfig(
        seed=seed,
        task=TaskSettings(id="CartPole-v1"),
        training=TaskTraining(population=population, generations=generations),
    )


def test_same_config_and_seed_give_the_same_run_and_a_resumed_run_matches(
    tmp_path: Path,
) -> None:
    a = train_task(_config(), tmp_path / "a.h5")
    b = train_task(_config(), tmp_path / "b.h5")
    first, second = read_task_run(a), read_task_run(b)
    np.testing.assert_array_equal(first.fitness, second.fitness)
    assert first.fitness.shape == (3, 20)
    with h5py.File(a, "r") as handle:  # a run file of kind "task" (docs/run-format.md)
        assert handle.attrs["format"] == "gnp-lab-run" and handle.attrs["kind"] == "task"
        assert json.loads(handle.attrs["config"])["task"]["id"] == "CartPole-v1"

    def stop_after_one(_summary: object) -> None:
        raise KeyboardInterrupt

    cut = tmp_path / "cut.h5"
    with pytest.raises(Interrupted):  # the lab's one loop stops after a complete generation
        train_task(_config(), cut, stop_after_one)
    assert read_task_run(cut).generation_done == 1
    resume_task(cut)
    np.testing.assert_array_equal(read_task_run(cut).fitness, first.fitness)
    other = read_task_run(train_task(_config(seed=6), tmp_path / "c.h5"))
    assert not np.array_equal(other.fitness, first.fitness)


def _cut_and_resumed(config: TaskRunConfig, tmp_path: Path) -> tuple[Path, Path]:
    """(a whole run, the same run cut after its first generation and resumed): their files."""
    whole = train_task(config, tmp_path / "whole.h5")

    def stop_after_one(_summary: object) -> None:
        raise KeyboardInterrupt

    cut = tmp_path / "cut.h5"
    with pytest.raises(Interrupted):
        train_task(config, cut, stop_after_one)
    resume_task(cut)
    return whole, cut


def _same_last_population(whole: Path, cut: Path) -> dict[str, np.ndarray]:
    """Both runs' last checkpoints, every field to the bit; returns the whole run's."""
    with RunReader(whole, TASK) as a, RunReader(cut, TASK) as b:
        last_a, last_b = a.checkpoint(), b.checkpoint()
        assert last_a is not None and last_b is not None and last_a[0] == last_b[0]
        for name, values in last_a[1].items():
            np.testing.assert_array_equal(values, last_b[1][name])
        return last_a[1]


def test_a_run_with_add_delete_node_mutation_trains_and_resumes_to_the_bit(
    tmp_path: Path,
) -> None:
    def config(p_add_delete: float) -> TaskRunConfig:
        evolution = gnp.EvolutionConfig(p_mutation=0.05, p_add_delete=p_add_delete)
        return _config(generations=4).model_copy(update={"brain": GnpSettings(evolution=evolution)})

    whole, cut = _cut_and_resumed(config(0.3), tmp_path)
    first, resumed = read_task_run(whole), read_task_run(cut)
    assert resumed.config.brain.evolution.p_add_delete == 0.3
    np.testing.assert_array_equal(resumed.fitness, first.fitness)
    _same_last_population(whole, cut)
    off = read_task_run(train_task(config(0.0), tmp_path / "off.h5"))
    np.testing.assert_array_equal(off.fitness[0], first.fitness[0])  # generation 0 is shared
    assert not np.array_equal(off.fitness, first.fitness)  # the setting reaches evolution


def test_a_run_with_multi_way_judgment_trains_and_resumes_to_the_bit(tmp_path: Path) -> None:
    def config(k: int) -> TaskRunConfig:
        controller = ControllerSettings(method="BS", fuzzy=False, judgment_branches=k)
        return _config(generations=3).model_copy(
            update={"brain": GnpSettings(controller=controller)}
        )

    whole, cut = _cut_and_resumed(config(3), tmp_path)
    first, resumed = read_task_run(whole), read_task_run(cut)
    assert resumed.config.brain.controller.judgment_branches == 3
    np.testing.assert_array_equal(resumed.fitness, first.fitness)
    last = _same_last_population(whole, cut)
    assert last["conn"].shape[3] == 3  # the branch axis has k entries
    _, best = first.best_genome(2)
    assert best.conn.shape[3] == 3
    two = read_task_run(train_task(config(2), tmp_path / "two.h5"))
    assert not np.array_equal(two.fitness, first.fitness)  # the setting reaches the walk


@pytest.mark.slow
def test_a_short_cartpole_training_beats_its_first_generation(tmp_path: Path) -> None:
    # GNP-RL, crisp, ε = 0.01 (examples/gnp_cartpole.py): on seed 1 the best balances the
    # pole for 500 steps, the most an episode gives, from generation 7 on.
    config = TaskRunConfig(
        seed=1,
        task=TaskSettings(id="CartPole-v1"),
        brain=GnpSettings(controller=ControllerSettings(method="RL", fuzzy=False)),
        training=TaskTraining(population=100, generations=10, epsilon=Schedule.fixed(0.01)),
    )
    run = read_task_run(train_task(config, tmp_path / "r.h5"))
    best, mean = run.fitness.max(axis=1), run.fitness.mean(axis=1)
    assert best[-3:].min() > 3 * best[0]
    assert mean[-3:].mean() > 5 * mean[0]


# --- command line -----------------------------------------------------------------------------


def _stop(_summary: object) -> None:
    raise KeyboardInterrupt


def test_cli_trains_resumes_replays_and_exports_a_task_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cp.h5"
    argv = ["train", "--task", "CartPole-v1", "--generations", "2", "--population", "10"]
    assert main([*argv, "--seed", "3", "--method", "RL", "--out", str(out), "--quiet"]) == 0
    assert "best return" in capsys.readouterr().out
    assert read_task_run(out).config.brain.controller.method == "RL"
    assert main(["replay", "cp", "--runs-dir", str(tmp_path), "--seed", "9"]) == 0
    said = capsys.readouterr().out
    expected = replay_task(out, 9)
    assert said.startswith(f"return {expected.episode_return:.1f} in {expected.length} steps")
    faulty = ["--fault-features", "0,2", "--fault-mode", "saturated", "--greedy"]
    assert main(["replay", "cp", "--runs-dir", str(tmp_path), *faulty, "--episodes", "5"]) == 0
    saturated = (ObservationFault(0, (0, 2), "saturated"),)
    lives = replay_episodes(out, [0, 1, 2, 3, 4], faults=saturated, epsilon=0.0)
    said = capsys.readouterr().out
    assert said.startswith(f"mean return {lives.returns.mean():.1f} ± ")
    assert "over 5 episodes, seeds 0..4" in said
    assert main(["export", "cp", "--runs-dir", str(tmp_path), "--out", str(tmp_path / "x")]) == 0
    from app.brains.registry import load_controller

    controller = load_controller(tmp_path / "x" / "controller.json")
    assert controller.settings["task"]["id"] == "CartPole-v1"
    assert controller.cfg.n_inputs == 4  # type: ignore[union-attr]
    assert main([*argv, "--print-config"]) == 0
    assert '"id": "CartPole-v1"' in capsys.readouterr().out
    assert main(["train", "--resume", str(out), "--task", "Acrobot-v1"]) == 2
    assert "drop --task" in capsys.readouterr().err
    cut = tmp_path / "cut.h5"
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("app.tasks.cli._progress", lambda _quiet: _stop)
        assert main([*argv, "--seed", "3", "--out", str(cut), "--quiet"]) == 130
    assert f"continue with: gnp-lab train --resume {cut}" in capsys.readouterr().err
    assert read_task_run(cut).generation_done == 1
    assert main(["train", "--resume", str(cut), "--quiet"]) == 0
    assert read_task_run(cut).generation_done == 2
    assert main(["runs", "--runs-dir", str(tmp_path)]) == 0
    listed = capsys.readouterr().out  # a task run is listed as one, not as unreadable
    assert "task CartPole-v1" in listed and "unreadable" not in listed
    assert main(["runs", "cp", "--runs-dir", str(tmp_path)]) == 0
    said = capsys.readouterr().out
    assert said.startswith("task run cp.h5: CartPole-v1, seed 3")
    assert f"best return {read_task_run(out).fitness[1].max():.1f}" in said
    assert main(["train", "--resume", str(out)]) == 1  # finished
    assert "finished run; there is nothing to resume" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("task", "extra", "says"),
    [
        ("Nope-v0", [], "unknown task 'Nope-v0'"),
        ("Blackjack-v1", [], "GNP judges a flat Box of features"),
        ("CartPole-v1", ["--set", "task.obs_low=[1.0]"], "obs_low gives 1 bounds"),
        ("CartPole-v1", ["--set", "task.speed=[1.0]"], "task.speed: unknown"),
        ("CartPole-v1", ["--brain", "nope"], "unknown brain family 'nope'"),
    ],
)
def test_cli_bad_tasks_are_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], task: str, extra: list[str], says: str
) -> None:
    out = tmp_path / "x.h5"
    assert main(["train", "--task", task, *extra, "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("gnp-lab: error: ") and says in err
    assert err.count("\n") == 1
    assert not out.exists()


def test_cli_trains_a_box_action_task_with_bounds_given(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "pendulum.h5"
    argv = ["train", "--task", "Pendulum-v1", "--generations", "2", "--population", "6"]
    bounds = ["--set", "task.obs_high=[0.5, nan, 4.0]", "--steps", "20"]
    assert main([*argv, *bounds, "--out", str(out), "--quiet"]) == 0
    run = read_task_run(out)
    assert run.config.task.obs_high == (0.5, None, 4.0)
    adapter = run.config.adapter
    np.testing.assert_allclose(adapter.obs_high, [0.5, 1.0, 4.0])
    np.testing.assert_allclose(adapter.act_low, [-2.0])
    assert run.config.gnp_config().n_outputs == 1
    assert run.fitness.shape == (2, 6) and np.all(run.fitness < 0)
    assert main(["replay", "pendulum", "--runs-dir", str(tmp_path), "--seed", "2"]) == 0
    assert "in 20 steps (seed 2)" in capsys.readouterr().out


def test_the_lab_imports_gymnasium_only_for_a_task() -> None:
    code = (
        "import sys, app.cli, app.export.cli\n"
        "assert 'gymnasium' not in sys.modules, 'gnp-lab imported gymnasium'\n"
        "from app.tasks import train_task\n"
        "assert 'gymnasium' in sys.modules\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
