"""GnpLab/WallFollow-v0: Gymnasium's checks, the lab's world as the oracle, faults, seeding."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
import warnings
from collections.abc import Callable, Iterator
from importlib import import_module
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env, data_equivalence
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from hypothesis import given, settings
from hypothesis import strategies as st

import sim
from sim import LIFE_STEPS
from sim.gym_env import ENV_ID, WallFollowEnv
from sim.gym_vector import WallFollowVectorEnv

ROOT = Path(__file__).resolve().parents[2]
ACTION_ADVICE = "symmetric and normalized"
"""Gymnasium's advice for Box actions in [-1, 1]: the task's commands are −10..10 (issue #34)."""


def gymnasium_warnings(check: Callable[[], None]) -> list[str]:
    """What Gymnasium warned while running `check`, its advice on action ranges aside."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check()
    return [str(w.message) for w in caught if ACTION_ADVICE not in str(w.message)]


def held(rng: np.random.Generator, steps: int, n: int) -> np.ndarray:
    """(steps, n, 2) commands held for 8 steps, mostly forward, so robots reach walls."""
    blocks = np.abs(rng.uniform(-10, 10, (steps // 8 + 1, n, 2)))
    blocks[:, :, 0] *= np.where(rng.random((steps // 8 + 1, n)) < 0.3, -1, 1)
    return np.repeat(blocks, 8, axis=0)[:steps]


# --- Gymnasium's own checks ---


@pytest.mark.parametrize(
    ("arena", "noise", "physics"),
    [("training", 0.0, "pymunk"), ("implementation", 50.0, "pymunk"), ("training", 50, "analytic")],
)
def test_check_env_passes(arena: str, noise: float, physics: str) -> None:
    env = gym.make(ENV_ID, arena=arena, noise=noise, physics=physics)
    assert env.spec is not None and env.spec.max_episode_steps == LIFE_STEPS
    assert gymnasium_warnings(lambda: check_env(env.unwrapped)) == []
    rendering = gym.make(ENV_ID, arena=arena, render_mode="rgb_array")
    assert gymnasium_warnings(lambda: check_env(rendering.unwrapped)) == []


def check_vector_env(envs: VectorEnv, seed: int = 7) -> None:
    """The vector API as Gymnasium documents it (1.4 has no vector check_env): batched spaces,
    reset and step types and shapes within them, seeding determinism, fresh arrays."""
    n = envs.num_envs
    assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert envs.observation_space == batch_space(envs.single_observation_space, n)
    assert envs.action_space == batch_space(envs.single_action_space, n)
    first, info = envs.reset(seed=seed)
    again, _ = envs.reset(seed=seed)
    assert isinstance(info, dict)
    assert first in envs.observation_space and first.dtype == envs.observation_space.dtype
    assert data_equivalence(first, again, exact=True) and first is not again
    envs.action_space.seed(seed)
    actions = [envs.action_space.sample() for _ in range(3)]
    runs = []
    for _ in range(2):
        envs.reset(seed=seed)
        runs.append([envs.step(a) for a in actions])
    for one, two in zip(*runs, strict=True):
        obs, reward, terminated, truncated, info = one
        assert obs in envs.observation_space
        assert reward.shape == terminated.shape == truncated.shape == (n,)
        assert reward.dtype == np.float64 and terminated.dtype == truncated.dtype == np.bool_
        assert isinstance(info, dict)
        assert data_equivalence(one, two, exact=True)
    assert not np.shares_memory(runs[0][0][0], runs[0][1][0])
    other, _ = envs.reset(seed=seed + 1000)
    assert not np.array_equal(first, other)


@pytest.mark.parametrize("noise", [0.0, 50.0])
def test_vector_env_passes_gymnasiums_vector_checks(noise: float) -> None:
    made: list[VectorEnv] = []
    assert gymnasium_warnings(lambda: made.append(gym.make_vec(ENV_ID, 5, noise=noise))) == []
    envs = made[0]  # make_vec warns if the metadata lacks an autoreset mode: none here
    assert isinstance(envs, WallFollowVectorEnv)  # the vector entry point, not SyncVectorEnv
    assert gymnasium_warnings(lambda: check_vector_env(envs)) == []


def test_the_vector_env_is_syncvectorenv_of_the_single_env_bit_for_bit() -> None:
    """Same seed and actions: the batched world gives what Gymnasium's SyncVectorEnv of N single
    envs gives, autoreset (next step) included, a fault option too."""
    kwargs = {"num_envs": 4, "noise": 50.0, "max_episode_steps": 6}
    ours = gym.make_vec(ENV_ID, vectorization_mode="vector_entry_point", **kwargs)
    sync = gym.make_vec(ENV_ID, vectorization_mode="sync", **kwargs)
    options = {"fault": {"mode": "stuck", "sensors": [1, 2], "step": 3}}
    got = [e.reset(seed=11, options=options) for e in (ours, sync)]
    assert data_equivalence(got[0], got[1], exact=True)
    commands = held(np.random.default_rng(0), 15, 4)
    for t, command in enumerate(commands):
        a, b = ours.step(command), sync.step(command)
        assert data_equivalence(a, b, exact=True), f"step {t}"
        assert a[3].all() == (t in (5, 12))  # truncated together; step 6 is the autoreset
    assert data_equivalence(ours.reset(seed=[3, 4, 5, 6]), sync.reset(seed=[3, 4, 5, 6]))


# --- the lab's own world as the oracle ---


def by_hand(
    seed: int, commands: np.ndarray, noise: float, c_from: sim.reward.CFrom = "true"
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """What the lab's world and reward give for one robot whose episode `seed` draws (as
    Gymnasium seeds np_random): the first observation, then each step's observation and terms."""
    rng = np.random.default_rng(seed)
    start, stream = int(rng.integers(sim.N_START_POSES)), int(rng.integers(2**63))
    world = sim.World(sim.load_arena("training"), n=1, noise_sigma=noise)
    world.reset(world.arena.start_poses[[start]], seeds=[stream])
    yield world.observe()[0], np.zeros(len(sim.TERM_NAMES))
    for command in commands:
        world.step(command[None])
        judged = world.sense() if c_from == "true" else world.observe()
        yield world.observe()[0], sim.reward_table(judged, command[None])[0]


