"""``GnpLab/WallFollow-v0`` as a Gymnasium vector env: N robots in one batched `sim.World`.

    envs = gymnasium.make_vec("GnpLab/WallFollow-v0", num_envs=300, noise=50.0)

Robot i of the vector env is the single env (`sim.gym_env.WallFollowEnv`) that Gymnasium's
``SyncVectorEnv`` would hold at index i, bit for bit: ``reset(seed=s)`` seeds robot i's generator
with s + i (as ``SyncVectorEnv`` seeds its envs), or with ``seed[i]`` for a list; each robot's
generator draws its start pose and noise stream; and a robot's trajectory in the batched world
never depends on the other robots. The options are the single env's (see `sim.gym_env`), a
fault taking ``"robots": [...]`` as well, ``"start"`` an index or one per robot.

Autoreset is Gymnasium's default, next step (``metadata["autoreset_mode"]``). The task has no
terminal state and every episode lasts ``max_episode_steps``, so all robots' episodes end at the
same step, and the next ``step`` starts a new episode for every robot (ignoring its actions,
returning reward 0), as ``SyncVectorEnv`` would; ``reset`` has no partial form (``reset_mask``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from sim.faults import WorldError
from sim.gym_env import (
    ArenaArg,
    TopDown,
    action_space,
    build_world,
    check_options,
    draw_episode,
    judge,
    metadata,
    observation_space,
    parse_faults,
    start_index,
)
from sim.khepera import LIFE_STEPS
from sim.kinds import DEFAULT_PHYSICS
from sim.reward import TERM_NAMES, CFrom
from sim.world import Physics


class WallFollowVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """N robots following walls, stepped in one call (see the module docstring).

    Args:
        num_envs: Number of robots N.
        max_episode_steps: Episode length (truncation), a training life by default.
        arena, noise, physics, c_from, fault, start, render_mode: as `WallFollowEnv`'s; a
            ``fault`` may name ``robots``.
    """

    metadata = metadata() | {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        arena: ArenaArg = "training",
        noise: float = 0.0,
        physics: Physics = DEFAULT_PHYSICS,
        c_from: CFrom = "true",
        fault: object = None,
        start: int | None = None,
        max_episode_steps: int = LIFE_STEPS,
        render_mode: str | None = None,
    ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int | np.integer) or num_envs < 1:
            raise WorldError(f"num_envs must be a positive int, got {num_envs!r}")
        if (
            isinstance(max_episode_steps, bool)
            or not isinstance(max_episode_steps, int | np.integer)
            or max_episode_steps < 1
        ):
            raise WorldError(f"max_episode_steps must be a positive int, got {max_episode_steps!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise WorldError(f"unknown render_mode {render_mode!r}: expected None or rgb_array")
        self.num_envs = int(num_envs)
        self.world = build_world(arena, self.num_envs, noise, physics, c_from, start)
        self.c_from: CFrom = c_from
        self.faults = parse_faults(fault, "fault", robots_allowed=True)
        self.world.schedule_faults(self.faults)  # checks the robot indices now
        self.start = start_index(start, "start")
        self.max_episode_steps = int(max_episode_steps)
        self.render_mode = render_mode
        self.single_observation_space = observation_space()
        self.single_action_space = action_space()
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._rngs: list[np.random.Generator] = []
        self._steps = 0
        self._autoreset = False
        self._view: TopDown | None = None

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode of every robot (seeds and options: see the module docstring)."""
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, int | np.integer):
            super().reset(seed=int(seed))
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise WorldError(f"seed must be an int or {n} seeds (one per robot), got {seed!r}")
        if not self._rngs:
            self._rngs = [seeding.np_random(s)[0] for s in seeds]
        else:
            for i, s in enumerate(seeds):
                if s is not None:
                    self._rngs[i] = seeding.np_random(s)[0]
        return self._start(check_options(options)), {}

    def _start(self, options: dict[str, Any]) -> np.ndarray:
        faults = parse_faults(options["fault"], "fault", True) if "fault" in options else None
        starts = self._starts(options.get("start"))
        drawn = np.array([draw_episode(rng) for rng in self._rngs], dtype=np.int64)
        poses = np.where(starts < 0, drawn[:, 0], starts)
        world = self.world
        world.schedule_faults([])  # the last episode's faults must not fire at this reset
        world.reset(world.arena.start_poses[poses], seeds=drawn[:, 1])
        world.schedule_faults(self.faults if faults is None else faults)
        self._steps = 0
        self._autoreset = False
        return world.observe()

    def _starts(self, option: object) -> np.ndarray:
        """Each robot's start pose index, −1 where it is drawn."""
        n = self.num_envs
        if option is None:
            return np.full(n, -1 if self.start is None else self.start)
        if isinstance(option, int | np.integer):
            return np.full(n, start_index(option, "option 'start'"))
        if not isinstance(option, Sequence) or len(option) != n:
            raise WorldError(f"option 'start' must be an index in 0..9 or {n} of them")
        return np.array([start_index(s, "option 'start'") for s in option])

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One control period of every robot: actions (N, 2) left, right wheel commands."""
        n = self.num_envs
        if not self._rngs:
            raise WorldError("call reset() before step()")
        if self._autoreset:  # next-step autoreset: every episode ended at the last step
            observed = self._start({})
            return observed, np.zeros(n), np.zeros(n, bool), np.zeros(n, bool), {}
        commands = np.asarray(actions, dtype=np.float64)
        if commands.shape != (n, 2):
            raise WorldError(f"actions must have shape ({n}, 2), got {commands.shape}")
        self.world.step(commands)
        observed, table = judge(self.world, commands, self.c_from)
        self._steps += 1
        self._autoreset = self._steps >= self.max_episode_steps
        terms = table.T.copy()  # one contiguous row per term, fresh every step
        every = np.ones(n, dtype=bool)  # Gymnasium's mask of the robots an info key holds
        info: dict[str, Any] = {}
        for name, column in zip(TERM_NAMES, terms, strict=True):
            info[name] = column
            info[f"_{name}"] = every
        truncated = np.full(n, self._autoreset)
        return observed, terms[0].copy(), np.zeros(n, bool), truncated, info

    def render(self) -> tuple[np.ndarray, ...] | None:
        """A top-down frame of each robot (``render_mode="rgb_array"``), else None."""
        if self.render_mode != "rgb_array":
            return None
        if self._view is None:
            self._view = TopDown(self.world.arena)
        view = self._view
        return tuple(view.frame(pose) for pose in self.world.poses)
