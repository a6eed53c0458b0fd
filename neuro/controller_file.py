"""One neural controller as the body of a controller document: its net's shape and every weight.

The body is {"net": {...ElmanConfig or RecurrentConfig, its sizes where not the robot's...},
"arrays": {name: nested lists, without the batch axis}}; the file around it (format, version,
settings) is written and read by `app.store.controller_file`. Floats are written as Python's
shortest round-trip repr, so the body gives back arrays equal bit for bit and a net that steps
identically.
"""

from __future__ import annotations

from typing import Any, cast

import numpy as np
from pydantic import TypeAdapter

from neuro.nets import NetConfig, NeuroError, check_arrays, field_dtype

# a union, which mypy (cache-dependently) refuses as a type argument; pydantic takes it
_NET: TypeAdapter[NetConfig] = TypeAdapter(cast(Any, NetConfig))


def net_body(
    cfg: NetConfig, arrays: dict[str, np.ndarray]
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The `net` and `arrays` entries of one net's document (arrays with a leading axis of 1).

    Raises:
        NeuroError: the arrays do not fit `cfg` or hold more than one net.
    """
    if check_arrays(cfg, arrays) != 1:
        raise NeuroError("a controller file holds one net")
    return cfg.model_dump(), {name: arrays[name][0].tolist() for name in cfg.shapes()}


def net_from_body(net_entry: Any, arrays: Any) -> tuple[NetConfig, dict[str, np.ndarray]]:
    """The net config and arrays (leading axis 1) of a document's `net` and `arrays`.

    Raises:
        NeuroError: the arrays do not fit the config (named).
        KeyError, TypeError, ValueError: the entries are malformed.
    """
    cfg = _NET.validate_python(net_entry)
    loaded = {name: _numbers(name, values)[None] for name, values in arrays.items()}
    check_arrays(cfg, loaded)
    return cfg, loaded


def _numbers(name: str, values: Any) -> np.ndarray:
    """An array of the document as its field's dtype: numbers only (no strings or booleans,
    which numpy would convert), in a rectangular nest of lists."""
    given = np.array(values)
    if given.dtype.kind not in "iuf":
        raise NeuroError(f"net array {name!r} must hold numbers, got {given.dtype}")
    return given.astype(field_dtype(name))
