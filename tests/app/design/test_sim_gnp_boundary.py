"""The facts `sim`, `gnp` and `neuro` must agree on, tied here: none of them imports another, so
each keeps its own constant and this test (which may import them all) fails when one moves."""

from __future__ import annotations

import numpy as np

import gnp
import neuro
import sim
from gnp import config as brain
from sim import khepera


def test_constants_on_both_sides_of_the_boundary_agree() -> None:
    # What a judgment node judges is a reading of the world's sensors...
    assert brain.N_SENSORS == sim.N_SENSORS == len(khepera.SENSOR_HEADINGS_RAD)
    assert brain.SENSOR_MAX == sim.IR_MAX  # β, α span the readings' range 0..1023
    # ...and what a processing node sets is a wheel command the world takes.
    assert brain.SPEED_MAX == sim.MAX_COMMAND
    assert brain.N_WHEELS == sim.N_WHEELS == 2  # the world steps (N, 2) commands: (left, right)
    # A net's inputs are the same readings, its outputs the same two wheels.
    assert neuro.N_INPUTS == sim.N_SENSORS
    assert neuro.N_OUTPUTS == brain.N_WHEELS


def test_a_right_wheel_node_turns_the_robot_left() -> None:
    """The wheel order, end to end: a processing node on P0 (right) sets the second column of
    gnp's (left, right) commands, which the world reads as its right wheel: the robot turns
    counter-clockwise (its heading grows)."""
    cfg = gnp.GnpConfig(method="RL", n_judgment=1, n_processing=1, n_sub=1)
    pop = gnp.init_population(cfg, 1, np.random.default_rng(0))
    processing = 1 + cfg.n_judgment
    pop.conn[0, 0] = processing  # start → the processing node, which loops on itself
    pop.conn[0, processing] = processing
    pop.function[0, processing] = brain.RIGHT_WHEEL
    pop.speed[0, processing] = brain.SPEED_MAX
    state = gnp.init_state(cfg, 1, [0])
    world = sim.World(sim.load_arena("training"), n=1, seed=0)
    world.reset(np.array([[500.0, 500.0, 0.0]]))
    for _ in range(5):
        commands, trace = gnp.step(cfg, pop, state, world.observe(), np.zeros(1), 0.0, 0.0)
        assert trace is None
        np.testing.assert_array_equal(commands, [[0.0, brain.SPEED_MAX]])
        world.step(commands)
    assert world.poses[0, 2] > 0.0  # turned left (counter-clockwise)
    # Turning about the left wheel: the centre moves forward and to the left.
    assert world.poses[0, 0] > 500.0 and world.poses[0, 1] > 500.0
