"""What the dashboard reads from one GNP individual: node kinds, columns, edges, and the
inspector's text for a node (sub nodes, parameters, connections, Q values)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import gnp
from gnp.config import BRANCH_NAMES, JUDGMENT, START, WHEEL_NAMES


@dataclass(frozen=True)
class GenomeView:
    """The static shape of an individual's graph.

    Attributes:
        kinds: (V,) START, JUDGMENT or PROCESSING.
        column_function: (V,) sensor or wheel of each node's first sub node (its column).
        edges: (E, 2) distinct (from, to) node pairs over every connection the individual has
            (every branch, every BS branch connection, CS credit branches).
    """

    kinds: np.ndarray
    column_function: np.ndarray
    edges: np.ndarray
    inputs: tuple[str, ...] | None = None  # a task's feature captions (None: the robot's)
    outputs: tuple[str, ...] | None = None  # a task's action captions (None: the wheels)


def genome_view(
    cfg: gnp.GnpConfig,
    population: gnp.Population,
    inputs: tuple[str, ...] | None = None,
    outputs: tuple[str, ...] | None = None,
) -> GenomeView:
    """The graph of individual 0 of `population` (`inputs`, `outputs`: a task's captions of
    its judgment and processing columns; default the robot's sensors and wheels)."""
    kinds = np.asarray(cfg.node_type, np.int64)
    function = population.function[0]
    conn = population.conn[0]  # (V, m, k, U)
    pairs: list[tuple[int, int]] = []
    for node, kind in enumerate(kinds):
        if kind == START:
            targets = conn[node, 0, 0, :1]
        elif kind == JUDGMENT:
            targets = conn[node].reshape(-1)
        else:
            targets = conn[node, :, 0, :].reshape(-1)
        if cfg.traits.credit and kind != START:
            targets = np.concatenate([targets, population.credit[0, node]])
        pairs.extend((node, int(t)) for t in targets)
    edges = np.unique(np.array(pairs, np.int64).reshape(-1, 2), axis=0)
    return GenomeView(kinds, function[:, 0].astype(np.int64), edges, inputs, outputs)


def node_label(cfg: gnp.GnpConfig, population: gnp.Population, node: int) -> str:
    """Short name of a node: `12 · J s3/s5` (judgment, sensors of its sub nodes), `47 · P right`."""
    kind = int(cfg.node_type[node])
    if kind == START:
        return f"{node} · start"
    functions = population.function[0, node]
    if kind == JUDGMENT:
        return f"{node} · J " + "/".join(f"s{f}" for f in functions)
    return f"{node} · P " + "/".join(WHEEL_NAMES[f].split()[1] for f in functions)


def node_markdown(cfg: gnp.GnpConfig, population: gnp.Population, node: int) -> str:
    """The inspector's view of one node: a table row per sub node with its Q values."""
    kind = int(cfg.node_type[node])
    pop = population
    if kind == START:
        return f"**Node {node}: start** → node {int(pop.conn[0, node, 0, 0, 0])}"
    lines = [f"**Node {node_label(cfg, pop, node)}** ({cfg.method}, m = {cfg.n_sub})", ""]
    u = cfg.n_conn_branches
    k = cfg.judgment_branches
    names = BRANCH_NAMES[:k]  # A, B (C, … with more branches)
    if kind == JUDGMENT:
        header = "| sub | sensor | β..α | " + " | ".join(f"→ {b}" for b in names) + " | Q_SS |"
    else:
        header = "| sub | wheel | speed | → | Q_SS |"
    if cfg.traits.branch_selection:
        header += f" Q_BS {' / '.join(names)} (per u) |"
    if cfg.traits.credit:
        header += " Q_CS normal / credit | credit → |"
    lines += [header, _rule(header)]
    for p in range(cfg.n_sub):
        targets = [",".join(str(int(t)) for t in pop.conn[0, node, p, b, :u]) for b in range(k)]
        a_targets = targets[0]
        q_ss = f"{pop.q_ss[0, node, p]:.3f}"
        if kind == JUDGMENT:
            row = (
                f"| {p} | s{int(pop.function[0, node, p])} | "
                f"{int(pop.mu_beta[0, node, p])}..{int(pop.mu_alpha[0, node, p])} | "
                f"{' | '.join(targets)} | {q_ss} |"
            )
        else:
            wheel = WHEEL_NAMES[int(pop.function[0, node, p])]
            row = f"| {p} | {wheel} | {int(pop.speed[0, node, p]):+d} | {a_targets} | {q_ss} |"
        if cfg.traits.branch_selection:
            q_bs = [",".join(f"{q:.3f}" for q in pop.q_bs[0, node, p, b, :u]) for b in range(k)]
            row += f" {' / '.join(q_bs)} |" if kind == JUDGMENT else f" {q_bs[0]} |"
        if cfg.traits.credit:
            q_n, q_c = pop.q_cs[0, node, p]
            row += f" {q_n:.3f} / {q_c:.3f} | {int(pop.credit[0, node, p])} |"
        lines.append(row)
    return "\n".join(lines)


def _rule(header: str) -> str:
    return "|" + "---|" * (header.count("|") - 1)
