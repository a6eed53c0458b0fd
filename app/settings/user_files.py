"""Reading a file someone gave the lab, checked before it is parsed: a regular file (never a FIFO,
a device or a folder, which would hang or stream forever), at most a size limit, and JSON no
deeper than `JSON_MAX_DEPTH` (deeper nesting would exhaust the parser's recursion).

Each reader of the lab (configs, arenas, controller files, experiment specs, values tables, the
JSON attributes of run files) reads through these, naming its own error class: a problem is that
reader's one error, on one line.
"""

from __future__ import annotations

import json
import os
import re
import stat
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

JSON_MAX_DEPTH = 32
"""Deepest nesting of arrays and objects accepted in any JSON the lab parses (its own documents
nest at most 6 deep: a controller file's Q values, an arena's points)."""

MAX_TEXT_BYTES = 16 * 1024 * 1024
"""Largest text file (config, controller, experiment, values table) or JSON attribute read."""

_STRING = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"', re.DOTALL)
_OPEN = np.frombuffer(b"[{", np.uint8)
_CLOSE = np.frombuffer(b"]}", np.uint8)


def check_regular(path: str | Path, error: type[Exception], what: str) -> None:
    """Refuse `path` unless it is a regular file (symbolic links followed).

    Raises:
        error: "<what> not found: PATH", or "PATH: <what> must be a regular file".
    """
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise error(f"{what} not found: {path}") from None
    except OSError as problem:
        raise error(f"cannot read {what} {path}: {problem.strerror}") from None
    if not stat.S_ISREG(info.st_mode):
        raise error(f"{path}: {what} must be a regular file")


def read_bytes(
    path: str | Path, error: type[Exception], what: str, limit: int = MAX_TEXT_BYTES
) -> bytes:
    """The bytes of the regular file `path`, of at most `limit` bytes.

    The file is opened without waiting (a FIFO's open would block until a writer comes) and
    checked on the open descriptor, so a file swapped after a check is still refused.

    Raises:
        error: missing, unreadable, not a regular file, or larger than `limit` (on one line).
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise error(f"{what} not found: {path}") from None
    except OSError as problem:
        raise error(f"cannot read {what} {path}: {problem.strerror}") from None
    try:
        with os.fdopen(fd, "rb") as handle:
            info = os.fstat(handle.fileno())
            if not stat.S_ISREG(info.st_mode):
                raise error(f"{path}: {what} must be a regular file")
            if info.st_size > limit:
                raise error(_too_large(path, what, info.st_size, limit))
            data = handle.read(limit + 1)
    except OSError as problem:
        raise error(f"cannot read {what} {path}: {problem.strerror}") from None
    if len(data) > limit:  # it grew meanwhile
        raise error(_too_large(path, what, len(data), limit))
    return data


def read_text(
    path: str | Path, error: type[Exception], what: str, limit: int = MAX_TEXT_BYTES
) -> str:
    """`read_bytes` decoded as UTF-8.

    Raises:
        error: as `read_bytes`, or the file is not UTF-8 text.
    """
    try:
        return read_bytes(path, error, what, limit).decode("utf-8")
    except UnicodeDecodeError:
        raise error(f"{what} {path} is not UTF-8 text") from None


def _too_large(path: str | Path, what: str, size: int, limit: int) -> str:
    return f"{path}: {what} of {size} bytes, more than the {limit} bytes one may have"


def json_depth(text: str | bytes) -> int:
    """How deep arrays and objects nest in `text` (brackets inside strings not counted); for
    text that is not JSON, a bound of what a parser would meet."""
    data = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else text
    codes = np.frombuffer(_STRING.sub(b"", data), np.uint8)
    steps = np.isin(codes, _OPEN).astype(np.int64) - np.isin(codes, _CLOSE)
    return int(np.cumsum(steps).max(initial=0))


def loads_json(
    text: str | bytes, error: type[Exception], what: str, limit: int = MAX_TEXT_BYTES
) -> Any:
    """Parse JSON after checking its size and depth (`limit`, `JSON_MAX_DEPTH`), before any
    parser recurses into it.

    Raises:
        error: too large, nested deeper than `JSON_MAX_DEPTH`, or not JSON (one line).
    """
    if len(text) > limit:
        raise error(f"{what}: {len(text)} bytes of JSON, more than the {limit} bytes one may have")
    depth = json_depth(text)
    if depth > JSON_MAX_DEPTH:
        raise error(f"{what}: JSON nested {depth} deep, deeper than the {JSON_MAX_DEPTH} allowed")
    try:
        return json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as problem:
        raise error(f"{what} is not JSON: {problem}") from None


def loads_toml(text: str, error: type[Exception], what: str) -> dict[str, Any]:
    """Parse TOML (text read by `read_text`, so of bounded size); nesting too deep for the
    parser is refused as malformed.

    Raises:
        error: not TOML, or nested too deep (one line).
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as problem:
        raise error(f"{what} is not valid TOML: {problem}".replace("\n", " ")) from None
    except RecursionError:  # tomllib recurses into nested arrays and inline tables
        raise error(f"{what}: TOML nested too deep") from None
