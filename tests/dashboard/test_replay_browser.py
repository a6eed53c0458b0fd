"""The exported replay folder plays in headless Chromium from `python -m http.server`."""

from __future__ import annotations

import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from app.dashboard.headless import free_port
from app.export import export_replay
from app.phases.implementation import implement
from app.phases.training import train
from app.settings.loading import build_config
from app.store import RunReader

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("replay-browser")]
TIMEOUT_MS = 60_000
FAULT_SECONDS = (300 + 150) * 0.064  # elite life, then the trial's steps until the fault, + 50


@pytest.fixture(scope="module")
def replay_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The replay folder of a tiny CS run with a stored implementation (sensors 2,3 die)."""
    directory = tmp_path_factory.mktemp("replay")
    config = build_config(
        {
            "seed": 5,
            "controller": {"method": "CS"},
            "training": {"population": 8, "steps": 300, "generations": 2},
            "implementation": {
                "steps": 200,
                "repeats": 1,
                "fault_step": 100,
                "broken_sensors": [2, 3],
                "recorded_trials": 1,
            },
        }
    )
    run = directory / "tiny.h5"
    train(config, run)
    with RunReader(run) as reader:
        settings = reader.config.implementation
    implement(run, settings, name="fault")
    return export_replay(run, directory / "replay")


@pytest.fixture(scope="module")
def replay_url(replay_dir: Path) -> Iterator[str]:
    """`python -m http.server` serving the folder on 127.0.0.1."""
    port = free_port()
    server = subprocess.Popen(
        [sys.executable, "-m", "http.server", "--bind", "127.0.0.1", str(port)],
        cwd=replay_dir,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    url = f"http://127.0.0.1:{port}/"
    deadline = time.monotonic() + 30
    while True:
        try:
            urllib.request.urlopen(url, timeout=2).close()
            break
        except OSError:
            if time.monotonic() > deadline or server.poll() is not None:
                server.kill()
                raise
            time.sleep(0.2)
    yield url
    server.terminate()
    server.wait(timeout=10)


PLAYBACK_TIME = "document.querySelector('input.mantine-NumberInput-input').value"
"""The playback bar's time field (seconds into the recording)."""


def _playback_time(page: Any) -> float:
    return float(page.locator("input.mantine-NumberInput-input").first.input_value())


def test_the_replay_plays_from_a_static_server(
    browser: Any, replay_url: str, screenshots: Path
) -> None:
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    errors: list[str] = []
    failed: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.on("response", lambda r: failed.append(r.url) if r.status >= 400 else None)
    try:
        page.goto(replay_url)
        assert "playbackPath=replay.viser" in page.url  # index.html asked for the recording
        page.wait_for_selector("canvas", timeout=TIMEOUT_MS)
        page.wait_for_selector("input.mantine-NumberInput-input", timeout=TIMEOUT_MS)
        page.wait_for_function(f"() => parseFloat({PLAYBACK_TIME}) > 0.5", timeout=TIMEOUT_MS)
        first, shot = _playback_time(page), page.locator("canvas").first.screenshot()
        page.wait_for_function(
            f"t => parseFloat({PLAYBACK_TIME}) > t + 1.0", arg=first, timeout=TIMEOUT_MS
        )
        assert page.locator("canvas").first.screenshot() != shot  # the robot moved on
        # Jump into the implementation trial after the fault (this pauses the playback).
        time_input = page.locator("input.mantine-NumberInput-input").first
        time_input.fill(f"{FAULT_SECONDS:.1f}")
        time_input.press("Enter")
        page.wait_for_timeout(1500)
        for close in page.locator("button.mantine-Notification-closeButton").all():
            close.click()  # Chromium's "software WebGL" notice
        page.wait_for_timeout(500)
        page.screenshot(path=str(screenshots / "replay.png"))
        assert errors == [] and failed == []
    finally:
        page.close()
