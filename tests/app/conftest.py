"""Shared fixtures of the lab's tests."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import settings
from lab_fixtures import tiny_config

from app.phases.training import train

# Properties are checked by what they assert, never by how long an example takes: a loaded
# 2-core CI machine must not turn a slow example into a failure.
settings.register_profile("lab", deadline=None)
settings.load_profile("lab")


@pytest.fixture(scope="session")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished tiny run (do not modify: copy it first)."""
    path = tmp_path_factory.mktemp("runs") / "tiny.h5"
    train(tiny_config(), path, workers=1)
    return path
