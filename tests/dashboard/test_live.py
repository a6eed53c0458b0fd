"""The live stepping loop (no viser): determinism, faults, learning settings, bounded memory."""

from __future__ import annotations

import re

import numpy as np
import pytest

import gnp
import sim
from app.brains.gnp_brain import VISIT_CAPACITY, GnpFamily
from app.phases.live import LearningSettings, LiveError, LiveSession, Ring, RobotSpec
from app.settings.config import ImplementationSettings
from app.settings.fields import read_setting


@pytest.fixture(scope="module")
def arena() -> sim.Arena:
    return sim.load_arena("training")


def individual(method: str, seed: int = 1) -> RobotSpec:
    cfg = gnp.GnpConfig(method=method)  # type: ignore[arg-type]
    return RobotSpec(
        method, GnpFamily.of(cfg), gnp.init_population(cfg, 1, np.random.default_rng(seed))
    )


def test_same_seed_same_run_and_the_callers_genome_is_untouched(arena: sim.Arena) -> None:
    spec = individual("CS")
    q_before = spec.population.q_ss.copy()
    runs = []
    for _ in range(2):
        session = LiveSession(arena, [spec], start=3, seed=5, noise_sigma=20.0)
        session.step(150)
        runs.append(session.snapshot()[0])
    a, b = runs
    np.testing.assert_array_equal(a.trajectory, b.trajectory)
    np.testing.assert_array_equal(a.rewards, b.rewards)
    np.testing.assert_array_equal(a.visits, b.visits)
    assert a.t == 150 and len(a.rewards) == 150
    np.testing.assert_array_equal(spec.population.q_ss, q_before)  # learning works on a copy
    # The robot starts at the chosen start pose.
    np.testing.assert_allclose(a.trajectory[0], arena.start_poses[3, :2])


def test_a_robot_alone_equals_the_same_robot_beside_another(arena: sim.Arena) -> None:
    alone = LiveSession(arena, [individual("BS")], start=1, seed=2)
    pair = LiveSession(arena, [individual("BS"), individual("RL", seed=9)], start=1, seed=2)
    alone.step(120)
    pair.step(120)
    np.testing.assert_array_equal(alone.snapshot()[0].trajectory, pair.snapshot()[0].trajectory)
    first, second = pair.snapshot()
    assert (first.method, second.method) == ("BS", "RL")


def test_visits_name_real_nodes_and_follow_the_trace(arena: sim.Arena) -> None:
    spec = individual("CS")
    session = LiveSession(arena, [spec], seed=4)
    session.step(40)
    snap = session.snapshot()[0]
    nodes = snap.visits[:, 0]
    assert np.all((nodes >= 0) & (nodes < spec.family.graph_config.n_nodes))
    assert snap.current_node == nodes[-1]
    assert set(np.unique(snap.visits[:, 4])) <= {0, 1}


def test_break_marks_sensors_and_the_controller_sees_the_fault(arena: sim.Arena) -> None:
    session = LiveSession(arena, [individual("RL")], start=0, seed=1)
    session.step(10)
    session.break_sensors([2, 3], "saturated")
    session.step(5)
    snap = session.snapshot()[0]
    np.testing.assert_array_equal(np.flatnonzero(snap.broken), [2, 3])
    np.testing.assert_array_equal(snap.seen_readings[[2, 3]], [1023, 1023])
    assert snap.fault_steps == (10,) and snap.fault_mode == "saturated"
    np.testing.assert_array_equal(snap.broken_counts[-6:], [0, 2, 2, 2, 2, 2])
    session.repair()
    session.step(1)
    assert not session.snapshot()[0].broken.any()


def test_a_scheduled_fault_fires_at_its_step_for_both_robots(arena: sim.Arena) -> None:
    session = LiveSession(arena, [individual("BS"), individual("CS")], seed=3)
    session.schedule_fault(25, [1], "dead")
    session.step(24)
    assert not any(r.broken.any() for r in session.snapshot())
    session.step(1)
    for robot in session.snapshot():
        assert robot.fault_steps == (25,)
        np.testing.assert_array_equal(np.flatnonzero(robot.broken), [1])


