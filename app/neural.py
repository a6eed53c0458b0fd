"""Neural controllers in the lab loop: `neuro` nets behind `app.rollout.Controllers`.

The nets see IR readings scaled to [0, 1] (÷ `sim.IR_MAX`) and their outputs in [−1, 1] become
wheel commands (× `sim.MAX_COMMAND`). They do not learn online: ε, α and `learn` are ignored.
A step's trace is the nets' activations (what the dashboard draws); a new episode zeroes them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import neuro
import sim
from app.recording import TraceLayout


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
