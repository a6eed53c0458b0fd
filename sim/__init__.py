"""The world: arenas, the Khepera I model, pymunk physics, IR sensors, noise, faults, reward."""

from sim.arena import ARENA_NAMES, Arena, ArenaError, load_arena
from sim.check import check_world
from sim.khepera import IR_RANGE_MM
from sim.reward import reward_terms
from sim.sensors import sensor_rays
from sim.world import FAULT_MODES, Fault, World, WorldError

__all__ = [
    "ARENA_NAMES",
    "FAULT_MODES",
    "IR_RANGE_MM",
    "Arena",
    "ArenaError",
    "Fault",
    "World",
    "WorldError",
    "check_world",
    "load_arena",
    "reward_terms",
    "sensor_rays",
]
