"""The compiled loop (app.loop.fused's world half, app.brains.gnp_fused's GNP half) steps a
batch exactly as its stages one at a time do, bit for bit.

Copies of one batch (GNP controllers, analytic world, noise, faults of every mode firing during
the steps, episodes redrawn): one stepped by `Batch.staged_step` (the stages called one by one
from Python, as the loop ran before it was compiled), the others by `Batch.step` and `rollout`,
which take the compiled path wherever they can, watched (recorded, traced) or not. After every
step, and after longer runs, every array they hold must be equal: poses, true readings,
observations, wheel commands, Q tables and the rest of the records, engine walks and streams,
rewards and reward sums, and what each step reports and records.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import gnp
import sim
from app.brains import gnp_fused
from app.brains.gnp_brain import gnp_trace
from app.brains.gnp_controllers import gnp_batch, gnp_of
from app.loop import fused
from app.loop.recording import TrajectoryRecorder
from app.loop.rollout import Batch, rollout
from app.settings.config import CFrom

N = 10  # more than a block of 3: the compiled loop splits the batch
FAULTS = (
    sim.Fault(step=4, sensors=(2,), mode="dead", robots=(0, 1, 2)),
    sim.Fault(step=7, sensors=(3, 5), mode="saturated", robots=(3, 4)),
    sim.Fault(step=7, sensors=(0, 1), mode="stuck", robots=(5, 6, 0)),
    sim.Fault(step=12, sensors=(6, 7), mode="random", robots=(1, 7, 8, 9)),
)
CONTROLLERS = [
    pytest.param(method, fuzzy, c_from, id=f"{method}-{'fuzzy' if fuzzy else 'crisp'}-{c_from}")
    for method in ("RL", "BS", "CS")
    for fuzzy in (True, False)
    for c_from in ("true", "observed")
]


def _batch(
    method: gnp.Method,
    fuzzy: bool,
    c_from: CFrom,
    physics: sim.Physics = "analytic",
    noise_stream: sim.NoiseStream = "box-muller-v1",
) -> Batch:
    cfg = gnp.GnpConfig(method=method, n_sub=2, n_branch=2, fuzzy=fuzzy)
    arena = sim.load_arena("training")
    world = sim.World(
        arena, n=N, seed=0, noise_sigma=50.0, physics=physics, noise_stream=noise_stream
    )
    robots = np.arange(N)
    world.reset(arena.start_poses[robots % len(arena.start_poses)], seeds=1000 + robots)
    world.schedule_faults(FAULTS)
    population = gnp.init_population(cfg, N, np.random.default_rng(3))
    return gnp_batch(world, cfg, population, 2000 + robots, c_from)


def _assert_same(a: Batch, b: Batch) -> None:
    assert a.world.t == b.world.t
    assert np.array_equal(a.world.poses, b.world.poses)
    assert np.array_equal(a.world.sense(), b.world.sense())
    assert np.array_equal(a.world.observe(), b.world.observe())
    assert np.array_equal(a.world.fault_modes, b.world.fault_modes)
    assert np.array_equal(
        gnp_of(a).population.records, gnp_of(b).population.records
    )  # Q tables included
    assert np.array_equal(gnp_of(a).state.walk, gnp_of(b).state.walk)
    assert np.array_equal(gnp_of(a).state.wheels, gnp_of(b).state.wheels)  # the step's commands
    assert np.array_equal(gnp_of(a).state.rng, gnp_of(b).state.rng)
    assert np.array_equal(a.reward, b.reward)


@pytest.fixture(params=[3, fused.ROBOTS_PER_BLOCK], ids=["blocks-of-3", "one-block"])
def block(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> int:
    """Robots per block of the compiled loop: several blocks, and the whole batch in one."""
    monkeypatch.setattr(fused, "ROBOTS_PER_BLOCK", request.param)
    return int(request.param)


@pytest.fixture
def compiled_calls(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """How many steps each call of the compiled loop took."""
    calls: list[int] = []
    original = gnp_fused.steps

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls.append(len(args[5]))
        return original(*args, **kwargs)

    monkeypatch.setattr(gnp_fused, "steps", counted)
    return calls


@pytest.mark.usefixtures("block")
@pytest.mark.parametrize(("method", "fuzzy", "c_from"), CONTROLLERS)
def test_each_compiled_step_is_the_staged_step_to_the_bit(
    method: gnp.Method, fuzzy: bool, c_from: CFrom, compiled_calls: list[int]
) -> None:
    staged, stepped, rolled = (_batch(method, fuzzy, c_from) for _ in range(3))
    for _ in range(20):
        record = staged.staged_step(0.1, 0.1, trace=True)
        again = stepped.step(0.1, 0.1, trace=True)
        outcome = rollout(rolled, 1, 0.1, 0.1)
        _assert_same(staged, stepped)
        _assert_same(staged, rolled)
        for field in ("observations", "commands", "readings", "term_table"):
            assert np.array_equal(getattr(again, field), getattr(record, field)), field
        for field in (*gnp.VISIT_FIELDS, "count"):
            assert np.array_equal(getattr(again.trace, field), getattr(record.trace, field))
        assert np.array_equal(outcome.term_sums, record.term_table)
        assert outcome.step_reward_sums[0] == record.reward.sum()
    assert len(compiled_calls) == 2 * (20 - len({f.step for f in FAULTS}))  # fault steps: staged


@pytest.mark.usefixtures("block")
@pytest.mark.parametrize(
    ("method", "fuzzy", "c_from"), [("BS", True, "true"), ("CS", False, "observed")]
)
def test_the_ziggurat_stream_is_drawn_alike_compiled_and_staged(
    method: gnp.Method, fuzzy: bool, c_from: CFrom, compiled_calls: list[int]
) -> None:
    """The compiled loop (lazy draws when C is true, all four pairs when observed) draws the
    ziggurat-v1 stream the staged path draws, a step per call and 30 steps in one call."""
    staged, stepped, rolled = (
        _batch(method, fuzzy, c_from, noise_stream="ziggurat-v1") for _ in range(3)
    )
    for _ in range(20):
        record = staged.staged_step(0.1, 0.1)
        again = stepped.step(0.1, 0.1)
        rollout(rolled, 1, 0.1, 0.1)
        _assert_same(staged, stepped)
        _assert_same(staged, rolled)
        assert np.array_equal(again.observations, record.observations)
    for _ in range(30):
        staged.staged_step(0.1, 0.1)
    rollout(rolled, 30, 0.1, 0.1)
    _assert_same(staged, rolled)
    assert compiled_calls[-1] == 30
    default = _batch(method, fuzzy, c_from)
    default.staged_step(0.1, 0.1)
    first = _batch(method, fuzzy, c_from, noise_stream="ziggurat-v1")
    first.staged_step(0.1, 0.1)
    assert not np.array_equal(default.world.observe(), first.world.observe())


@pytest.mark.usefixtures("block")
@pytest.mark.parametrize(("method", "fuzzy", "c_from"), CONTROLLERS)
def test_a_compiled_rollout_is_the_per_step_rollout_to_the_bit(
    method: gnp.Method, fuzzy: bool, c_from: CFrom, compiled_calls: list[int]
) -> None:
    """Many steps per call, through faults and new episodes, with ε and α changing per step."""
    steps, redraw = 60, 25
    epsilon = np.linspace(0.3, 0.0, steps)
    alpha = np.linspace(0.0, 0.2, steps)
    starts = np.random.default_rng(5).integers(0, 10, (N, 3))
    each, compiled, recorded = (_batch(method, fuzzy, c_from) for _ in range(3))
    recorder = TrajectoryRecorder(N, steps, gnp_trace(gnp_of(each).cfg))
    expected = TrajectoryRecorder(N, steps, gnp_trace(gnp_of(each).cfg))
    sums = np.zeros((N, len(sim.TERM_NAMES)))
    step_sums = np.zeros(steps)
    poses = each.world.arena.start_poses
    for t in range(steps):  # the per-step loop, as rollout ran it before the compiled path
        if t > 0 and t % redraw == 0:
            each.new_episode(poses[starts[:, t // redraw]])
        record = each.staged_step(float(epsilon[t]), float(alpha[t]), trace=True)
        sums += record.term_table
        step_sums[t] = record.reward.sum()
        assert record.trace is not None
        expected.record(
            each.world.poses,
            record.readings,
            record.observations,
            record.commands,
            record.term_table,
            record.trace,
        )
    outcome = rollout(compiled, steps, epsilon, alpha, episode_starts=starts, redraw_every=redraw)
    watched = rollout(
        recorded,
        steps,
        epsilon,
        alpha,
        recorder=recorder,
        episode_starts=starts,
        redraw_every=redraw,
    )
    for batch, result in ((compiled, outcome), (recorded, watched)):
        _assert_same(each, batch)
        assert np.array_equal(result.term_sums, sums)
        assert np.array_equal(result.step_reward_sums, step_sums)
    lives, again = expected.trajectory(starts[:, 0]), recorder.trajectory(starts[:, 0])
    for field in ("poses", "readings", "observations", "commands"):
        assert np.array_equal(getattr(again, field), getattr(lives, field)), field
    for name in sim.TERM_NAMES:
        assert np.array_equal(again.terms[name], lives.terms[name]), name
    for name, values in lives.trace.items():
        assert np.array_equal(again.trace[name], values), name
    fault_steps = len({f.step for f in FAULTS})
    assert max(compiled_calls) > 1 and sum(compiled_calls) == 2 * (steps - fault_steps)


def test_the_compiled_path_is_taken_only_for_gnp_in_an_analytic_world(
    compiled_calls: list[int],
) -> None:
    rollout(_batch("BS", True, "true", physics="pymunk"), 3, 0.1, 0.1)
    ablated = _batch("BS", True, "true")
    gnp_of(ablated).second_stage = False
    rollout(ablated, 3, 0.1, 0.1)
    assert compiled_calls == []
    rollout(_batch("BS", True, "true"), 3, 0.1, 0.1)
    assert compiled_calls == [3]


def test_a_world_refuses_compiled_steps_through_a_fault() -> None:
    world = _batch("RL", False, "true").world
    with pytest.raises(sim.WorldError, match="fault fires"):
        world.stepped(5)