@pytest.mark.parametrize("c_from", ["true", "observed"])
def test_reward_and_observations_are_the_labs_bit_for_bit(c_from: sim.reward.CFrom) -> None:
    commands = held(np.random.default_rng(1), 200, 1)[:, 0] * 1.2  # some beyond ±10: clipped
    env = WallFollowEnv(noise=50.0, c_from=c_from)
    expected = by_hand(5, commands, 50.0, c_from)
    obs, _ = env.reset(seed=5)
    assert np.array_equal(obs, next(expected)[0])
    near_wall = 0.0
    for command, (seen, terms) in zip(commands, expected, strict=False):
        obs, reward, terminated, truncated, info = env.step(command)
        assert np.array_equal(obs, seen) and reward == terms[0]
        assert [info[name] for name in sim.TERM_NAMES] == terms.tolist()
        assert not terminated and not truncated
        near_wall += info["reward/near_wall"]
    assert near_wall > 0  # the commands did bring the robot to a wall


def test_same_seed_same_episode_different_seeds_differ() -> None:
    env = gym.make(ENV_ID, noise=50.0)
    commands = held(np.random.default_rng(2), 60, 1)[:, 0]

    def episode(seed: int | None) -> list[Any]:
        out: list[Any] = [env.reset(seed=seed)[0]]
        out += [env.step(c)[:2] for c in commands]
        return out

    one, two, three = episode(9), episode(9), episode(10)
    assert data_equivalence(one, two, exact=True)
    assert not data_equivalence(one, three)
    assert not data_equivalence(one, episode(None))  # the next episode of the same stream


