"""`graph.dot`: an individual's node-transition graph for GraphViz.

Nodes are grouped in clusters as the dashboard draws them in columns (app/views/
graph_layout.py): the start node, the judgment nodes per sensor s0..s7, the processing nodes per
wheel. There is one edge per distinct (from, to) pair of the individual's connections (every
branch, every BS branch connection, CS credit branches: app/views/genome.py), weighted by
how often the recorded life took it.
"""

from __future__ import annotations

from collections import Counter

import numpy as np

import gnp
from app.views.genome import genome_view
from app.views.graph_layout import graph_layout
from gnp.config import JUDGMENT, START, WHEEL_NAMES

Transitions = Counter[tuple[int, int]]


def visit_sequence(node: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The nodes visited over a life, in order, from a trace's `node` (T, K) and `count` (T,)."""
    node, count = np.asarray(node), np.asarray(count)
    if node.ndim != 2 or count.shape != node.shape[:1]:
        raise ValueError(f"a trace's node {node.shape} and count {count.shape} do not match")
    return np.concatenate([node[t, : int(count[t])] for t in range(len(count))]).astype(np.int64)


def transition_counts(node: np.ndarray, count: np.ndarray) -> Transitions:
    """How often each (from, to) transition was taken over a recorded life.

    Consecutive visits are transitions, also across control steps (the current node carries
    over). A move to the start node is a new episode, not a connection, and is not counted.
    """
    visits = visit_sequence(node, count)
    pairs: Transitions = Counter()
    for a, b in zip(visits[:-1].tolist(), visits[1:].tolist(), strict=True):
        if b != 0:
            pairs[(a, b)] += 1
    return pairs


def node_caption(cfg: gnp.GnpConfig, individual: gnp.Population, node: int) -> str:
    """`J3` with a line `s2 120..610` per sub node; `P45` with `P0 right +7` per sub node."""
    kind = int(cfg.node_type[node])
    if kind == START:
        return "start"
    lines = []
    for p in range(cfg.n_sub):
        function = int(individual.function[0, node, p])
        if kind == JUDGMENT:
            beta, alpha = int(individual.mu_beta[0, node, p]), int(individual.mu_alpha[0, node, p])
            lines.append(f"s{function} {beta}..{alpha}")
        else:
            lines.append(f"{WHEEL_NAMES[function]} {int(individual.speed[0, node, p]):+d}")
    return "\\n".join([f"{'J' if kind == JUDGMENT else 'P'}{node}", *lines])


def graph_dot(
    cfg: gnp.GnpConfig,
    individual: gnp.Population,
    transitions: Transitions | None,
    title: str,
) -> str:
    """The DOT text of individual 0's graph.

    Args:
        cfg: its gnp config.
        individual: a 1-individual population.
        transitions: (from, to) -> times taken in the recorded life, or None when there is no
            recorded life (every weight is then 0, and a comment says so).
        title: the graph's caption (one line, no quotes).
    """
    view = genome_view(cfg, individual)
    layout = graph_layout(view.kinds, view.column_function)
    taken = transitions if transitions is not None else Counter()
    most = max((taken[(int(a), int(b))] for a, b in view.edges), default=0)
    lines = [f"// GNP node-transition graph: {title}"]
    if transitions is None:
        lines.append("// no recorded life for this generation: every edge weight is 0")
    else:
        total = sum(taken.values())
        lines.append(f"// edge weight = transitions taken in the recorded life ({total} in all)")
    lines += [
        "digraph gnp {",
        f'  label="{title}"; labelloc=t; rankdir=LR; newrank=true;',
        '  node [shape=box, style="rounded,filled", fillcolor=white, fontname="Helvetica",'
        " fontsize=10];",
        '  edge [fontname="Helvetica", fontsize=8, arrowsize=0.6];',
    ]
    fills = {START: "gray85", JUDGMENT: "lightblue", 2: "palegreen"}
    for column, name in enumerate(layout.column_names):
        members = np.flatnonzero(layout.column_of == column)
        if not members.size:
            continue
        lines.append(f'  subgraph cluster_{column} {{ label="{name}"; style=rounded; color=gray60;')
        for node in members.tolist():
            caption = node_caption(cfg, individual, node)
            fill = fills[int(view.kinds[node])]
            lines.append(f'    n{node} [label="{caption}", fillcolor={fill}];')
        lines.append("  }")
    for a, b in view.edges.tolist():
        n = taken[(a, b)]
        if n:
            width = 1.0 + 4.0 * n / most
            attrs = f'weight={n}, penwidth={width:.2f}, label="{n}"'
        else:
            attrs = "weight=0, penwidth=0.5, style=dashed, color=gray70"
        lines.append(f"  n{a} -> n{b} [{attrs}];")
    lines.append("}")
    return "\n".join(lines) + "\n"
