"""Where each node of a GNP graph is drawn: a pure function of the node kinds and functions.

Columns left to right: the start node, one column per sensor holding the judgment nodes that
judge it (s0..s7), then one column per wheel holding the processing nodes (P0 right, P1 left).
A node's column follows the function of its first sub node (sub nodes of one node may judge
different sensors after mutation; the inspector lists them all).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gnp.config import JUDGMENT, N_SENSORS, N_WHEELS, PROCESSING, START, WHEEL_NAMES


class GraphLayoutError(ValueError):
    """The node kinds or functions given to the layout are inconsistent."""


@dataclass(frozen=True)
class GraphLayout:
    """Node positions in a `width` x `height` box (origin bottom left) and column captions.

    Attributes:
        positions: (n_nodes, 2) x, y of each node.
        column_x: (11,) x of the start, 8 sensor and 2 wheel columns.
        column_names: 11 captions, in the same order.
        column_of: (n_nodes,) index into `column_x` of each node's column.
    """

    positions: np.ndarray
    column_x: np.ndarray
    column_names: tuple[str, ...]
    column_of: np.ndarray


def graph_layout(
    kinds: np.ndarray, functions: np.ndarray, width: float = 1.0, height: float = 1.0
) -> GraphLayout:
    """Lay out a node-transition graph in columns, nodes spread evenly down each column.

    Args:
        kinds: (n_nodes,) START, JUDGMENT or PROCESSING; exactly one START.
        functions: (n_nodes,) the sensor (0..7) of a judgment node, the wheel (0 = right,
            1 = left) of a processing node; ignored for the start node.
        width: width of the box the graph fills.
        height: height of the box the graph fills.

    Raises:
        GraphLayoutError: when shapes differ, there is not exactly one start node, or a
            function is outside its range.
    """
    kinds = np.asarray(kinds, dtype=np.int64)
    functions = np.asarray(functions, dtype=np.int64)
    if kinds.ndim != 1 or kinds.shape != functions.shape:
        raise GraphLayoutError(
            f"kinds {kinds.shape} and functions {functions.shape} must be equal 1-D shapes"
        )
    if np.count_nonzero(kinds == START) != 1:
        raise GraphLayoutError("a GNP graph has exactly one start node")
    judgment, processing = kinds == JUDGMENT, kinds == PROCESSING
    if not np.all(judgment | processing | (kinds == START)):
        raise GraphLayoutError(f"unknown node kind in {sorted(set(kinds.tolist()))}")
    if np.any((functions[judgment] < 0) | (functions[judgment] >= N_SENSORS)):
        raise GraphLayoutError(f"a judgment node's sensor must be in 0..{N_SENSORS - 1}")
    if np.any((functions[processing] < 0) | (functions[processing] >= N_WHEELS)):
        raise GraphLayoutError("a processing node's wheel must be 0 (right) or 1 (left)")

    column_of = np.zeros(kinds.shape, np.int64)
    column_of[judgment] = 1 + functions[judgment]
    column_of[processing] = 1 + N_SENSORS + functions[processing]
    n_columns = 1 + N_SENSORS + N_WHEELS
    # Start alone at the left, a gap, the sensor columns, a wider gap, the wheel columns.
    slots = np.concatenate(
        [[0.0], 1.5 + np.arange(N_SENSORS), 2.5 + N_SENSORS + np.arange(N_WHEELS)]
    )
    column_x = width * slots / slots[-1]

    positions = np.zeros((kinds.size, 2))
    for column in range(n_columns):
        members = np.flatnonzero(column_of == column)
        positions[members, 0] = column_x[column]
        # Even spacing, centred; node order within a column follows node index.
        positions[members, 1] = height * (1.0 - (np.arange(members.size) + 0.5) / members.size)
    names = ("start", *(f"s{i}" for i in range(N_SENSORS)), *WHEEL_NAMES)
    return GraphLayout(positions, column_x, names, column_of)
