"""One neural controller as a JSON document: its net's shape and every weight, exactly.

{"format": "gnp-lab-neural-controller", "version": 1, "net": {...ElmanConfig or
RecurrentConfig...}, "settings": {...}, "arrays": {name: nested lists, without the batch
axis}}. Floats are written as Python's shortest round-trip repr, so `load_net` gives back
arrays equal bit for bit and a net that steps identically.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import TypeAdapter, ValidationError

from neuro.nets import NetConfig, NeuroError, check_arrays, field_dtype

FORMAT = "gnp-lab-neural-controller"
VERSION = 1
_NET: TypeAdapter[NetConfig] = TypeAdapter(NetConfig)


def save_net(
    path: str | Path,
    cfg: NetConfig,
    arrays: dict[str, np.ndarray],
    settings: dict[str, Any] | None = None,
) -> Path:
    """Write one net (arrays with a leading axis of 1) as `path`; `settings` stored as given."""
    if check_arrays(cfg, arrays) != 1:
        raise NeuroError("a controller file holds one net")
    document = {
        "format": FORMAT,
        "version": VERSION,
        "net": cfg.model_dump(),
        "settings": settings or {},
        "arrays": {name: arrays[name][0].tolist() for name in cfg.shapes()},
    }
    path = Path(path)
    path.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    return path


def load_net(path: str | Path) -> tuple[NetConfig, dict[str, np.ndarray], dict[str, Any]]:
    """Read a neural controller file: (net config, arrays with a leading axis 1, settings).

    Raises:
        NeuroError: missing, not JSON, another format or version, or malformed (named).
    """
    path = Path(path)
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise NeuroError(f"controller file not found: {path}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise NeuroError(f"{path} is not a JSON controller file: {error}") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise NeuroError(f"{path} is not a gnp-lab neural controller (no format {FORMAT!r})")
    if document.get("version") != VERSION:
        raise NeuroError(
            f"{path} is neural controller version {document.get('version')!r}; "
            f"this gnp-lab reads version {VERSION}"
        )
    try:
        cfg = _NET.validate_python(document["net"])
        arrays = {
            name: np.array(values, dtype=field_dtype(name))[None]
            for name, values in document["arrays"].items()
        }
        check_arrays(cfg, arrays)
    except NeuroError as error:
        raise NeuroError(f"{path}: {error}") from None
    except (KeyError, TypeError, ValueError, ValidationError) as error:
        raise NeuroError(f"{path}: malformed controller ({type(error).__name__})") from None
    return cfg, arrays, dict(document.get("settings", {}))
