"""The wall-following task as a Gymnasium environment: ``GnpLab/WallFollow-v0``.

One Khepera I robot in a `sim.World`; the observation is what the robot's controller sees (the
8 IR readings after the noise of Eq. 2.6 and any sensor fault), the action the (left, right)
wheel commands, the reward Eq. 2.7 with its terms in ``info`` under `sim.TERM_NAMES`. A step is
the lab's own step (`app.loop.rollout.Batch.staged_step`): the world advances, the reward is judged
from the readings after it, and the next observation is drawn there.

    import gymnasium
    import sim.gym_env  # registers GnpLab/WallFollow-v0 (or make("sim.gym_env:GnpLab/...")).
    env = gymnasium.make("GnpLab/WallFollow-v0", arena="implementation", noise=50.0)
    obs, info = env.reset(seed=1, options={"fault": {"mode": "dead", "sensors": [0, 3],
                                                     "step": 500}})

``gymnasium.make_vec("GnpLab/WallFollow-v0", num_envs=N)`` gives `sim.gym_vector`'s vector
env: N robots in one batched world, stepped in one call.

Reset options (``env.reset(options=...)``; each applies to that episode only):

- ``"fault"``: a dict, or a list of dicts, each ``{"sensors": [i, ...], "mode": "dead",
  "step": 0}``: sensors (indices 0..7) break in ``mode`` (one of `sim.FAULT_MODES`: ``dead``
  reads 0, ``saturated`` 1023, ``stuck`` keeps the value it showed when it broke, ``random``
  uniform 0..1023 each step; default ``dead``) when the episode's step count reaches ``step``
  (0, the default, breaks them at reset). The vector env also takes ``"robots": [i, ...]``
  (default: every robot). Replaces the env's own ``fault`` for the episode.
- ``"start"``: index 0..9 of the arena's start pose (default: the env's ``start``, else drawn
  uniformly from the 10 each episode, as a training life draws it).

Seeding is Gymnasium's: ``reset(seed=s)`` seeds ``env.np_random``, which draws the episode's start
pose and the robot's noise stream, so the same seed and actions give the same episode.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, SupportsFloat, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sim.arena import N_START_POSES, Arena, load_arena
from sim.faults import Fault, FaultMode, WorldError
from sim.khepera import (
    BODY_RADIUS_MM,
    CONTROL_PERIOD_S,
    IR_MAX,
    LIFE_STEPS,
    MAX_COMMAND,
    N_SENSORS,
)
from sim.kinds import DEFAULT_PHYSICS
from sim.reward import C_FROM, TERM_NAMES, CFrom, reward_table
from sim.world import PHYSICS, Physics, World

ENV_ID = "GnpLab/WallFollow-v0"
SEED_BOUND = 2**63
"""The robot's noise stream seed is drawn from ``env.np_random`` in [0, SEED_BOUND)."""
FAULT_KEYS = ("sensors", "mode", "step", "robots")
OPTION_KEYS = ("fault", "start")
FRAME_PIXELS = 256
"""Side of a rendered frame (``render_mode="rgb_array"``)."""

ArenaArg = str | Path | Arena


def observation_space() -> spaces.Box:
    """One robot's observation: its 8 IR readings as the controller sees them, 0..1023."""
    return spaces.Box(0.0, IR_MAX, (N_SENSORS,), np.float64)


def action_space() -> spaces.Box:
    """One robot's action: (left, right) wheel commands in rad/s, −10..10."""
    return spaces.Box(-MAX_COMMAND, MAX_COMMAND, (2,), np.float64)


def metadata() -> dict[str, Any]:
    """The envs' metadata (a fresh dict: the vector env adds its autoreset mode)."""
    return {"render_modes": ["rgb_array"], "render_fps": 1.0 / CONTROL_PERIOD_S}


def build_world(
    arena: ArenaArg, n: int, noise: float, physics: Physics, c_from: CFrom, start: int | None
) -> World:
    """A world of n robots for the envs, every argument checked with a one-line error.

    Raises:
        ArenaError: for an unknown arena or a bad arena file.
        WorldError: for any other bad argument.
    """
    if not isinstance(arena, Arena):
        arena = load_arena(arena)
    try:
        sigma = float(noise)
    except (TypeError, ValueError):
        sigma = float("nan")
    if isinstance(noise, bool) or not (np.isfinite(sigma) and sigma >= 0):
        raise WorldError(f"noise (σ of Eq. 2.6, reading units) must be a number ≥ 0, got {noise!r}")
    if physics not in PHYSICS:
        raise WorldError(f"unknown physics {physics!r}: expected one of {', '.join(PHYSICS)}")
    if c_from not in C_FROM:
        raise WorldError(f"unknown c_from {c_from!r}: expected one of {', '.join(C_FROM)}")
    start_index(start, "start")
    return World(arena, n=n, seed=0, noise_sigma=sigma, physics=physics)


