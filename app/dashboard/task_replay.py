"""A task run's best individual living its task again, step by step, for the dashboard (no viser).

`TaskReplay` is `app.tasks.replay_task` one step at a time, for any brain family (through the
contract): the generation's best from the run file, its controller seeded with the episode's
seed, the episode reset with that seed, learning online with the generation's ε and α (ε = 0
when greedy) if its family does, the terminal update when the episode terminates (GNP's Sarsa),
at most the run's `steps` per episode; its first episode is the one `replay_task(path, seed)`
lives (tested for GNP and a net). When an episode ends the next starts at once from seed + 1,
what the controller learned kept. It records what the views draw: the episode's return so far,
the last returns, what the family's tracer keeps (GNP's visits of the node-transition graph, a
net's activations), and the task's frame on demand.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import gnp
from app.brains import TerminalLearner
from app.dashboard.stage import MAX_STEPS_PER_ADVANCE
from app.dashboard.task_frame import task_frame
from app.loop.rollout import OnlineLearner
from app.phases.live import RobotSnapshot
from app.tasks.common import TaskError
from app.tasks.config import make_env
from app.tasks.faults import ObservationFault, ObservationFaults
from app.tasks.spaces import TaskAdapter
from app.tasks.store import read_task_run
from gnp.config import JUDGMENT, START

#: Short names of the observation features and actions of tasks the lab knows (captions of
#: the graph's columns); any other task's are `f0`, `f1`, ... and `action` / `a0`, `a1`, ...
FEATURE_NAMES: dict[str, tuple[str, ...]] = {
    "CartPole-v0": ("cart x", "cart v", "pole θ", "pole ω"),
    "CartPole-v1": ("cart x", "cart v", "pole θ", "pole ω"),
    "MountainCar-v0": ("x", "v"),
    "MountainCarContinuous-v0": ("x", "v"),
    "Pendulum-v1": ("cos θ", "sin θ", "ω"),
    "Acrobot-v1": ("cos θ1", "sin θ1", "cos θ2", "sin θ2", "ω1", "ω2"),
}
ACTION_NAMES: dict[str, str] = {
    "CartPole-v0": "push ← | →",
    "CartPole-v1": "push ← | →",
    "MountainCar-v0": "push ← | 0 | →",
    "Acrobot-v1": "torque − | 0 | +",
}


def feature_captions(task: str, n: int) -> tuple[str, ...]:
    """`f2 pole θ`: each judgment column's feature index and, if known, its name."""
    names = FEATURE_NAMES.get(task, ())
    return tuple(f"f{j} {names[j]}" if j < len(names) == n else f"f{j}" for j in range(n))


def action_captions(
    task: str, n_outputs: int, discrete: bool, per_action: bool = False
) -> tuple[str, ...]:
    """The processing columns: one for a Discrete action, one per component of a Box; with
    `per_action` (`GnpConfig.processing_output` "function") one per action, the function."""
    if discrete and per_action:
        return tuple(f"action {k}" for k in range(n_outputs))
    if discrete:
        return (f"action ({ACTION_NAMES[task]})" if task in ACTION_NAMES else "action",)
    return tuple(f"a{j}" for j in range(n_outputs))


def captions(cfg: gnp.GnpConfig, adapter: TaskAdapter, task: str) -> tuple[str, ...]:
    """`action_captions` of a task run's brain: its outputs as its processing nodes set them."""
    per_action = cfg.processing_output == "function"
    count = cfg.n_outputs if per_action else adapter.n_outputs
    return action_captions(task, count, adapter.kind == "discrete", per_action)


@dataclass(frozen=True)
class TaskReplayRequest:
    """What to replay: a task run file, a generation's best (None: the last), the first
    episode's seed, greedy or the generation's ε, learning online, observation faults."""

    path: Path
    generation: int | None = None
    seed: int = 0
    greedy: bool = True
    learn: bool = True
    faults: tuple[ObservationFault, ...] = ()


