"""`gnp-lab --help`, a command's `--help` and the commands that need no simulator start without
importing the heavy modules (numba, the simulator, the brains, Dask, viser, Gymnasium, the
dashboard): each command's modules are imported when it runs. Start-up is timed in
bench/cli_startup.py, never here."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

from app.cli.parser import COMMANDS, build_parser

ROOT = Path(__file__).resolve().parents[2]

ENTRY = "import sys; from app.cli import main; sys.exit(main())"  # the gnp-lab script

HEAVY = ("numba", "sim", "gnp", "neuro", "dask", "viser", "gymnasium", "app.dashboard")


def heavy_imported(code: str) -> list[str]:
    """The `HEAVY` modules a fresh interpreter holds after running `code`."""
    listing = f"[m for m in {HEAVY!r} if m in sys.modules]"
    probe = f"{code}\nimport json, sys\nprint(json.dumps({listing}))"
    done = subprocess.run(
        [sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    return list(json.loads(done.stdout.strip().splitlines()[-1]))


def test_importing_the_entry_point_imports_nothing_heavy() -> None:
    assert heavy_imported("import app.cli.main") == []


@pytest.mark.parametrize("argv", [["--help"], ["runs", "--help"], ["serve", "--help"], []])
def test_help_imports_nothing_heavy(argv: list[str]) -> None:
    code = f"from app.cli import main\nassert main({argv!r}) in (0, 2)"
    assert heavy_imported(code) == []


def test_every_command_is_listed_with_the_help_its_parser_gives() -> None:
    """`gnp-lab --help` lists each command from `COMMANDS` without building its parser; the
    commands whose parsers live in their packages say the same there."""
    full = build_parser()
    listing = build_parser(())
    for parser in (full, listing):
        (commands,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        helps = {action.dest: action.help for action in commands._get_subactions()}
        assert helps == COMMANDS


def test_a_user_mistake_in_a_lazy_command_is_one_line(tmp_path: Path) -> None:
    """The errors caught as a user's mistake are those of the modules the command loaded."""
    done = subprocess.run(
        [sys.executable, "-c", ENTRY, "runs", "nosuch", "--runs-dir", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1
    assert done.stderr == f"gnp-lab: error: no run named 'nosuch' in {tmp_path}\n"