def start_index(start: object, where: str) -> int | None:
    """A start pose index 0..9 (or None), checked."""
    if start is None:
        return None
    if isinstance(start, bool) or not isinstance(start, int | np.integer):
        raise WorldError(f"{where} must be a start pose index in 0..{N_START_POSES - 1}")
    if not 0 <= start < N_START_POSES:
        raise WorldError(f"{where} {start} is not a start pose index in 0..{N_START_POSES - 1}")
    return int(start)


def parse_faults(spec: object, where: str, robots_allowed: bool) -> list[Fault]:
    """Faults from the option schema (module docstring): None, a dict or a list of dicts.

    Raises:
        WorldError: naming the bad key, sensor index or mode.
    """
    if spec is None:
        return []
    items = [spec] if isinstance(spec, Mapping) else spec
    if isinstance(items, str | bytes) or not isinstance(items, Sequence):
        raise WorldError(f"{where} must be a dict {{'sensors': [...], ...}} or a list of them")
    allowed = FAULT_KEYS if robots_allowed else FAULT_KEYS[:-1]
    faults = []
    for item in items:
        if not isinstance(item, Mapping):
            raise WorldError(f"{where}: a fault is a dict with keys {', '.join(allowed)}")
        unknown = sorted(str(k) for k in set(item) - set(allowed))
        if unknown:
            raise WorldError(f"{where}: unknown key {unknown[0]!r}: expected {', '.join(allowed)}")
        if "sensors" not in item:
            raise WorldError(f"{where}: a fault needs 'sensors' (indices in 0..{N_SENSORS - 1})")
        sensors = item["sensors"]
        if isinstance(sensors, str | bytes) or not isinstance(sensors, int | np.integer | Iterable):
            raise WorldError(f"{where}: 'sensors' must be indices in 0..7, got {sensors!r}")
        sensors = [sensors] if isinstance(sensors, int | np.integer) else list(sensors)
        robots = item.get("robots")
        robots = None if robots is None else tuple(np.atleast_1d(robots).tolist())
        mode = cast(FaultMode, item.get("mode", "dead"))
        faults.append(
            Fault(step=item.get("step", 0), sensors=tuple(sensors), mode=mode, robots=robots)
        )
    return faults


def check_options(options: Mapping[str, Any] | None) -> dict[str, Any]:
    """The reset options as a dict, an unknown key refused."""
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise WorldError(f"reset options must be a dict, got {options!r}")
    unknown = sorted(str(k) for k in set(options) - set(OPTION_KEYS))
    if unknown:
        raise WorldError(f"unknown reset option {unknown[0]!r}: expected {', '.join(OPTION_KEYS)}")
    return dict(options)


def draw_episode(rng: np.random.Generator) -> tuple[int, int]:
    """A robot's start pose index and noise stream seed for an episode, from its generator
    (both drawn every episode, so a fixed start leaves the noise stream unchanged)."""
    start = int(rng.integers(N_START_POSES))
    return start, int(rng.integers(SEED_BOUND))


def judge(world: World, commands: np.ndarray, c_from: CFrom) -> tuple[np.ndarray, np.ndarray]:
    """After a world step: the observations (N, 8) and the reward table (N, 4) of the step,
    C judged from the true readings or the observed ones (as the lab's `Batch` does)."""
    observed = world.observe()
    judged = world.sense() if c_from == "true" else observed
    return observed, reward_table(judged, commands)