@dataclass(frozen=True)
class TaskStatus:
    """What the readout says about the replay now."""

    task: str
    generation: int
    episode: int  # 0, 1, ... since the replay started
    seed: int  # the episode's seed
    t: int  # steps into the episode
    episode_return: float  # so far
    returns: tuple[float, ...]  # of the episodes ended, oldest first (the last 20)
    current_node: int
    action: str
    broken: tuple[int, ...]  # features broken now


def _render_env(
    task: str, faults: Sequence[ObservationFault], adapter: TaskAdapter, seed: int
) -> Any:
    """The task's env drawing rgb_array frames, with the observation faults if any."""
    env = make_env(task, render_mode="rgb_array")
    if faults:
        env = ObservationFaults(env, faults, adapter.obs_low, adapter.obs_high, seed)
    return env


class TaskReplay:
    """The replay of `request` (see the module docstring), through the brain contract: any
    family's controllers (`BrainFamily.controllers`, rates set if they learn online, the
    terminal update of a `TerminalLearner`), its tracer feeding the views (GNP's graph:
    `cfg`, `population`; a net's network: `net`).

    Raises:
        RunFileError: the file is missing, not a task run, or has no such generation.
        TaskError: the task cannot be made here (an extra missing), a fault is out of range,
            or the run's family is not registered here.
    """

    def __init__(self, request: TaskReplayRequest) -> None:
        run = read_task_run(request.path)
        if run.generation_done == 0:
            raise TaskError(f"{request.path.stem} has no generation done yet")
        g = run.generation_done - 1 if request.generation is None else request.generation
        if g < 0:
            g += run.generation_done
        individual = run.best_individual(g)
        self.config = run.config
        self.family = self.config.family
        self.cfg = self.family.graph_config  # GNP's node graph (None: no graph to draw)
        self.net = self.family.network_config  # a net's network (None: no net)
        self.adapter = self.config.adapter
        self.request = request
        self.task = self.config.task.id
        self.generation = g
        self.epsilon = 0.0 if request.greedy else float(run.epsilon[g])
        self.alpha = float(run.alpha[g])
        self.population = self.family.copies(individual, 1)  # learns; the file's stays
        self.env = _render_env(self.task, request.faults, self.adapter, request.seed)
        seeds = np.array([request.seed], np.uint64)
        self.controllers = self.family.controllers(self.population, seeds)
        if isinstance(self.controllers, OnlineLearner):
            self.controllers.set_rates(self.epsilon, self.alpha, request.learn)
        self.speed = 30.0  # steps per second of wall time
        self.playing = True
        self.episode = -1
        self.returns: list[float] = []
        self._owed = 0.0
        self._action = "—"
        self._begin()

    @property
    def seed(self) -> int:
        """The seed of the episode under way."""
        return self.request.seed + self.episode

    def _begin(self) -> None:
        """A new episode from the next seed; the controller back at its start (GNP's start
        node, a net's zero context), its tracer anew (the views show this episode)."""
        self.episode += 1
        if self.episode:
            self.controllers.reset_episode()
        obs, _ = self.env.reset(seed=self.seed)
        self._obs = np.asarray(obs)
        self._readings = self.adapter.observe(self._obs[None])[0]
        self._commands = np.zeros(self.adapter.n_outputs)
        self._reward = np.zeros(1)
        self._tracer = self.family.tracer()
        self.t = 0
        self.episode_return = 0.0

    @property
    def current_node(self) -> int:
        """The node GNP's walk is at (0, the start, for a family without a graph)."""
        return int(self._tracer.view().get("current_node", 0))

    def step(self, steps: int = 1) -> None:
        """`steps` steps of the task (a new episode after one ends)."""
        for _ in range(steps):
            self._step()

    def _step(self) -> None:
        readings = self.adapter.observe(self._obs[None])
        commands, trace = self.controllers.act(readings, self._reward, trace=True)
        self._tracer.record(trace)
        self._readings, self._commands = readings[0], np.asarray(commands, np.float64)[0]
        action = self.adapter.act(commands)[0]
        self._action = str(np.round(action, 2)) if np.ndim(action) else str(int(action))
        obs, reward, terminated, truncated, _ = self.env.step(action)
        self._obs = np.asarray(obs)
        self.t += 1
        self.episode_return += float(reward)
        self._reward = np.array([float(reward)])
        if terminated and isinstance(self.controllers, TerminalLearner):
            self.controllers.end_episode(self._reward, np.ones(1, bool))
        if terminated or truncated or self.t >= self.config.training.steps:
            self.returns = [*self.returns[-19:], self.episode_return]
            self._begin()

    def advance(self, seconds: float) -> int:
        """Step for `seconds` of wall time at `speed` (at most 50 steps); the steps taken."""
        if not self.playing:
            return 0
        self._owed += seconds * self.speed
        steps = min(int(self._owed), MAX_STEPS_PER_ADVANCE)
        self._owed = min(self._owed - steps, 1.0)
        self.step(steps)
        return steps

    def frame(self) -> np.ndarray:
        """The task's picture now (raises `FrameError` when it has none)."""
        return task_frame(self.env)

    def broken(self) -> tuple[int, ...]:
        """The features broken at this step of the episode."""
        hit = {j for f in self.request.faults if self.t >= f.step for j in f.features}
        return tuple(sorted(hit))

    def status(self) -> TaskStatus:
        return TaskStatus(
            task=self.task,
            generation=self.generation,
            episode=self.episode,
            seed=self.seed,
            t=self.t,
            episode_return=self.episode_return,
            returns=tuple(self.returns),
            current_node=self.current_node,
            action=self._action,
            broken=self.broken(),
        )

    def node_words(self, node: int) -> str:
        """`node 12 · J f2 pole θ/f0 cart x` / `node 47 · P action −5/action +9`: what a node's
        sub nodes judge or set; for a family without a graph, its description and last outputs
        (`cmaes: Elman net, 8 hidden · outputs +0.31`)."""
        if self.cfg is None:
            given = " ".join(f"{v:+.2f}" for v in self._commands)
            return f"{self.family.description} · outputs {given}"
        kind = int(self.cfg.node_type[node])
        functions = self.population.function[0, node]
        if kind == JUDGMENT:
            names = feature_captions(self.task, self.adapter.n_inputs)
            return f"node {node} · J " + "/".join(names[int(f)] for f in functions)
        if kind == START:
            return f"node {node} · start"
        outputs = captions(self.cfg, self.adapter, "")
        if self.cfg.processing_output == "function":  # the function is the action
            return f"node {node} · P " + "/".join(outputs[int(f)] for f in functions)
        speeds = self.population.speed[0, node]
        sets = (f"{outputs[int(f)]} {int(v):+d}" for f, v in zip(functions, speeds, strict=True))
        return f"node {node} · P " + "/".join(sets)

    def snapshot(self) -> RobotSnapshot:
        """The views' picture of the controller: what its family's tracer keeps (GNP's visits,
        a net's activations), the readings it took and the commands it gave (the robot's
        other fields at rest)."""
        return RobotSnapshot(
            label=self.task,
            method=self.family.label,
            t=self.t,
            pose=np.zeros(3),
            true_readings=self._readings.copy(),
            seen_readings=self._readings.copy(),
            broken=np.isin(np.arange(self.adapter.n_inputs), self.broken()),
            fault_mode=None,
            trajectory=np.zeros((0, 2)),
            trajectory_reward=np.zeros(0),
            reward_steps=np.zeros(0, np.int64),
            rewards=np.zeros(0),
            broken_counts=np.zeros(0, np.int64),
            fault_steps=(),
            epsilon=self.epsilon,
            alpha=self.alpha,
            mean_reward=0.0,
            commands=self._commands.copy(),
            learns_online=self.family.learns_online,
            **self._tracer.view(),
        )

    def close(self) -> None:
        self.env.close()
