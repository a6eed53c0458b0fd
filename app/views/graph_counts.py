"""What the simplified graph shows: pure functions of a robot's visit history (no viser here).

The full graph draws every connection of the genome; the simplified one draws only the nodes
visited in the current life and the transitions taken over a recent window of visits, each
shaded by how often it was taken, so the program the robot actually runs stands out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FULL, SIMPLIFIED = "full", "simplified"
GRAPH_MODES = (FULL, SIMPLIFIED)
WINDOW = 256
"""Visits over which the simplified graph counts transitions (~ 80 control steps)."""


@dataclass(frozen=True)
class GraphCounts:
    """Visits and transitions counted over a window of a visit history.

    Attributes:
        node_visits: (V,) how often each node was visited in the window.
        edges: (E, 2) distinct (from, to) node pairs taken in the window, sorted.
        edge_counts: (E,) how often each of them was taken (≥ 1).
        window: the number of visits counted.
    """

    node_visits: np.ndarray
    edges: np.ndarray
    edge_counts: np.ndarray
    window: int


def graph_counts(visits: np.ndarray, n_nodes: int, window: int = WINDOW) -> GraphCounts:
    """Count node visits and transitions over the last `window` visits of a history.

    Args:
        visits: (K, ≥ 1) visit history, oldest first; column 0 is the node visited (the rest,
            sub node, branch, u, skipped, as in `RobotSnapshot.visits`, is ignored).
        n_nodes: number of nodes of the graph (node 0 the start node).
        window: how many of the latest visits to count (≥ 1).

    A transition is a pair of consecutive visits in the window. One into the start node is a
    new episode, not a connection, and is not counted.

    Raises:
        ValueError: a bad window, or a node outside 0..n_nodes − 1.
    """
    if window < 1:
        raise ValueError(f"the window must be ≥ 1 visit, got {window}")
    history = np.asarray(visits)
    if history.ndim != 2:
        raise ValueError(f"a visit history is (K, ≥ 1), got shape {history.shape}")
    nodes = history[-window:, 0].astype(np.int64)
    if len(nodes) and (nodes.min() < 0 or nodes.max() >= n_nodes):
        raise ValueError(f"visited nodes must be in 0..{n_nodes - 1}")
    node_visits = np.bincount(nodes, minlength=n_nodes)
    pairs = np.stack([nodes[:-1], nodes[1:]], axis=1)
    pairs = pairs[pairs[:, 1] != 0]
    if len(pairs):
        edges, counts = np.unique(pairs, axis=0, return_counts=True)
    else:
        edges, counts = np.zeros((0, 2), np.int64), np.zeros(0, np.int64)
    return GraphCounts(node_visits, edges.astype(np.int64), counts.astype(np.int64), len(nodes))


def edge_shades(
    counts: np.ndarray,
    color: tuple[int, int, int],
    background: tuple[int, int, int] = (255, 255, 255),
    faintest: float = 0.12,
) -> np.ndarray:
    """(E, 3) uint8 colours of edges taken `counts` times, from the background towards `color`
    by faintest + (1 − faintest) · count / the largest count: the most taken in full `color`,
    a one-off (an ε exploration) barely there."""
    counts = np.asarray(counts, dtype=np.float64)
    if len(counts) == 0:
        return np.zeros((0, 3), np.uint8)
    strength = faintest + (1.0 - faintest) * counts / max(counts.max(), 1.0)
    back = np.asarray(background, np.float64)
    blend = back + strength[:, None] * (np.asarray(color, np.float64) - back)
    return np.round(blend).astype(np.uint8)
