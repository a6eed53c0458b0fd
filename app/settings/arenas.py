"""Arenas in configs: carried inline, so that a run file never makes gnp-lab read another file.

A config's `training.arena` / `implementation.arena` is always an inline `sim.ArenaSpec` once
validated: a shipped arena's name becomes its spec (this is how old run files, which stored
names, still load), and a dict is validated as a spec. A path is read only where the user gives
it (command line, a config or experiment file: `read_arena_paths`), as a regular file of at most
`MAX_ARENA_BYTES`; a path in a stored config is refused.
"""

from __future__ import annotations

import json
from functools import cache, lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import sim
from app.settings.user_files import loads_json, read_bytes
from sim.arena import ArenaSpec, arena_from_spec

MAX_ARENA_BYTES = 256 * 1024
"""Largest arena file read (the shipped ones are about 2 KiB)."""

PHASES = ("training", "implementation")


@cache
def shipped_spec(name: str) -> ArenaSpec:
    """The spec of a shipped arena (see `sim.ARENA_NAMES`)."""
    text = (resources.files("sim") / "arenas" / f"{name}.json").read_text(encoding="utf-8")
    return ArenaSpec.model_validate_json(text)


def inline_arena(value: Any) -> Any:
    """A config's arena as an inline spec: a shipped name becomes its spec, a spec or dict is
    left to validation; any other string (a path) is refused (pydantic "before" validator)."""
    if isinstance(value, str):
        if value in sim.ARENA_NAMES:
            return shipped_spec(value)
        raise ValueError(
            f"{value!r} is not a shipped arena ({', '.join(sim.ARENA_NAMES)}); an arena file is "
            "read only when given on the command line or in a config file, and runs carry "
            "their arenas inline"
        )
    return value


def read_arena_file(path: str | Path) -> dict[str, Any]:
    """An arena file given by the user, checked: a regular file of at most `MAX_ARENA_BYTES`
    holding a valid arena (its geometry too). Returns its JSON object.

    Raises:
        sim.ArenaError: naming the file and the problem.
    """
    what = "arena file"
    raw = loads_json(
        read_bytes(path, sim.ArenaError, what, MAX_ARENA_BYTES), sim.ArenaError, f"{what} {path}"
    )
    try:
        spec = ArenaSpec.model_validate(raw)
    except ValueError as error:
        problems = str(error).splitlines()
        raise sim.ArenaError(f"{path}: invalid arena: {' '.join(problems[:3])}") from None
    arena_from_spec(spec, str(path))  # the geometry: raises ArenaError
    return spec.model_dump()


def read_arena_paths(layer: dict[str, Any]) -> dict[str, Any]:
    """`layer` (user settings) with each arena given as a path replaced by the file's arena.

    Raises:
        sim.ArenaError: a named file is missing, too large, not a file or not a valid arena.
    """
    out = dict(layer)
    for phase in PHASES:
        section = out.get(phase)
        if not isinstance(section, dict):
            continue
        value = section.get("arena")
        if isinstance(value, str | Path) and str(value) not in sim.ARENA_NAMES:
            out[phase] = {**section, "arena": read_arena_file(value)}
    return out


def arena_of(spec: ArenaSpec) -> sim.Arena:
    """The world's arena of an inline spec (geometry validated; built once per spec)."""
    return _build(spec.model_dump_json())


def new_world(
    arena: sim.Arena,
    *,
    n: int,
    seed: int,
    noise_sigma: float,
    control_period: float = sim.CONTROL_PERIOD_S,
    physics: sim.Physics = sim.DEFAULT_PHYSICS,
    noise_stream: sim.NoiseStream = sim.DEFAULT_NOISE_STREAM,
) -> sim.World:
    """A world of `n` robots in `arena`: the one place the lab builds a `sim.World` (training's
    shards, the implementation phase's trials, the dashboard's live robots)."""
    return sim.World(
        arena,
        n=n,
        seed=seed,
        noise_sigma=noise_sigma,
        control_period=control_period,
        physics=physics,
        noise_stream=noise_stream,
    )


@lru_cache(maxsize=16)
def _build(spec_json: str) -> sim.Arena:
    spec = ArenaSpec.model_validate_json(spec_json)
    return arena_from_spec(spec, f"arena {spec.name!r}")


def toml_arena(spec: ArenaSpec) -> str:
    """An arena as a TOML value: a shipped arena's name, else an inline table."""
    if spec.name in sim.ARENA_NAMES and spec == shipped_spec(spec.name):
        return json.dumps(spec.name)
    return _toml(spec.model_dump())


def _toml(value: Any) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # a JSON string is a TOML basic string
    return repr(float(value)) if isinstance(value, float) else repr(value)
