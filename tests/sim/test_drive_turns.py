"""The drive's turn per substep looked up for whole-number commands (`sim.drive.turn_table`) is
the one it computes, to the bit: the table's rows against `cos` and `sin` in the same compiled
code, and the forces of random commands (whole numbers, signed zeros, fractions) with the table
and without it."""

from __future__ import annotations

import numba as nb
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sim import drive
from sim.khepera import AXLE_MM, MAX_COMMAND, WHEEL_RADIUS_MM

NO_TURNS = np.empty((0, 2))
SUBSTEPS = (0.064 / 3, 0.064, 0.01, 0.1 / 7)


@nb.njit
def _computed(left: float, right: float, dt: float) -> tuple[float, float]:
    """`drive_forces`' own operations before the table: cos and sin of spin·dt."""
    spin = (right * WHEEL_RADIUS_MM - left * WHEEL_RADIUS_MM) / AXLE_MM
    return np.cos(spin * dt), np.sin(spin * dt)


def test_every_whole_command_pair_reads_the_computed_turn() -> None:
    whole = np.arange(-MAX_COMMAND, MAX_COMMAND + 1)
    for dt in SUBSTEPS:
        table = drive.turn_table(dt)
        for left in (*whole, -0.0):
            for right in (*whole, -0.0):
                spin = (right * WHEEL_RADIUS_MM - left * WHEEL_RADIUS_MM) / AXLE_MM
                looked = drive._turn(left, right, spin * dt, table)
                computed = _computed(left, right, dt)
                assert np.array_equal(np.array(looked), np.array(computed))
                assert np.signbit(looked[1]) == np.signbit(computed[1])


command = st.one_of(
    st.integers(-10, 10).map(float),
    st.sampled_from([-0.0, 0.0, 10.0, -10.0]),
    st.floats(-MAX_COMMAND, MAX_COMMAND),
)


@settings(max_examples=200, deadline=None)
@given(
    commands=st.lists(st.tuples(command, command), min_size=1, max_size=12),
    angle=st.floats(-10.0, 10.0),
    spin=st.floats(-20.0, 20.0),
    dt=st.sampled_from(SUBSTEPS),
)
def test_forces_are_the_same_with_and_without_the_table(
    commands: list[tuple[float, float]], angle: float, spin: float, dt: float
) -> None:
    n = len(commands)
    wheels = np.array(commands)
    angles, spins, rows = np.full(n, angle), np.full(n, spin), np.arange(n)
    looked, computed = np.zeros((3, n, 3)), np.zeros((3, n, 3))
    drive.drive_forces(angles, spins, wheels, rows, dt, looked, drive.turns_for(dt))
    drive.drive_forces(angles, spins, wheels, rows, dt, computed, NO_TURNS)
    assert looked.tobytes() == computed.tobytes()  # signed zeros included