def test_episodes_are_truncated_after_a_training_life() -> None:
    env = gym.make(ENV_ID, max_episode_steps=5)
    env.reset(seed=0)
    flags = [env.step(np.array([3.0, 3.0]))[3] for _ in range(5)]
    assert flags == [False] * 4 + [True]
    assert LIFE_STEPS == 1000  # thesis Table 2.4: a training life


# --- faults ---


def fault_run(mode: str, sensors: list[int], step: int, seed: int) -> tuple[np.ndarray, ...]:
    commands = held(np.random.default_rng(seed), 30, 1)[:, 0]
    env = WallFollowEnv(noise=50.0)
    runs = []
    for options in ({}, {"fault": {"mode": mode, "sensors": sensors, "step": step}}):
        obs = [env.reset(seed=seed, options=options)[0]]
        rewards = []
        for c in commands:
            o, r, *_ = env.step(c)
            obs.append(o)
            rewards.append(r)
        runs += [np.array(obs), np.array(rewards)]
    return tuple(runs)


@settings(max_examples=12, deadline=None)
@given(
    mode=st.sampled_from(sim.FAULT_MODES),
    sensors=st.lists(st.integers(0, 7), min_size=1, max_size=8, unique=True),
    step=st.integers(0, 25),
    seed=st.integers(0, 2**32),
)
def test_a_fault_option_breaks_the_named_sensors_from_its_step(
    mode: str, sensors: list[int], step: int, seed: int
) -> None:
    healthy, healthy_reward, broken, broken_reward = fault_run(mode, sensors, step, seed)
    others = [s for s in range(8) if s not in sensors]
    assert np.array_equal(healthy[:step], broken[:step])  # nothing before its step
    assert np.array_equal(healthy[:, others], broken[:, others])  # only the named sensors
    assert np.array_equal(healthy_reward, broken_reward)  # C from the true readings
    after = broken[step:, sensors]
    if mode == "dead":
        assert np.all(after == 0)
    elif mode == "saturated":
        assert np.all(after == sim.IR_MAX)
    elif mode == "stuck":
        assert np.all(after == healthy[step, sensors])  # what they showed when they broke
    else:
        assert np.all((after >= 0) & (after <= sim.IR_MAX))
        assert not np.array_equal(after, healthy[step:, sensors])


def test_the_envs_own_fault_fires_every_episode_and_an_option_replaces_it() -> None:
    env = WallFollowEnv(fault={"mode": "saturated", "sensors": 6})
    for _ in range(2):
        assert env.reset()[0][6] == sim.IR_MAX
    obs, _ = env.reset(options={"fault": [{"sensors": [0], "mode": "dead", "step": 0}]})
    assert obs[0] == 0 and obs[6] < sim.IR_MAX
    assert env.reset()[0][6] == sim.IR_MAX


def test_a_vector_fault_may_name_robots() -> None:
    envs = WallFollowVectorEnv(3, start=4)
    obs, _ = envs.reset(
        seed=0, options={"fault": {"sensors": [2], "mode": "saturated", "robots": [1]}}
    )
    assert obs[:, 2].tolist()[1] == sim.IR_MAX and obs[[0, 2], 2].max() < sim.IR_MAX


# --- bad input: one clear line naming the problem ---


