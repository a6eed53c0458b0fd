"""A plain-Python interpreter of ONE controller: the test oracle for the compiled engine.

It is written for reading, not speed: one visit at a time, the episode's visits kept in a list.
Given the same genome, seed, observations and rewards it must reproduce `gnp.step` transition
for transition and Q value for Q value (it draws the same splitmix64 numbers in the same order).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gnp.config import (
    JUDGMENT,
    NODE_COST,
    SKIP_COST,
    START,
    STEP_BUDGET,
    GnpConfig,
)
from gnp.population import Population
from gnp.rng import py_mix64, py_next_uniform


@dataclass
class Visit:
    """One node visit: the actions chosen there and the reward it earned."""

    node: int
    sub: int
    branch: int  # A = 0, B = 1, … (`judgment_branches`); −1 for a credit skip
    u: int  # branch connection (BS), else 0; −1 for a credit skip
    credit: bool  # skipped through the credit branch (CS)
    reward: float = 0.0


class ReferenceController:
    """One GNP controller with Sarsa learning; owns copies of one individual's genes."""

    def __init__(self, cfg: GnpConfig, pop: Population, index: int, seed: int) -> None:
        self.cfg = cfg
        gene_fields = ("function", "mu_beta", "mu_alpha", "speed", "conn", "credit")
        self.genes = {f: np.array(getattr(pop, f)[index]) for f in gene_fields}
        # Q values are stored as the population stores them (float32); updates compute in
        # float64 and round on store, as the engine does.
        self.q_ss = np.array(pop.q_ss[index])
        self.q_bs = np.array(pop.q_bs[index])
        self.q_cs = np.array(pop.q_cs[index])
        self.stream = py_mix64(seed)
        self.node = 0
        self.left = 0.0
        self.right = 0.0
        self.visits: list[Visit] = []

    def reset_episode(self, seed: int | None = None) -> None:
        """Back to the start node; Q tables kept."""
        if seed is not None:
            self.stream = py_mix64(seed)
        self.node = 0
        self.left = self.right = 0.0
        self.visits = []

    def uniform(self) -> float:
        self.stream, value = py_next_uniform(self.stream)
        return value

    def epsilon_greedy(self, values: list[float], epsilon: float) -> int:
        """Random action with probability ε, else a uniformly chosen maximum (the first one
        with `tie_break` "first")."""
        if self.uniform() < epsilon:
            return min(int(self.uniform() * len(values)), len(values) - 1)
        best = max(values)
        maxima = [a for a, v in enumerate(values) if v == best]
        if len(maxima) == 1 or self.cfg.tie_break == "first":
            return maxima[0]
        return maxima[min(int(self.uniform() * len(maxima)), len(maxima) - 1)]

    def step(
        self,
        sensors: list[float],
        reward: float,
        epsilon: float,
        alpha: float,
        learn: bool = True,
        second_stage: bool = True,
    ) -> tuple[tuple[float, float], list[Visit]]:
        """One world step: returns ((left, right), the visits made in this step).

        With `second_stage` off, BS takes the greedy branch connection (ties to the lowest u, no
        draw) and CS never its credit branch (no draw); neither updates its second-stage Q.
        """
        cfg, g = self.cfg, self.genes
        if self.visits and (not self.visits[-1].credit or self.cfg.skip_reward == "step"):
            self.visits[-1].reward = reward  # the previous step's last visit earns its reward
        made: list[Visit] = []
        used = 0
        while used < STEP_BUDGET:
            node = self.node
            kind = int(cfg.node_type[node])
            if kind == START:
                made.append(Visit(node, 0, 0, 0, False))
                self.node = int(g["conn"][node, 0, 0, 0])
                continue
            sub = self.epsilon_greedy(list(self.q_ss[node]), epsilon)
            credit = False
            if cfg.traits.credit and second_stage:
                credit = self.epsilon_greedy(list(self.q_cs[node, sub]), epsilon) == 1
            if learn:
                self.learn(node, sub, credit, alpha, second_stage)
            if credit:
                used += SKIP_COST
                visit = Visit(node, sub, -1, -1, True)
                self.node = int(g["credit"][node, sub])
            else:
                used += NODE_COST[kind]
                function = int(g["function"][node, sub])
                if kind == JUDGMENT:
                    beta, alpha_mu = g["mu_beta"][node, sub], g["mu_alpha"][node, sub]
                    branch = self.judge(sensors[function], beta, alpha_mu)
                else:
                    speed = float(g["speed"][node, sub])
                    if cfg.processing_output == "function":  # output 0 (P0), bin centre
                        self.right = (function + 0.5) * 20.0 / cfg.n_outputs - 10.0
                    elif function == 0:
                        self.right = speed
                    else:
                        self.left = speed
                    branch = 0
                u = 0
                if cfg.traits.branch_selection and second_stage:
                    u = self.epsilon_greedy(list(self.q_bs[node, sub, branch]), epsilon)
                elif cfg.traits.branch_selection:
                    values = list(self.q_bs[node, sub, branch])
                    u = values.index(max(values))  # the first maximum: ties to the lowest u
                visit = Visit(node, sub, branch, u, False)
                self.node = int(g["conn"][node, sub, branch, u])
            made.append(visit)
            self.visits.append(visit)
        return (self.left, self.right), made

    def judge(self, x: float, beta: int, alpha: int) -> int:
        """Branch A (0) or B (1) of a judgment sub node (Eq. 2.1–2.2, or the crisp threshold);
        crisp with k = `judgment_branches` > 2, branch k − 1 − i of the i-th of k equal bins
        of β..α (edges β + j(α − β)/k belong to the bin above; x ≤ β: bin 0, x ≥ α: bin k − 1).
        """
        k = self.cfg.judgment_branches
        if not self.cfg.fuzzy and k > 2:
            low, width = int(beta), int(alpha) - int(beta)
            inner_edges_passed = sum(k * (x - low) >= j * width for j in range(1, k))
            return k - 1 - inner_edges_passed
        if not self.cfg.fuzzy:
            return 0 if x >= (beta + alpha) / 2.0 else 1
        if x >= alpha:
            mu = 1.0
        elif x <= beta:
            mu = 0.0
        else:
            mu = (x - beta) / (alpha - beta)
        return 0 if self.uniform() < mu else 1

    def learn(
        self, node: int, sub: int, credit: bool, alpha: float, second_stage: bool = True
    ) -> None:
        """Sarsa updates once the new visit (node, sub, credit) has chosen its actions; with
        the second stage off only Q_SS."""
        if not self.visits:
            return
        gamma = self.cfg.gamma
        last = self.visits[-1]
        r = last.reward

        def update(table: np.ndarray, key: tuple[int, ...], target: float) -> None:
            old = float(table[key])
            table[key] = old + alpha * (target - old)

        # Eq. 2.3 / 3.1 / 5.1: Q_SS(i, ip) += α(r_t + γ Q_SS(j, jp') − Q_SS(i, ip)).
        update(self.q_ss, (last.node, last.sub), r + gamma * float(self.q_ss[node, sub]))
        if self.cfg.traits.credit and second_stage:
            # Eq. 5.2 / 5.3 (a credit skip earned r = 0): bootstrap on the chosen CS action.
            target = r + gamma * float(self.q_cs[node, sub, int(credit)])
            update(self.q_cs, (last.node, last.sub, int(last.credit)), target)
        if self.cfg.traits.branch_selection and second_stage and len(self.visits) >= 2:
            # Eq. 3.2: the branch connection chosen at t led to the last visit, whose reward
            # is r_{t+1}; bootstrap on the branch connection the last visit chose.
            before = self.visits[-2]
            key = (before.node, before.sub, before.branch, before.u)
            target = r + gamma * float(self.q_bs[last.node, last.sub, last.branch, last.u])
            update(self.q_bs, key, target)
