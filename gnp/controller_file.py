"""One controller as a JSON document: an individual with its Q tables, usable without a run file.

The schema (version 1) is in docs/controller-format.md. Every gene and Q value of the individual
is written, unused parts included, so `load_controller` gives back a population that steps
bit-identically to the original.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from gnp.config import JUDGMENT, PROCESSING, START, GnpConfig, GnpError
from gnp.population import Population, population_from_arrays

FORMAT = "gnp-lab-controller"
VERSION = 1
_TYPE_NAMES = {START: "start", JUDGMENT: "judgment", PROCESSING: "processing"}
_BRANCHES = ("A", "B")


def _sub_node(pop: Population, node: int, sub: int) -> dict[str, Any]:
    conn, q_bs, q_cs = pop.conn[0, node, sub], pop.q_bs[0, node, sub], pop.q_cs[0, node, sub]
    return {
        "function": int(pop.function[0, node, sub]),
        "beta": int(pop.mu_beta[0, node, sub]),
        "alpha": int(pop.mu_alpha[0, node, sub]),
        "speed": int(pop.speed[0, node, sub]),
        "next": {b: [int(j) for j in conn[i]] for i, b in enumerate(_BRANCHES)},
        "credit": int(pop.credit[0, node, sub]),
        "q_ss": float(pop.q_ss[0, node, sub]),
        "q_bs": {b: [float(q) for q in q_bs[i]] for i, b in enumerate(_BRANCHES)},
        "q_cs": {"normal": float(q_cs[0]), "credit": float(q_cs[1])},
    }


def controller_document(
    cfg: GnpConfig, individual: Population, settings: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The JSON-ready document of a 1-individual population (see docs/controller-format.md)."""
    if individual.size != 1:
        raise GnpError(f"a controller is one individual, got {individual.size}")
    return {
        "format": FORMAT,
        "version": VERSION,
        "gnp": cfg.model_dump(),
        "settings": settings or {},
        "nodes": [
            {
                "id": node,
                "type": _TYPE_NAMES[int(cfg.node_type[node])],
                "sub_nodes": [_sub_node(individual, node, sub) for sub in range(cfg.n_sub)],
            }
            for node in range(cfg.n_nodes)
        ],
    }


def save_controller(
    path: str | Path,
    cfg: GnpConfig,
    individual: Population,
    settings: dict[str, Any] | None = None,
) -> Path:
    """Write a 1-individual population as `path` (JSON); `settings` is stored as given."""
    path = Path(path)
    document = controller_document(cfg, individual, settings)
    path.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    return path


def _arrays(cfg: GnpConfig, nodes: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    v, m, u = cfg.n_nodes, cfg.n_sub, cfg.n_conn_branches
    arrays = {
        "function": np.zeros((1, v, m)),
        "mu_beta": np.zeros((1, v, m)),
        "mu_alpha": np.zeros((1, v, m)),
        "speed": np.zeros((1, v, m)),
        "conn": np.zeros((1, v, m, 2, u)),
        "credit": np.zeros((1, v, m)),
        "q_ss": np.zeros((1, v, m)),
        "q_bs": np.zeros((1, v, m, 2, u)),
        "q_cs": np.zeros((1, v, m, 2)),
    }
    if len(nodes) != v:
        raise GnpError(f"the controller has {len(nodes)} nodes, its gnp settings say {v}")
    for i, node in enumerate(nodes):
        subs = node["sub_nodes"]
        if len(subs) != m:
            raise GnpError(f"node {i} has {len(subs)} sub nodes, the gnp settings say {m}")
        for p, sub in enumerate(subs):
            arrays["function"][0, i, p] = sub["function"]
            arrays["mu_beta"][0, i, p] = sub["beta"]
            arrays["mu_alpha"][0, i, p] = sub["alpha"]
            arrays["speed"][0, i, p] = sub["speed"]
            arrays["credit"][0, i, p] = sub["credit"]
            arrays["q_ss"][0, i, p] = sub["q_ss"]
            arrays["q_cs"][0, i, p] = (sub["q_cs"]["normal"], sub["q_cs"]["credit"])
            for b, branch in enumerate(_BRANCHES):
                arrays["conn"][0, i, p, b] = sub["next"][branch]
                arrays["q_bs"][0, i, p, b] = sub["q_bs"][branch]
    return arrays


def load_controller(path: str | Path) -> tuple[GnpConfig, Population, dict[str, Any]]:
    """Read a controller file: its gnp config, a validated 1-individual population, settings.

    Raises:
        GnpError: the file is missing, not JSON, not a controller of a known version, or holds
            an invalid genome (the message names the problem).
    """
    path = Path(path)
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise GnpError(f"controller file not found: {path}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise GnpError(f"{path} is not a JSON controller file: {error}") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise GnpError(f"{path} is not a gnp-lab controller (no format {FORMAT!r})")
    if document.get("version") != VERSION:
        raise GnpError(
            f"{path} is controller format version {document.get('version')!r}; "
            f"this gnp reads version {VERSION}"
        )
    try:
        cfg = GnpConfig.model_validate(document["gnp"])
        arrays = _arrays(cfg, document["nodes"])
    except GnpError:
        raise
    except (KeyError, TypeError, ValueError) as error:
        raise GnpError(f"{path}: malformed controller ({type(error).__name__}: {error})") from None
    return cfg, population_from_arrays(cfg, arrays), dict(document.get("settings", {}))
