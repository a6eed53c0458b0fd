"""What the graph panel draws of a neural controller: layers, weighted edges, live activations.

Pure functions of a net's config and weights (no viser here). Three columns, left to right: the
8 IR inputs with, below them, the context — the units' values of the previous step that feed
the next (an Elman net's hidden layer; a NEAT net's units with a recurrent connection) —, then
the hidden units, then the 2 wheels. Every edge is a weight that is read by a unit, so edges all
run left to right: a net's recurrence is drawn as its context units, not as loops.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import neuro
import sim

INPUT, CONTEXT, HIDDEN, OUTPUT = 0, 1, 2, 3
KIND_NAMES = ("IR in", "context t−1", "hidden", "wheels")
TASK_KIND_NAMES = ("in", "context t−1", "hidden", "out")
"""The kinds' words for a net sized to a task (its features in, its commands out)."""
WHEELS = ("left", "right")
POSITIVE = (215, 80, 20)  # orange-red: a positive weight or activation
NEGATIVE = (30, 100, 215)  # blue: a negative one
NEUTRAL = (236, 236, 240)  # an activation of 0 (a weight of 0 is not drawn)
BACKGROUND = (255, 255, 255)


@dataclass(frozen=True)
class NetworkLayout:
    """The drawn network of one controller, in a `width` x `height` box (origin bottom left).

    Attributes:
        kinds: (V,) INPUT, CONTEXT, HIDDEN or OUTPUT of each drawn node.
        index: (V,) its sensor (inputs), unit of the net's state (context, hidden; NEAT's
            outputs are units 0 and 1 too), or wheel (outputs: 0 left, 1 right).
        positions: (V, 2) x, y of each node.
        edges: (E, 2) (source, target) drawn nodes of each nonzero weight, weakest first.
        weights: (E,) those weights.
        names: (V,) short name of each node: `s3`, `h2`, `h2(t−1)`, `left`.
        column_x: (3,) x of the input/context, hidden and wheel columns.
        robot: the net is sized to the robot (its sensors in, its wheels out), not to a task.
    """

    net: str
    kinds: np.ndarray
    index: np.ndarray
    positions: np.ndarray
    edges: np.ndarray
    weights: np.ndarray
    names: tuple[str, ...]
    column_x: np.ndarray
    robot: bool

    def count(self, kind: int) -> int:
        """Drawn nodes of `kind`."""
        return int(np.count_nonzero(self.kinds == kind))


def _robots(cfg: neuro.NetConfig) -> bool:
    """Whether the net is sized to the robot (its sensors in, its wheels out)."""
    return (cfg.n_inputs, cfg.n_outputs) == (neuro.N_INPUTS, len(WHEELS))


def _output_names(cfg: neuro.NetConfig) -> tuple[str, ...]:
    """The robot's wheels, or y0, y1, … for a net of other sizes (a task's)."""
    return WHEELS if _robots(cfg) else tuple(f"y{o}" for o in range(cfg.n_outputs))


def io_captions(cfg: neuro.NetConfig) -> tuple[str, str]:
    """Captions of the input and output columns: the robot's (`IR in s0–s7`, `wheels (left,
    right)`), or a task's (`inputs s0–s3`, `outputs y0`)."""
    last = f"s{cfg.n_inputs - 1}"
    if _robots(cfg):
        return f"IR in s0–{last}", f"wheels ({', '.join(WHEELS)})"
    inputs = "input s0" if cfg.n_inputs == 1 else f"inputs s0–{last}"
    return inputs, "outputs " + ", ".join(_output_names(cfg))


def _unit_name(cfg: neuro.NetConfig, unit: int) -> str:
    if isinstance(cfg, neuro.RecurrentConfig) and unit < cfg.n_outputs:
        return _output_names(cfg)[unit]
    return f"h{unit if isinstance(cfg, neuro.ElmanConfig) else unit - cfg.n_outputs}"


