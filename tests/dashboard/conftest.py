"""Fixtures of the dashboard tests: two tiny trained runs, a served dashboard, headless Chromium."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from app.dashboard.headless import (
    CHROMIUM_ARGS,
    chromium_executable,
    start_dashboard,
    stop_dashboard,
)
from app.phases.training import train
from app.settings.config import RunConfig
from app.settings.loading import build_config

REPO = Path(__file__).resolve().parents[2]
SCREENSHOTS = REPO / "test-output" / "dashboard"


def tiny_run_config(method: str, seed: int = 3) -> RunConfig:
    """A run that trains in a few seconds: 8 individuals, 600 steps, 2 generations."""
    return build_config(
        {
            "seed": seed,
            "controller": {"method": method},
            "training": {"population": 8, "steps": 600, "generations": 2},
            "implementation": {"steps": 200, "repeats": 1, "fault_step": 100},
        }
    )


@pytest.fixture(scope="session")
def runs_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A runs directory holding two finished tiny runs, `bs` and `cs`."""
    directory = tmp_path_factory.mktemp("runs")
    train(tiny_run_config("BS"), directory / "bs.h5")
    train(tiny_run_config("CS"), directory / "cs.h5")
    return directory


def tiny_net_config(seed: int = 3) -> RunConfig:
    """A CMA-ES Elman run that trains in seconds: 6 nets, 150 steps, 2 generations."""
    return build_config(
        {
            "seed": seed,
            "training": {"population": 6, "steps": 150, "generations": 2},
            "implementation": {"steps": 120, "repeats": 1, "fault_step": 60},
            "neuro": {"optimiser": "cmaes", "hidden": 6},
        }
    )


@pytest.fixture(scope="session")
def net_runs_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A runs directory holding one finished tiny neural run, `elman` (CMA-ES)."""
    directory = tmp_path_factory.mktemp("net-runs")
    train(tiny_net_config(), directory / "elman.h5")
    return directory


@pytest.fixture(scope="session")
def dashboard_url(runs_dir: Path) -> Iterator[str]:
    """`gnp-lab serve` on a free local port, in its own process, showing `cs` first."""
    process, url = start_dashboard(runs_dir, runs_dir.parent / "server.log", ("--run", "cs"))
    yield url
    stop_dashboard(process)


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    """Debian's headless Chromium driven by Playwright (never `playwright install`)."""
    from playwright.sync_api import sync_playwright

    executable = chromium_executable()
    with sync_playwright() as playwright:
        instance = playwright.chromium.launch(executable_path=executable, args=CHROMIUM_ARGS)
        yield instance
        instance.close()


@pytest.fixture(scope="session")
def screenshots() -> Path:
    """Where the browser tests save a PNG of each state (GNP_LAB_SCREENSHOTS overrides)."""
    directory = Path(os.environ.get("GNP_LAB_SCREENSHOTS", SCREENSHOTS))
    directory.mkdir(parents=True, exist_ok=True)
    return directory
