"""GNP's controllers in the lab's loop: a population and its engine state, stepped staged or fused.

`GnpControllers` satisfies `app.loop.rollout.Controllers` and offers the loop its compiled
steps (`fused`, `app.brains.gnp_fused`). Numba's: the family imports this module for lives only.
"""

from __future__ import annotations

import numpy as np

import gnp
import sim
from app.brains import gnp_fused
from app.loop.fused import FusedSteps, Watched
from app.loop.rollout import Batch
from app.settings.config import CFrom


class GnpControllers:
    """A `gnp.Population` and its engine state: online Sarsa, ε-greedy (an `OnlineLearner`).
    `second_stage` off is the live ablation of `gnp.step` (BS: greedy branch connection, CS:
    no credit branch), the dashboard's switch."""

    def __init__(
        self, cfg: gnp.GnpConfig, population: gnp.Population, engine_seeds: np.ndarray
    ) -> None:
        self.cfg = cfg
        self.population = population
        self.state = gnp.init_state(cfg, population.size, engine_seeds)
        self.second_stage = True
        self.epsilon, self.alpha, self.learn = 0.0, 0.0, False  # until the loop sets them

    def set_rates(self, epsilon: float, alpha: float, learn: bool) -> None:
        self.epsilon, self.alpha, self.learn = epsilon, alpha, learn

    @property
    def size(self) -> int:
        return self.population.size

    def act(
        self, observations: np.ndarray, reward: np.ndarray, *, trace: bool
    ) -> tuple[np.ndarray, gnp.StepTrace | None]:
        return gnp.step(
            self.cfg,
            self.population,
            self.state,
            observations,
            reward,
            self.epsilon,
            self.alpha,
            self.learn,
            trace=trace,
            second_stage=self.second_stage,
        )

    def reset_episode(self) -> None:
        gnp.reset_episode(self.state)

    def end_episode(self, reward: np.ndarray, terminated: np.ndarray) -> None:
        """`app.brains.contract.TerminalLearner`: Sarsa's terminal update (`gnp.end_episode`)."""
        if self.learn:
            gnp.end_episode(self.cfg, self.population, self.state, reward, self.alpha, terminated)

    @property
    def fused(self) -> FusedSteps:
        """The compiled steps the loop may take: these controllers' own (`fits`, `steps`)."""
        return self

    def fits(self) -> bool:
        """The compiled walk runs the method's second stage: on, or a method without one."""
        return self.second_stage or not self.cfg.traits.two_stage

    def steps(
        self,
        world: sim.World,
        reward: np.ndarray,
        epsilon: np.ndarray,
        alpha: np.ndarray,
        *,
        learn: bool,
        judge_observed: bool,
        term_sums: np.ndarray,
        watch: bool,
    ) -> tuple[np.ndarray, np.ndarray, Watched | None]:
        return gnp_fused.steps(
            world,
            self.cfg,
            self.population,
            self.state,
            reward,
            epsilon,
            alpha,
            learn=learn,
            judge_observed=judge_observed,
            term_sums=term_sums,
            watch=watch,
        )


def gnp_batch(
    world: sim.World,
    cfg: gnp.GnpConfig,
    population: gnp.Population,
    engine_seeds: np.ndarray,
    c_from: CFrom = "true",
) -> Batch:
    """A batch of `world`'s robots driven by `population` (one individual per robot)."""
    if population.size != world.n:
        raise ValueError(f"{population.size} controllers for {world.n} robots")
    return Batch(world, GnpControllers(cfg, population, engine_seeds), c_from)


def gnp_of(batch: Batch) -> GnpControllers:
    """The GNP controllers driving `batch` (their config, population and engine state: the
    ones it steps, not copies); a TypeError for other controllers."""
    if not isinstance(batch.controllers, GnpControllers):
        raise TypeError(f"the batch is driven by {type(batch.controllers).__name__}, not GNP")
    return batch.controllers
