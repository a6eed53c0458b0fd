"""The sensor noise's streams: box-muller-v1 (the default, every earlier run's bits) and
ziggurat-v1 (faster, other draws of the same N(0, σ²)), chosen by `World(noise_stream=...)`."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from scipy import stats

import sim
from sim import noise

#: sha256 of ziggurat-v1's first 4 steps × 100 robots × 8 sensors of standard normals (robot
#: seeds 0..99). A version is never changed: a new way of drawing is a new stream name.
ZIGGURAT_V1_DIGEST = "29d48135f648e865fc1f5db2b5d483db7d4374c4fb32272cb3f30e985f7e34da"


def _draws(stream: sim.NoiseStream, robots: int, steps: int, first_seed: int = 0) -> np.ndarray:
    keys = noise.robot_keys(np.arange(first_seed, first_seed + robots, dtype=np.uint64))
    out = np.empty((steps, robots, sim.N_SENSORS))
    noise.normal_draws(keys, steps, noise.noise_stream_code(stream), out)
    return out


def test_the_default_is_box_muller_and_an_unknown_stream_is_one_line() -> None:
    arena = sim.load_arena("training")
    assert sim.World(arena, n=1).noise_stream == "box-muller-v1"
    assert sim.NOISE_STREAMS == ("box-muller-v1", "ziggurat-v1")
    with pytest.raises(sim.WorldError, match=r"^unknown noise stream 'polar': expected one of "):
        sim.World(arena, n=1, noise_stream="polar")  # type: ignore[arg-type]


def test_ziggurat_draws_are_standard_normal() -> None:
    """10⁶ draws (1250 robots × 100 steps × 8 sensors), a fixed seed: KS against N(0, 1),
    mean and variance within 4.5 standard errors, the tail beyond R as often as it should be."""
    z = _draws("ziggurat-v1", 1250, 100, first_seed=7).ravel()
    n = z.size
    assert n == 1_000_000
    assert stats.kstest(z, "norm").pvalue > 0.001
    assert abs(z.mean()) < 4.5 / np.sqrt(n)
    assert abs(z.var() - 1.0) < 4.5 * np.sqrt(2.0 / n)
    tail = 2.0 * stats.norm.sf(noise._ZIG_TAIL)  # the draws the base layer's tail gives
    share = np.mean(np.abs(z) > noise._ZIG_TAIL)
    assert abs(share - tail) < 4.5 * np.sqrt(tail / n)
    assert np.all(np.isfinite(z))


def test_ziggurat_v1_is_deterministic_and_frozen() -> None:
    a = _draws("ziggurat-v1", 100, 4)
    assert np.array_equal(a, _draws("ziggurat-v1", 100, 4))
    assert hashlib.sha256(a.tobytes()).hexdigest() == ZIGGURAT_V1_DIGEST
    assert not np.any(a == _draws("box-muller-v1", 100, 4))


def test_a_robots_draws_depend_on_its_key_and_clock_alone() -> None:
    """Robot i's draws are the same alone or in any batch (so any split into workers or
    blocks): its stream is a function of its seed and the step."""
    batch = _draws("ziggurat-v1", 50, 6, first_seed=100)
    for i in (0, 17, 49):
        assert np.array_equal(_draws("ziggurat-v1", 1, 6, first_seed=100 + i)[:, 0], batch[:, i])


@pytest.mark.parametrize("stream", sim.NOISE_STREAMS)
def test_the_world_adds_the_streams_draws(stream: sim.NoiseStream) -> None:
    """`World.observe` adds σ times the stream's draws (readings clipped to 0..1023), step by
    step: the staged path draws what `noise.normal_draws` (and the compiled loop, by the same
    `observe_pair`) draw."""
    arena = sim.load_arena("training")
    n, sigma = 20, 50.0
    world = sim.World(arena, n=n, noise_sigma=sigma, physics="analytic", noise_stream=stream)
    seeds = np.arange(300, 300 + n)
    world.reset(arena.start_poses[np.arange(n) % len(arena.start_poses)], seeds=seeds)
    z = _draws(stream, n, 5, first_seed=300)
    for t in range(5):
        true = world.sense()
        expected = np.minimum(sim.IR_MAX, np.maximum(0.0, true + sigma * z[t]))
        if stream == "box-muller-v1":  # its old order: (σ·√(−2 ln u₁))·cos, not σ·(√…·cos)
            assert np.allclose(world.observe(), expected, rtol=0, atol=1e-9)
        else:
            assert np.array_equal(world.observe(), expected)
        world.step(np.full((n, 2), 3.0))
