"""Shared fixtures of the lab's tests."""

from __future__ import annotations

from pathlib import Path

import pytest
from lab_fixtures import tiny_config

from app.training import train


@pytest.fixture(scope="session")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished tiny run (do not modify: copy it first)."""
    path = tmp_path_factory.mktemp("runs") / "tiny.h5"
    train(tiny_config(), path, workers=1)
    return path
