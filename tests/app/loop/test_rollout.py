"""The lab's one loop: batch independence, episodes, ε/α per step, what a rollout returns."""

from __future__ import annotations

import numpy as np
import pytest

import gnp
import sim
from app.brains.gnp_brain import gnp_trace
from app.brains.gnp_controllers import gnp_batch, gnp_of
from app.loop.recording import TrajectoryRecorder
from app.loop.rollout import Batch, rollout

CFG = gnp.GnpConfig(method="BS", n_sub=2, n_branch=2)


def _batch(n: int, robots: np.ndarray | None = None, noise: float = 50.0) -> Batch:
    """Robots `robots` (default 0..n-1) of a family whose member i always has the same genome,
    start pose and streams, whatever batch it sits in."""
    robots = np.arange(n) if robots is None else robots
    arena = sim.load_arena("training")
    everyone = gnp.init_population(CFG, 8, np.random.default_rng(3))
    world = sim.World(arena, n=len(robots), seed=0, noise_sigma=noise)
    world.reset(arena.start_poses[robots % 10], seeds=1000 + robots)
    return gnp_batch(world, CFG, gnp.take(everyone, robots), 2000 + robots)


def test_a_robot_lives_the_same_life_in_any_batch() -> None:
    whole = _batch(8)
    alone = _batch(2, np.array([5, 2]))
    a = rollout(whole, 40, 0.1, 0.1)
    b = rollout(alone, 40, 0.1, 0.1)
    assert np.array_equal(a.term_sums[[5, 2]], b.term_sums)
    assert np.array_equal(whole.world.poses[[5, 2]], alone.world.poses)
    assert np.array_equal(gnp_of(whole).population.q_ss[[5, 2]], gnp_of(alone).population.q_ss)


def test_blocks_of_steps_continue_one_life() -> None:
    once, blocks = _batch(3), _batch(3)
    whole = rollout(once, 30, 0.1, 0.2)
    parts = [rollout(blocks, n, 0.1, 0.2) for n in (10, 5, 15)]
    assert np.array_equal(once.world.poses, blocks.world.poses)
    assert np.array_equal(gnp_of(once).population.q_bs, gnp_of(blocks).population.q_bs)
    assert np.array_equal(
        whole.step_reward_sums, np.concatenate([p.step_reward_sums for p in parts])
    )
    np.testing.assert_allclose(whole.term_sums, sum(p.term_sums for p in parts), rtol=1e-12)


def test_the_returned_sums_are_the_recorded_rewards() -> None:
    batch = _batch(4)
    recorder = TrajectoryRecorder(4, 25, gnp_trace(CFG))
    outcome = rollout(batch, 25, 0.1, 0.1, recorder=recorder)
    life = recorder.trajectory(np.zeros(4, np.int64))
    for column, name in enumerate(sim.TERM_NAMES):
        np.testing.assert_allclose(outcome.term_sums[:, column], life.terms[name].sum(axis=1))
    np.testing.assert_allclose(outcome.step_reward_sums, life.reward.sum(axis=0))
    # The reward is Eq. 2.7 of the true readings after each step and the step's commands.
    expected = sim.reward_terms(life.readings[:, -1], life.commands[:, -1])["reward"]
    assert np.array_equal(life.reward[:, -1], expected)


def test_epsilon_alpha_are_taken_per_step() -> None:
    batch = _batch(3)
    q_before = gnp_of(batch).population.q_ss.copy()
    alpha = np.zeros(40)
    rollout(batch, 40, 0.1, alpha)  # α = 0: Sarsa moves nothing
    assert np.array_equal(gnp_of(batch).population.q_ss, q_before)
    alpha[30:] = 0.5
    rollout(batch, 40, 0.1, alpha)
    assert not np.array_equal(gnp_of(batch).population.q_ss, q_before)
    with pytest.raises(ValueError):
        rollout(batch, 40, 0.1, np.zeros(39))


def test_offline_steps_leave_q_tables_alone() -> None:
    batch = _batch(3)
    q_before = gnp_of(batch).population.q_ss.copy()
    rollout(batch, 30, 0.1, 0.5, learn=False)
    assert np.array_equal(gnp_of(batch).population.q_ss, q_before)


def test_episodes_move_robots_to_their_next_start_pose() -> None:
    batch = _batch(2, noise=0.0)
    starts = np.array([[0, 4], [1, 7]])
    recorder = TrajectoryRecorder(2, 20, gnp_trace(CFG))
    rollout(batch, 20, 0.1, 0.1, recorder=recorder, episode_starts=starts, redraw_every=10)
    poses = recorder.trajectory(starts[:, 0]).poses
    arena_poses = batch.world.arena.start_poses
    # One step after a redraw a robot is within one step's travel (75 mm/s × 64 ms) of its pose.
    travel = np.linalg.norm(poses[:, 10, :2] - arena_poses[starts[:, 1], :2], axis=1)
    assert np.all(travel <= 75 * 0.064 + 1e-9)
    assert np.all(np.linalg.norm(poses[:, 9, :2] - arena_poses[starts[:, 1], :2], axis=1) > 10)


def test_a_batch_needs_one_controller_per_robot() -> None:
    arena = sim.load_arena("training")
    pop = gnp.init_population(CFG, 3, np.random.default_rng(0))
    with pytest.raises(ValueError, match="3 controllers for 2 robots"):
        gnp_batch(sim.World(arena, n=2), CFG, pop, np.arange(2))
