"""Neural controllers in the lab loop: scaling, traces, batch independence."""

from __future__ import annotations

import numpy as np

import neuro
import sim
from app.brains.nets import NeuralControllers, trace_layout
from app.loop.recording import TrajectoryRecorder
from app.loop.rollout import Batch, rollout

NET = neuro.ElmanConfig(hidden=3)


def _nets(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return neuro.from_flat(NET, rng.normal(0, 1, (n, NET.n_params)))


def test_readings_are_scaled_in_and_commands_out() -> None:
    arrays = neuro.zeros(NET, 1)
    arrays["w_out"][0, 0, 0] = 1.0  # left wheel = 10 tanh(h0)
    arrays["w_in"][0, 0, 2] = 1.0  # h0 = tanh(s2 / 1023)
    arrays["b_out"][0, 1] = -0.5  # right wheel = 10 tanh(−0.5)
    controllers = NeuralControllers(NET, arrays)
    seen = np.zeros((1, 8))
    seen[0, 2] = 511.5
    commands, trace = controllers.act(seen, np.zeros(1), trace=True)
    h0 = np.tanh(0.5)
    assert np.allclose(commands, [[10 * np.tanh(h0), 10 * np.tanh(-0.5)]], rtol=0, atol=1e-12)
    assert trace is not None and np.allclose(trace.activation, [[h0, 0.0, 0.0]], atol=1e-15)
    controllers.reset_episode()
    assert not controllers.state.any()


def _lives(arrays: dict[str, np.ndarray], starts: np.ndarray, steps: int) -> tuple:
    arena = sim.load_arena("training")
    world = sim.World(arena, n=len(starts), seed=3, noise_sigma=50.0)
    world.reset(arena.start_poses[starts], seeds=100 + starts.astype(np.uint64))
    batch = Batch(world, NeuralControllers(NET, arrays))
    recorder = TrajectoryRecorder(len(starts), steps, trace_layout(NET))
    out = rollout(batch, steps, 0.0, 0.0, learn=False, recorder=recorder)
    return out, recorder.trajectory(starts)


def test_a_neural_robot_lives_the_same_life_alone_or_in_a_batch() -> None:
    arrays = _nets(3, seed=4)
    starts = np.array([0, 5, 7])
    out, together = _lives(arrays, starts, 40)
    assert np.ptp(together.poses[:, :, 0], axis=1).min() > 1.0  # they move
    _, alone = _lives(neuro.take(arrays, [1]), starts[1:2], 40)
    assert np.array_equal(alone.poses[0], together.poses[1])
    assert np.array_equal(alone.trace["activation"][0], together.trace["activation"][1])
    assert np.allclose(out.term_sums[:, 0], together.reward.sum(axis=1), rtol=0, atol=1e-12)
    assert together.trace["activation"].shape == (3, 40, NET.hidden)