def _wiring(
    cfg: neuro.NetConfig, arrays: dict[str, np.ndarray]
) -> tuple[list[int], list[int], list[tuple[int, int, int, float]]]:
    """Context units, hidden units, and weights as (source kind, source index, target node
    key, weight); a target key is a hidden unit, or −1 − wheel for a wheel."""
    neuro.check_arrays(cfg, arrays)
    n_in, n_out = cfg.n_inputs, cfg.n_outputs
    links: list[tuple[int, int, int, float]] = []
    if isinstance(cfg, neuro.ElmanConfig):
        w_in, w_rec, w_out = arrays["w_in"][0], arrays["w_rec"][0], arrays["w_out"][0]
        units = list(range(cfg.hidden))
        for j in units:
            links += [(INPUT, i, j, float(w_in[j, i])) for i in range(n_in)]
            links += [(CONTEXT, k, j, float(w_rec[j, k])) for k in units]
        for o in range(n_out):
            links += [(HIDDEN, j, -1 - o, float(w_out[o, j])) for j in units]
        return units, units, links
    weights, active = arrays["weights"][0], arrays["active"][0].astype(bool)
    # A padded slot has no weight in or out; a hidden node without inputs is kept (it is 0).
    used = active | np.any(weights[:, n_in:] != 0.0, axis=0)
    hidden = [j for j in range(n_out, cfg.n_units) if used[j]]
    context = [k for k in range(cfg.n_units) if np.any(weights[active, n_in + k] != 0.0)]
    for j in map(int, np.flatnonzero(active)):
        key = j if j >= n_out else -1 - j
        links += [(INPUT, i, key, float(weights[j, i])) for i in range(n_in) if weights[j, i]]
        links += [
            (CONTEXT, k, key, float(weights[j, n_in + k])) for k in context if weights[j, n_in + k]
        ]
    return context, hidden, links


def network_layout(
    cfg: neuro.NetConfig, arrays: dict[str, np.ndarray], width: float = 1.0, height: float = 1.0
) -> NetworkLayout:
    """Lay out the net of individual 0 of `arrays` (a leading axis of 1) in three columns.

    Raises:
        neuro.NeuroError: `arrays` are not nets of `cfg`.
    """
    context, hidden, links = _wiring(cfg, arrays)
    n_in, n_out = cfg.n_inputs, cfg.n_outputs
    kinds = np.array(
        [INPUT] * n_in + [CONTEXT] * len(context) + [HIDDEN] * len(hidden) + [OUTPUT] * n_out,
        np.int64,
    )
    index = np.array([*range(n_in), *context, *hidden, *range(n_out)], np.int64)
    names = (
        *(f"s{i}" for i in range(n_in)),
        *(_unit_name(cfg, k) + "(t−1)" for k in context),
        *(_unit_name(cfg, j) for j in hidden),
        *_output_names(cfg),
    )
    column_x = width * np.array([0.0, 0.55, 1.0])
    positions = np.zeros((len(kinds), 2))
    # Left column: the inputs on top, a one-slot gap, the context below.
    left = n_in + (1 + len(context) if context else 0)
    slots = np.concatenate([np.arange(n_in), n_in + 1 + np.arange(len(context))])
    positions[: len(slots), 1] = height * (1.0 - (slots + 0.5) / left)
    for kind, column in ((HIDDEN, 1), (OUTPUT, 2)):
        members = np.flatnonzero(kinds == kind)
        positions[members, 0] = column_x[column]
        positions[members, 1] = height * (1.0 - (np.arange(len(members)) + 0.5) / len(members))
    # Node of each (kind, index); a target key is a hidden unit or −1 − wheel.
    node_of = {(int(k), int(i)): v for v, (k, i) in enumerate(zip(kinds, index, strict=True))}
    pairs = [
        (node_of[(kind, source)], node_of[(OUTPUT, -1 - key) if key < 0 else (HIDDEN, key)])
        for kind, source, key, _ in links
    ]
    weights = np.array([w for *_, w in links], np.float64)
    edges = np.array(pairs, np.int64).reshape(-1, 2)
    keep = weights != 0.0
    order = np.argsort(np.abs(weights[keep]), kind="stable")  # the strongest drawn on top
    return NetworkLayout(
        "Elman" if isinstance(cfg, neuro.ElmanConfig) else "NEAT",
        kinds,
        index,
        positions,
        edges[keep][order],
        weights[keep][order],
        names,
        column_x,
        _robots(cfg),
    )