@pytest.mark.parametrize(
    ("make", "error", "message"),
    [
        (lambda: WallFollowEnv(arena="nope"), sim.ArenaError, "unknown arena 'nope'"),
        (lambda: WallFollowEnv(noise=-1.0), sim.WorldError, "noise .* must be a number ≥ 0"),
        (lambda: WallFollowEnv(physics="box2d"), sim.WorldError, "unknown physics 'box2d'"),
        (lambda: WallFollowEnv(c_from="both"), sim.WorldError, "unknown c_from 'both'"),
        (lambda: WallFollowEnv(start=10), sim.WorldError, "start 10 is not a start pose"),
        (
            lambda: WallFollowEnv(fault={"sensors": [1], "mode": "on fire"}),
            sim.WorldError,
            "unknown fault mode 'on fire'",
        ),
        (
            lambda: WallFollowEnv(fault={"sensors": [8]}),
            sim.WorldError,
            "sensor index 8 is not in 0..7",
        ),
        (lambda: WallFollowEnv(fault={"sensor": [1]}), sim.WorldError, "unknown key 'sensor'"),
        (lambda: WallFollowEnv(fault={"sensors": 1.5}), sim.WorldError, "'sensors' must be"),
        (
            lambda: WallFollowEnv(fault={"sensors": [1], "robots": [0]}),
            sim.WorldError,
            "unknown key 'robots'",
        ),
        (
            lambda: WallFollowEnv(fault={"sensors": [1], "step": -2}),
            sim.WorldError,
            "step must be ≥ 0",
        ),
        (
            lambda: WallFollowEnv().reset(options={"faults": {}}),
            sim.WorldError,
            "unknown reset option 'faults'",
        ),
        (
            lambda: WallFollowEnv().reset(options={"start": 12}),
            sim.WorldError,
            "option 'start' 12 is not",
        ),
        (lambda: WallFollowEnv().step(np.zeros(3)), sim.WorldError, "action must be"),
        (lambda: WallFollowVectorEnv(0), sim.WorldError, "num_envs must be a positive int"),
        (
            lambda: WallFollowVectorEnv(2, fault={"sensors": [1], "robots": [2]}),
            sim.WorldError,
            "robot indices must be in 0..1",
        ),
        (lambda: WallFollowVectorEnv(2).reset(seed=[1]), sim.WorldError, "2 seeds"),
        (lambda: WallFollowVectorEnv(2).step(np.zeros((2, 2))), sim.WorldError, "call reset"),
    ],
)
def test_bad_input_raises_one_clear_line(
    make: Callable[[], Any], error: type, message: str
) -> None:
    with pytest.raises(error, match=message) as caught:
        make()
    assert "\n" not in str(caught.value)


# --- registration, rendering, layering ---


def test_the_entry_point_registers_the_env_and_make_needs_no_import_of_ours() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    target = project["project"]["entry-points"]["gymnasium.envs"]["GnpLab"]
    module, function = target.split(":")
    getattr(import_module(module), function)()  # what a plugin loader does; idempotent
    assert gym.spec(ENV_ID).vector_entry_point == "sim.gym_vector:WallFollowVectorEnv"
    code = (
        "import gymnasium; env = gymnasium.make('sim.gym_env:GnpLab/WallFollow-v0', noise=5.0); "
        "print(env.reset(seed=1)[0].shape, env.unwrapped.world.noise_sigma)"
    )
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "(8,) 5.0"


def test_rgb_array_frames_show_the_walls_and_the_robot() -> None:
    env = WallFollowEnv(render_mode="rgb_array", start=0)
    env.reset(seed=0)
    frame = env.render()
    assert frame is not None and frame.shape == (256, 256, 3) and frame.dtype == np.uint8
    assert (frame == 0).all(axis=2).sum() > 500  # walls
    assert (frame == (40, 90, 220)).all(axis=2).sum() > 50  # the robot's disc
    envs = WallFollowVectorEnv(2, render_mode="rgb_array")
    envs.reset(seed=0)
    frames = envs.render()
    assert frames is not None and len(frames) == 2 and frames[0].shape == frame.shape
    assert WallFollowEnv().render() is None


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32), noise=st.sampled_from([0.0, 50.0]), hold=st.integers(1, 12))
def test_every_step_is_in_the_spaces_and_the_reward_is_its_terms(
    seed: int, noise: float, hold: int
) -> None:
    envs = WallFollowVectorEnv(6, noise=noise, max_episode_steps=40)
    obs, _ = envs.reset(seed=seed)
    envs.action_space.seed(seed)
    for t in range(40):
        if t % hold == 0:
            actions = envs.action_space.sample()
        obs, reward, terminated, truncated, info = envs.step(actions)
        assert obs in envs.observation_space
        assert np.all(np.abs(reward) <= 1) and not terminated.any()
        assert np.array_equal(
            reward, info["reward/speed"] * info["reward/straightness"] * info["reward/near_wall"]
        )
        assert truncated.all() == (t == 39)
