"""bench/versus.py still drives the lab's entry points (it compares trees side by side, so an
API change breaks it only when someone runs it). Timing is the bench's job, not this test's."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_versus_runs_a_tree_against_itself() -> None:
    tiny = "--population 4 --steps 10 --trials 10 --impl-steps 20 --rounds 1 --workers 1"
    done = subprocess.run(
        [sys.executable, str(ROOT / "bench" / "versus.py"), "--baseline", str(ROOT), *tiny.split()],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    number = r"\s+[\d.]+ /\s+[\d.]+"
    for case in ("training generation, 1 worker", "implementation block, 1 worker"):
        row = rf"{case}\s+this tree{number}\s+baseline{number}\s+baseline / this tree\s+[\d.]+×"
        assert re.search(row, done.stdout), done.stdout
    assert "implementation 10 trials × 20 steps" in done.stdout