def node_values(
    layout: NetworkLayout,
    activation: np.ndarray,
    context: np.ndarray,
    readings: np.ndarray,
    commands: np.ndarray,
) -> np.ndarray:
    """(V,) what each drawn node holds after a step: an input its reading ÷ IR_MAX in [0, 1],
    a context node its unit's value of the step before, a hidden node its unit's value, a wheel
    its command ÷ MAX_COMMAND (all in [−1, 1]).

    Args:
        activation: (units,) the net's state after the step.
        context: (units,) its state before the step (zeros at a life's start).
        readings: (8,) the readings the net was given (noise and faults included).
        commands: (2,) the wheel commands it gave (left, right).
    """
    values = np.zeros(len(layout.kinds))
    for kind, source in (
        (INPUT, np.clip(np.asarray(readings, np.float64) / sim.IR_MAX, 0.0, 1.0)),
        (CONTEXT, context),
        (HIDDEN, activation),
        (OUTPUT, np.asarray(commands, np.float64) / sim.MAX_COMMAND),
    ):
        members = layout.kinds == kind
        values[members] = np.asarray(source)[layout.index[members]]
    return values


def activation_colors(values: np.ndarray) -> np.ndarray:
    """(V, 3) uint8: an activation's colour, NEUTRAL at 0, towards POSITIVE at +1 and NEGATIVE at
    −1 (clipped)."""
    v = np.clip(np.asarray(values, np.float64), -1.0, 1.0)[:, None]
    end = np.where(v >= 0.0, np.array(POSITIVE, np.float64), np.array(NEGATIVE, np.float64))
    neutral = np.array(NEUTRAL, np.float64)
    return np.round(neutral + np.abs(v) * (end - neutral)).astype(np.uint8)


def weight_colors(weights: np.ndarray, faintest: float = 0.1) -> np.ndarray:
    """(E, 3) uint8: a weight's colour by its sign (POSITIVE, NEGATIVE), from the background
    towards it by faintest + (1 − faintest) · |w| / the largest |w| of the net."""
    w = np.asarray(weights, np.float64)
    if len(w) == 0:
        return np.zeros((0, 3), np.uint8)
    strength = faintest + (1.0 - faintest) * np.abs(w) / max(float(np.abs(w).max()), 1e-12)
    end = np.where(
        w[:, None] >= 0.0, np.array(POSITIVE, np.float64), np.array(NEGATIVE, np.float64)
    )
    back = np.array(BACKGROUND, np.float64)
    return np.round(back + strength[:, None] * (end - back)).astype(np.uint8)


def describe_layers(layout: NetworkLayout) -> str:
    """`Elman · 8 IR in · 8 context t−1 · 8 hidden · 2 wheels · 144 weights` (a task's net:
    `Elman · 4 in · 3 context t−1 · 3 hidden · 1 out · 24 weights`)."""
    words = KIND_NAMES if layout.robot else TASK_KIND_NAMES
    counts = " · ".join(f"{layout.count(kind)} {name}" for kind, name in enumerate(words))
    return f"{layout.net} · {counts} · {len(layout.weights)} weights"


def net_markdown(layout: NetworkLayout) -> str:
    """The inspector's words on a net: its layers, what the colours mean, what does not apply."""
    hidden = layout.count(HIDDEN)
    if layout.net == "Elman":
        wiring = (
            f"8 IR readings ÷ {sim.IR_MAX:g} → {hidden} hidden tanh units, each also reading "
            "every hidden unit's value of the step before (the context) → 2 wheels, tanh × "
            f"{sim.MAX_COMMAND:g}"
        )
    else:
        wiring = (
            f"neat-python's recurrent net: {hidden} hidden nodes and the 2 wheels each read the "
            "IR readings and the values of the units they connect from at the step before (the "
            f"context); tanh(2.5 z), wheels × {sim.MAX_COMMAND:g}"
        )
    largest = float(np.abs(layout.weights).max()) if len(layout.weights) else 0.0
    return (
        f"**{layout.net} net**: {wiring}. {len(layout.weights)} nonzero weights, largest |w| "
        f"{largest:.3g}; biases are not drawn.  \n"
        "Edges: <span style='color:#d75014'>orange</span> positive, "
        "<span style='color:#1e64d7'>blue</span> negative, darker the larger |w|. Nodes: their "
        "live value (blue −1, grey 0, orange +1; inputs 0..1).  \n"
        "<small>A net does not learn online and has no GNP nodes: the node inspector, the "
        "simplified graph, ε/α and the second stage do not apply to it.</small>"
    )
