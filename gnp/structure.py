"""Add/delete-node mutation: the active graph grows and shrinks inside the fixed node budget.

fracnetics (`callAddDelNodes`) grows and shrinks its networks: each generation a network adds
a node or deletes an unused one, with probability ½ each. A population here has a fixed number
of nodes, so the faithful reading acts on the part of the graph a walk can reach from the start
node (`reachable`): deleting a reachable node redirects every connection into it to another
node (it becomes unreachable, its genes kept as junk), adding one connects an unreachable node
(one usable branch of a reachable node redirected to it) with its genes drawn afresh as
generation 0 draws them. docs/decisions.md, "Add/delete-node mutation".
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from gnp.config import JUDGMENT, PROCESSING, START, GnpConfig, GnpError
from gnp.population import FIELDS, Population, init_population, population_to_arrays


class Edited(NamedTuple):
    """`add_delete_nodes`' result: the population and, per individual, the node added and the
    node deleted (−1: none)."""

    population: Population
    added: np.ndarray
    deleted: np.ndarray


def usable_slots(cfg: GnpConfig) -> np.ndarray:
    """(V, K) bool: the connection slots a walk can follow, K = m·k·U conn slots (flattened in
    `conn`'s order) then m credit slots. The start node follows conn[0, 0, 0, 0] only; a
    judgment node every branch; a processing node branch A; credit branches under CS only."""
    m, u = cfg.n_sub, cfg.n_conn_branches
    conn = np.zeros((cfg.n_nodes, m, cfg.judgment_branches, u), dtype=bool)
    types = cfg.node_type
    conn[types == JUDGMENT] = True
    conn[types == PROCESSING, :, 0, :] = True
    conn[types == START, 0, 0, 0] = True
    credit = np.zeros((cfg.n_nodes, m), dtype=bool)
    if cfg.traits.credit:
        credit[types != START] = True
    return np.concatenate((conn.reshape(cfg.n_nodes, -1), credit), axis=1)


def _targets(pop: Population) -> np.ndarray:
    """(N, V, K) the node each slot of `usable_slots`' order names."""
    n, v = pop.function.shape[:2]
    return np.concatenate((pop.conn.reshape(n, v, -1), pop.credit), axis=2)


def reachable(cfg: GnpConfig, pop: Population) -> np.ndarray:
    """(N, V) bool: the nodes a walk of each individual can reach from the start node (the start
    node included), following the slots of `usable_slots`."""
    usable = usable_slots(cfg)
    targets = _targets(pop)
    reach = np.zeros(targets.shape[:2], dtype=bool)
    reach[:, 0] = True
    while True:
        ind, node, slot = np.nonzero(reach[:, :, None] & usable[None])
        grown = reach.copy()
        grown[ind, targets[ind, node, slot]] = True
        if np.array_equal(grown, reach):
            return reach
        reach = grown


def add_delete_nodes(
    cfg: GnpConfig, pop: Population, p_add_delete: float, rng: np.random.Generator
) -> Edited:
    """Each individual, with probability `p_add_delete`, adds or deletes a node (½ each).

    - delete: a reachable node d ≠ 0 drawn uniformly; every connection and credit branch of the
      individual that names d (unused slots too) is redirected uniformly among the nodes
      1..V−1 other than d, so no connection names d. Nothing else changes.
    - add: an unreachable node a drawn uniformly (none: nothing happens); one usable slot of a
      reachable node (`usable_slots`) drawn uniformly is redirected to a, and a's genes and Q
      values are replaced by node a of `init_population(cfg, 1, rng)`: generation 0's draw.

    Q values of redirected slots are kept, as `mutate` keeps them. `pop` is not modified; with
    `p_add_delete` 0 nothing is drawn.
    """
    if not 0.0 <= p_add_delete <= 1.0:
        raise GnpError(f"p_add_delete must be in 0..1, got {p_add_delete}")
    n, v = pop.size, cfg.n_nodes
    added = np.full(n, -1, dtype=np.intp)
    deleted = np.full(n, -1, dtype=np.intp)
    out = {f: a.copy() for f, a in population_to_arrays(pop).items()}
    if p_add_delete == 0.0 or n == 0:
        return Edited(Population(**out), added, deleted)
    hit = rng.random(n) < p_add_delete
    adds = rng.random(n) < 0.5
    usable = usable_slots(cfg)
    reach = reachable(cfg, pop)
    conn_slots = int(np.prod(out["conn"].shape[2:]))
    for i in np.flatnonzero(hit):
        if adds[i]:
            free = np.flatnonzero(~reach[i, 1:]) + 1
            if free.size == 0:
                continue
            a = int(free[rng.integers(free.size)])
            nodes, slots = np.nonzero(reach[i, :, None] & usable)
            j = rng.integers(nodes.size)
            node, slot = int(nodes[j]), int(slots[j])
            if slot < conn_slots:
                p, b, u = np.unravel_index(slot, out["conn"].shape[2:])
                out["conn"][i, node, p, b, u] = a
            else:
                out["credit"][i, node, slot - conn_slots] = a
            fresh = init_population(cfg, 1, rng)
            for f in FIELDS:
                out[f][i, a] = getattr(fresh, f)[0, a]
            added[i] = a
        else:
            alive = np.flatnonzero(reach[i, 1:]) + 1
            d = int(alive[rng.integers(alive.size)])
            for f in ("conn", "credit"):
                row = out[f][i]
                into = row == d
                r = rng.integers(1, v - 1, size=int(into.sum()))
                row[into] = np.where(r >= d, r + 1, r)
            deleted[i] = d
    return Edited(Population(**out), added, deleted)
