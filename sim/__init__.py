"""The world: arenas, the Khepera I model, physics (pymunk or analytic), IR sensors, noise,
faults, reward.

The constants below are the world's facts; `app` imports them rather than re-typing them.
"""

from sim.arena import ARENA_NAMES, N_START_POSES, Arena, ArenaError, load_arena
from sim.check import check_world
from sim.faults import FAULT_MODES, Fault, FaultMode, WorldError
from sim.khepera import (
    BODY_RADIUS_MM,
    CONTROL_PERIOD_S,
    IR_MAX,
    IR_RANGE_MM,
    LIFE_STEPS,
    MAX_COMMAND,
    N_SENSORS,
)
from sim.noise import NOISE_STREAMS, NoiseStream
from sim.reward import TERM_NAMES, reward_table, reward_terms
from sim.sensors import WallGrid, ir_readings, sensor_rays
from sim.world import PHYSICS, Physics, World

__all__ = [
    "ARENA_NAMES",
    "BODY_RADIUS_MM",
    "CONTROL_PERIOD_S",
    "FAULT_MODES",
    "IR_MAX",
    "IR_RANGE_MM",
    "LIFE_STEPS",
    "MAX_COMMAND",
    "NOISE_STREAMS",
    "N_SENSORS",
    "N_START_POSES",
    "PHYSICS",
    "TERM_NAMES",
    "Arena",
    "ArenaError",
    "Fault",
    "FaultMode",
    "NoiseStream",
    "Physics",
    "WallGrid",
    "World",
    "WorldError",
    "check_world",
    "ir_readings",
    "load_arena",
    "reward_table",
    "reward_terms",
    "sensor_rays",
]