def test_bad_requests_are_refused_and_change_nothing(arena: sim.Arena) -> None:
    session = LiveSession(arena, [individual("RL")])
    # The world refuses a bad sensor, mode or fault step: nothing else checks them.
    with pytest.raises(sim.WorldError, match=r"sensor index 8 is not in 0\.\.7"):
        session.break_sensors([8], "dead")
    with pytest.raises(sim.WorldError, match="unknown fault mode 'melted'"):
        session.break_sensors([1], "melted")
    with pytest.raises(LiveError, match="noise σ: Input should be greater than or equal to 0"):
        session.set_noise(-1.0)
    with pytest.raises(sim.WorldError, match=r"Fault\.step must be ≥ 0"):
        session.schedule_fault(-1, [1], "dead")
    with pytest.raises(sim.WorldError, match="no sensors given"):
        session.schedule_fault(5, [], "dead")
    with pytest.raises(LiveError, match="start pose"):
        LiveSession(arena, [individual("RL")], start=10)
    with pytest.raises(LiveError, match="1 to 3 robots, got 4"):
        LiveSession(arena, [individual("RL")] * 4)
    with pytest.raises(LiveError, match="1 to 3 robots, got 0"):
        LiveSession(arena, [])
    session.step(1)
    assert not session.snapshot()[0].broken.any()
    assert session.robots[0].world.noise_sigma == 0.0


def test_noise_is_bounded_by_the_settings_field_not_only_by_the_world(arena: sim.Arena) -> None:
    """The world takes any finite σ ≥ 0; a live session takes what `noise_sigma` allows
    (0..IR_MAX), so the live page cannot show a noise no run could be configured with."""
    setting = read_setting(ImplementationSettings, "noise_sigma")
    assert setting is not None and (setting.low, setting.high) == (0, sim.IR_MAX)
    high = float(sim.IR_MAX)
    session = LiveSession(arena, [individual("RL")], noise_sigma=high)
    assert session.robots[0].world.noise_sigma == float(sim.IR_MAX)
    session.set_noise(0)
    assert session.robots[0].world.noise_sigma == 0.0
    with pytest.raises(LiveError) as refused:
        session.set_noise(sim.IR_MAX + 1)
    assert str(refused.value) == "noise σ: Input should be less than or equal to 1023 (got 1024.0)"
    with pytest.raises(LiveError, match=r"noise σ: .* \(got nan\)"):
        session.set_noise(float("nan"))
    assert session.robots[0].world.noise_sigma == 0.0  # nothing changed
    with pytest.raises(LiveError, match=re.escape("less than or equal to 1023 (got 5000.0)")):
        LiveSession(arena, [individual("RL")], noise_sigma=5000.0)


def test_learning_rates_fixed_and_scheduled_after_the_fault() -> None:
    fixed = LearningSettings(epsilon=0.1, alpha=0.2)
    assert fixed.rates(0, None) == (0.1, 0.2)
    assert fixed.rates(900, 100) == (0.1, 0.2)
    scheduled = LearningSettings(
        epsilon=0.05,
        alpha=0.3,
        after_fault=(
            gnp.Schedule(max=0.15, min=0.01, n=1.0),
            gnp.Schedule(max=0.7, min=0.1, n=2.0),
        ),
        horizon=1000,
    )
    assert scheduled.rates(50, None) == (0.05, 0.3)  # before any fault: the fixed values
    assert scheduled.rates(99, 100) == (0.05, 0.3)  # still before the fault
    eps, alpha = scheduled.rates(600, 100)  # halfway through the horizon
    assert eps == pytest.approx(0.14 * 0.5 + 0.01)  # Eq. 4.3, n = 1
    assert alpha == pytest.approx(0.6 * 0.25 + 0.1)  # Eq. 4.4, n = 2
    assert scheduled.rates(5000, 100) == pytest.approx((0.01, 0.1))
    with pytest.raises(ValueError, match="horizon"):
        LearningSettings(horizon=0)
    with pytest.raises(ValueError, match=r"ε must be in 0\.\.1"):
        LearningSettings(epsilon=1.5)


def test_offline_replay_leaves_q_values_alone(arena: sim.Arena) -> None:
    spec = individual("RL")
    session = LiveSession(arena, [spec], learning=LearningSettings(online=False))
    session.step(60)
    robot = session.robots[0]
    np.testing.assert_array_equal(robot.population.q_ss, spec.population.q_ss)
    session.set_learning(LearningSettings(online=True))
    session.step(200)
    assert np.any(robot.population.q_ss != spec.population.q_ss)


def test_histories_stay_bounded(arena: sim.Arena) -> None:
    session = LiveSession(arena, [individual("RL")])
    robot = session.robots[0]
    session.step(robot.history_capacity + 50)
    snap = session.snapshot()[0]
    assert len(snap.rewards) == robot.history_capacity
    assert len(snap.trajectory) == robot.trajectory_capacity
    assert len(snap.visits) == VISIT_CAPACITY
    assert snap.reward_steps[-1] == snap.t and snap.reward_steps[0] == snap.t - 999


def test_ring_keeps_the_newest_rows_in_order() -> None:
    ring = Ring(3)
    for value in range(5):
        ring.append(float(value))
    np.testing.assert_array_equal(ring.values(), [2.0, 3.0, 4.0])
    ring.clear()
    assert len(ring) == 0 and ring.values().shape == (0,)
