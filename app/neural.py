"""Neural controllers in the lab loop: `neuro` nets behind `app.rollout.Controllers`.

The nets see IR readings scaled to [0, 1] (÷ `sim.IR_MAX`) and their outputs in [−1, 1] become
wheel commands (× `sim.MAX_COMMAND`). They do not learn online: ε, α and `learn` are ignored.
A step's trace is the nets' activations (what the dashboard draws); a new episode zeroes them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import gnp
import neuro
import sim
from app.config import CFrom
from app.recording import TraceLayout
from app.rollout import Batch
from app.store import RunReader


@dataclass(frozen=True)
class NeuralTrace:
    """What N nets did in one step."""

    activation: np.ndarray  # (N, units) each net's units after the step (Elman: context)


def trace_layout(net: neuro.NetConfig) -> TraceLayout:
    """The recorded trace of one net: its units' activations per step."""
    return {"activation": ((net.n_units,), np.dtype(np.float64))}


class NeuralControllers:
    """N neural controllers, one per robot (satisfies `app.rollout.Controllers`)."""

    def __init__(self, net: neuro.NetConfig, arrays: dict[str, np.ndarray]) -> None:
        self.net = net
        self.arrays = arrays
        self.state = neuro.init_state(net, neuro.check_arrays(net, arrays))

    @property
    def size(self) -> int:
        return len(self.state)

    def act(
        self,
        observations: np.ndarray,
        reward: np.ndarray,
        epsilon: float,
        alpha: float,
        *,
        learn: bool,
        trace: bool,
        second_stage: bool,
    ) -> tuple[np.ndarray, NeuralTrace | None]:
        outputs = neuro.step(self.net, self.arrays, self.state, observations / sim.IR_MAX)
        commands = outputs * sim.MAX_COMMAND
        return commands, NeuralTrace(self.state.copy()) if trace else None

    def reset_episode(self) -> None:
        self.state[...] = 0.0


# --- either family: what the phases handle without asking which brain it is -----------------

#: The brain of one trained individual: a GNP config, or a net's.
BrainConfig = gnp.GnpConfig | neuro.NetConfig
#: One individual: a 1-individual `gnp.Population`, or one net's arrays (leading axis 1).
Individual = gnp.Population | dict[str, np.ndarray]


def copies(
    world: sim.World,
    cfg: BrainConfig,
    individual: Individual,
    engine_seeds: np.ndarray,
    c_from: CFrom = "true",
) -> Batch:
    """A batch driving each of `world`'s robots with its own copy of `individual` (GNP copies
    learn apart, each from its own engine seed; nets ignore the seeds); the reward's C judged
    as `c_from` says."""
    every = np.zeros(world.n, np.int64)
    if isinstance(cfg, gnp.GnpConfig):
        assert isinstance(individual, gnp.Population)
        return Batch(world, cfg, gnp.take(individual, every), engine_seeds, c_from)
    assert isinstance(individual, dict)
    return Batch.driven_by(world, NeuralControllers(cfg, neuro.take(individual, every)), c_from)


def recorded_trace(cfg: BrainConfig) -> gnp.GnpConfig | TraceLayout:
    """What `TrajectoryRecorder` records of this brain's steps."""
    return cfg if isinstance(cfg, gnp.GnpConfig) else trace_layout(cfg)


def best_individual(run: RunReader, generation: int = -1) -> tuple[BrainConfig, Individual]:
    """A generation's best of a run of either family (`RunReader.best_genome` for GNP)."""
    settings = run.config.neuro
    if settings is None:
        return run.best_genome(generation)
    net = settings.net_config()
    arrays = run.best_genome_arrays(generation)
    neuro.check_arrays(net, arrays)
    return net, arrays