class TopDown:
    """Top-down frames of robots in an arena: walls black, robot blue, heading red."""

    def __init__(self, arena: Arena, pixels: int = FRAME_PIXELS) -> None:
        xmin, ymin, xmax, ymax = arena.bounds
        margin = 10.0
        self.scale = (pixels - 1) / (max(xmax - xmin, ymax - ymin) + 2 * margin)  # px per mm
        self.origin = np.array([xmin - margin, ymin - margin])
        self.pixels = pixels
        self.background = np.full((pixels, pixels, 3), 255, dtype=np.uint8)
        for a, b in arena.walls:
            self._line(self.background, a, b, (0, 0, 0))
        centres = (np.arange(pixels) + 0.5) / self.scale
        self.x = self.origin[0] + centres[None, :]
        self.y = self.origin[1] + centres[::-1, None]  # row 0 at the top: +y up

    def _line(
        self, frame: np.ndarray, a: np.ndarray, b: np.ndarray, colour: tuple[int, int, int]
    ) -> None:
        count = int(np.ceil(np.hypot(*(b - a)) * self.scale * 2)) + 2
        points = a + np.linspace(0.0, 1.0, count)[:, None] * (b - a)
        col, row = ((points - self.origin) * self.scale).astype(int).T
        keep = (col >= 0) & (col < self.pixels) & (row >= 0) & (row < self.pixels)
        frame[self.pixels - 1 - row[keep], col[keep]] = colour

    def frame(self, pose: np.ndarray) -> np.ndarray:
        """An (H, W, 3) uint8 frame of a robot at pose (x mm, y mm, heading rad)."""
        frame = self.background.copy()
        x, y, heading = (float(v) for v in pose)
        disc = (self.x - x) ** 2 + (self.y - y) ** 2 <= BODY_RADIUS_MM**2
        frame[disc] = (40, 90, 220)
        nose = np.array([x, y]) + BODY_RADIUS_MM * np.array([np.cos(heading), np.sin(heading)])
        self._line(frame, np.array([x, y]), nose, (220, 30, 30))
        return frame


class WallFollowEnv(gym.Env[np.ndarray, np.ndarray]):
    """One robot following walls (see the module docstring for the options and seeding).

    Args:
        arena: A shipped arena's name (``training``, ``implementation``), a JSON path or an Arena.
        noise: σ of the sensor noise of Eq. 2.6 (reading units, ≥ 0).
        physics: ``pymunk`` (the world of record) or ``analytic``.
        c_from: Readings C of Eq. 2.7 is judged from: ``true`` or ``observed``.
        fault: Faults of every episode (the ``"fault"`` option's schema); an option replaces it.
        start: Start pose index 0..9 of every episode; None draws one per episode.
        render_mode: None or ``rgb_array``.

    The episode has no terminal state; ``gymnasium.make`` truncates it after `LIFE_STEPS`
    steps (pass ``max_episode_steps`` to change that).
    """

    metadata = metadata()

    def __init__(
        self,
        arena: ArenaArg = "training",
        noise: float = 0.0,
        physics: Physics = DEFAULT_PHYSICS,
        c_from: CFrom = "true",
        fault: object = None,
        start: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise WorldError(f"unknown render_mode {render_mode!r}: expected None or rgb_array")
        self.world = build_world(arena, 1, noise, physics, c_from, start)
        self.c_from: CFrom = c_from
        self.faults = parse_faults(fault, "fault", robots_allowed=False)
        self.start = start_index(start, "start")
        self.render_mode = render_mode
        self.observation_space = observation_space()
        self.action_space = action_space()
        self._view: TopDown | None = None

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        opts = check_options(options)
        faults = parse_faults(opts["fault"], "fault", False) if "fault" in opts else self.faults
        start = start_index(opts.get("start"), "option 'start'")
        drawn, stream = draw_episode(self.np_random)
        if start is None:
            start = drawn if self.start is None else self.start
        world = self.world
        world.schedule_faults([])  # the last episode's faults must not fire at this reset
        world.reset(world.arena.start_poses[[start]], seeds=[stream])
        world.schedule_faults(faults)
        return world.observe()[0], {}

    def step(
        self, action: np.ndarray
    ) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        commands = np.asarray(action, dtype=np.float64)
        if commands.shape != (2,):
            raise WorldError(f"action must be (left, right) wheel commands, got {commands.shape}")
        commands = commands.reshape(1, 2)
        self.world.step(commands)
        observed, table = judge(self.world, commands, self.c_from)
        info = {name: float(table[0, column]) for column, name in enumerate(TERM_NAMES)}
        return observed[0], float(table[0, 0]), False, False, info

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        if self._view is None:
            self._view = TopDown(self.world.arena)
        return self._view.frame(self.world.poses[0])


def register_envs() -> None:
    """Register ``GnpLab/WallFollow-v0`` (and its vector entry point) with Gymnasium, once."""
    if ENV_ID in gym.registry:
        return
    gym.register(
        id=ENV_ID,
        entry_point="sim.gym_env:WallFollowEnv",
        vector_entry_point="sim.gym_vector:WallFollowVectorEnv",
        max_episode_steps=LIFE_STEPS,
    )


register_envs()
