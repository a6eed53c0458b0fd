"""One controller's genome and Q tables as the body of a controller document, and back.

The schema (version 1) is in docs/controller-format.md; the file around the body (format,
version, settings) is written and read by `app.store.controller_file`. Every gene and Q value of the
individual is written, unused parts included, so the body gives back a population that steps
bit-identically to the original.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gnp.config import (
    BRANCH_NAMES,
    JUDGMENT,
    PROCESSING,
    START,
    TASK_SETTINGS,
    GnpConfig,
    GnpError,
)
from gnp.population import Population, population_from_arrays

_TYPE_NAMES = {START: "start", JUDGMENT: "judgment", PROCESSING: "processing"}


def _sub_node(pop: Population, node: int, sub: int) -> dict[str, Any]:
    conn, q_bs, q_cs = pop.conn[0, node, sub], pop.q_bs[0, node, sub], pop.q_cs[0, node, sub]
    branches = BRANCH_NAMES[: conn.shape[0]]  # A, B (and C, … with judgment_branches > 2)
    return {
        "function": int(pop.function[0, node, sub]),
        "beta": int(pop.mu_beta[0, node, sub]),
        "alpha": int(pop.mu_alpha[0, node, sub]),
        "speed": int(pop.speed[0, node, sub]),
        "next": {b: [int(j) for j in conn[i]] for i, b in enumerate(branches)},
        "credit": int(pop.credit[0, node, sub]),
        "q_ss": float(pop.q_ss[0, node, sub]),
        "q_bs": {b: [float(q) for q in q_bs[i]] for i, b in enumerate(branches)},
        "q_cs": {"normal": float(q_cs[0]), "credit": float(q_cs[1])},
    }


def controller_body(cfg: GnpConfig, individual: Population) -> tuple[dict[str, Any], list[Any]]:
    """The `gnp` and `nodes` entries of a 1-individual population's controller document.

    Raises:
        GnpError: `individual` is not one individual.
    """
    if individual.size != 1:
        raise GnpError(f"a controller is one individual, got {individual.size}")
    nodes = [
        {
            "id": node,
            "type": _TYPE_NAMES[int(cfg.node_type[node])],
            "sub_nodes": [_sub_node(individual, node, sub) for sub in range(cfg.n_sub)],
        }
        for node in range(cfg.n_nodes)
    ]
    entry = cfg.model_dump()
    if cfg.io_defaults:  # the robot's 8 inputs and 2 outputs: documents as before the settings
        del entry["n_inputs"], entry["n_outputs"]
    for name in TASK_SETTINGS:  # a task's settings only where they are not the defaults
        if name not in cfg.task_settings():
            del entry[name]
    return entry, nodes


def _arrays(cfg: GnpConfig, nodes: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    v, m, k, u = cfg.n_nodes, cfg.n_sub, cfg.judgment_branches, cfg.n_conn_branches
    arrays = {
        "function": np.zeros((1, v, m)),
        "mu_beta": np.zeros((1, v, m)),
        "mu_alpha": np.zeros((1, v, m)),
        "speed": np.zeros((1, v, m)),
        "conn": np.zeros((1, v, m, k, u)),
        "credit": np.zeros((1, v, m)),
        "q_ss": np.zeros((1, v, m)),
        "q_bs": np.zeros((1, v, m, k, u)),
        "q_cs": np.zeros((1, v, m, 2)),
    }
    if len(nodes) != v:
        raise GnpError(f"the controller has {len(nodes)} nodes, its gnp settings say {v}")
    for i, node in enumerate(nodes):
        subs = node["sub_nodes"]
        if len(subs) != m:
            raise GnpError(f"node {i} has {len(subs)} sub nodes, the gnp settings say {m}")
        for p, sub in enumerate(subs):
            where = f"node {i} sub node {p}"
            for key, field in _GENES:
                arrays[field][0, i, p] = _number(sub[key], f"{where}: {key}", whole=True)
            arrays["q_ss"][0, i, p] = _number(sub["q_ss"], f"{where}: q_ss")
            q_cs = sub["q_cs"]
            arrays["q_cs"][0, i, p] = (
                _number(q_cs["normal"], f"{where}: q_cs.normal"),
                _number(q_cs["credit"], f"{where}: q_cs.credit"),
            )
            for b, branch in enumerate(BRANCH_NAMES[:k]):
                arrays["conn"][0, i, p, b] = _numbers(sub["next"][branch], f"{where}: next", True)
                arrays["q_bs"][0, i, p, b] = _numbers(sub["q_bs"][branch], f"{where}: q_bs")
    return arrays


_GENES = (
    ("function", "function"),
    ("beta", "mu_beta"),
    ("alpha", "mu_alpha"),
    ("speed", "speed"),
    ("credit", "credit"),
)
"""A sub node's integer genes: (key in the document, population field)."""


def _number(value: Any, where: str, whole: bool = False) -> float:
    """A number of the document (never a string or a boolean, which numpy would convert).

    Raises:
        GnpError: naming where it is and what it is.
    """
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if number and abs(value) <= _LARGEST and (not whole or float(value).is_integer()):
        return float(value)
    shown = repr(value) if len(repr(value)) < 40 else type(value).__name__
    raise GnpError(f"{where} must be {'an integer' if whole else 'a number'}, got {shown}")


_LARGEST = 1e300
"""Largest magnitude read (a larger integer does not fit a float; genes are checked later)."""


def _numbers(values: Any, where: str, whole: bool = False) -> list[float]:
    """A list of numbers of the document (see `_number`)."""
    if not isinstance(values, list):
        raise GnpError(f"{where} must be a list of numbers, got {values!r}")
    return [_number(v, where, whole) for v in values]


def controller_from_body(gnp_entry: Any, nodes: Any) -> tuple[GnpConfig, Population]:
    """The gnp config and validated 1-individual population of a document's `gnp` and `nodes`.

    Raises:
        GnpError: the nodes do not fit the config, or the genome is invalid (named).
        KeyError, TypeError, ValueError: the entries are malformed.
    """
    cfg = GnpConfig.model_validate(gnp_entry)
    return cfg, population_from_arrays(cfg, _arrays(cfg, nodes))
