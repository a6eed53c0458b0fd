"""Where each node of a GNP graph is drawn: a pure function of the node kinds and functions.

Columns left to right: the start node, one column per sensor holding the judgment nodes that
judge it (s0..s7), then one column per wheel holding the processing nodes (P0 right, P1 left).
A node's column follows the function of its first sub node (sub nodes of one node may judge
different sensors after mutation; the inspector lists them all). A brain on a Gymnasium task
(app.tasks) has its own inputs and outputs: the columns are then named by `inputs` and `outputs`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gnp.config import JUDGMENT, N_SENSORS, PROCESSING, START, WHEEL_NAMES


class GraphLayoutError(ValueError):
    """The node kinds or functions given to the layout are inconsistent."""


@dataclass(frozen=True)
class GraphLayout:
    """Node positions in a `width` x `height` box (origin bottom left) and column captions.

    Attributes:
        positions: (n_nodes, 2) x, y of each node.
        column_x: x of the start, input (8 sensors) and output (2 wheels) columns.
        column_names: their captions, in the same order.
        column_of: (n_nodes,) index into `column_x` of each node's column.
    """

    positions: np.ndarray
    column_x: np.ndarray
    column_names: tuple[str, ...]
    column_of: np.ndarray


def graph_layout(
    kinds: np.ndarray,
    functions: np.ndarray,
    width: float = 1.0,
    height: float = 1.0,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
) -> GraphLayout:
    """Lay out a node-transition graph in columns, nodes spread evenly down each column.

    Args:
        kinds: (n_nodes,) START, JUDGMENT or PROCESSING; exactly one START.
        functions: (n_nodes,) the sensor (0..7) of a judgment node, the wheel (0 = right,
            1 = left) of a processing node; ignored for the start node.
        width: width of the box the graph fills.
        height: height of the box the graph fills.
        inputs: captions of the judgment columns (default the robot's s0..s7).
        outputs: captions of the processing columns (default the robot's two wheels).

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
    input_names = tuple(inputs) if inputs is not None else tuple(f"s{i}" for i in range(N_SENSORS))
    output_names = tuple(outputs) if outputs is not None else WHEEL_NAMES
    n_in, n_out = len(input_names), len(output_names)
    judgment, processing = kinds == JUDGMENT, kinds == PROCESSING
    if not np.all(judgment | processing | (kinds == START)):
        raise GraphLayoutError(f"unknown node kind in {sorted(set(kinds.tolist()))}")
    if np.any((functions[judgment] < 0) | (functions[judgment] >= n_in)):
        raise GraphLayoutError(f"a judgment node's sensor must be in 0..{n_in - 1}")
    if np.any((functions[processing] < 0) | (functions[processing] >= n_out)):
        if outputs is None:
            raise GraphLayoutError("a processing node's wheel must be 0 (right) or 1 (left)")
        raise GraphLayoutError(f"a processing node's output must be in 0..{n_out - 1}")

    column_of = np.zeros(kinds.shape, np.int64)
    column_of[judgment] = 1 + functions[judgment]
    column_of[processing] = 1 + n_in + functions[processing]
    n_columns = 1 + n_in + n_out
    # Start alone at the left, a gap, the sensor columns, a wider gap, the wheel columns.
    slots = np.concatenate([[0.0], 1.5 + np.arange(n_in), 2.5 + n_in + np.arange(n_out)])
    column_x = width * slots / slots[-1]

    positions = np.zeros((kinds.size, 2))
    for column in range(n_columns):
        members = np.flatnonzero(column_of == column)
        positions[members, 0] = column_x[column]
        # Even spacing, centred; node order within a column follows node index.
        positions[members, 1] = height * (1.0 - (np.arange(members.size) + 0.5) / members.size)
    names = ("start", *input_names, *output_names)
    return GraphLayout(positions, column_x, names, column_of)
