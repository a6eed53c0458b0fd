"""`gnp-lab --help`, a command's `--help` and the commands that need no simulator start without
importing the heavy modules (numba, the simulator, the brains, Dask, viser, Gymnasium, the
dashboard): each command's modules are imported when it runs. `gnp-lab runs` and `train --help`
read the run configs (the packages `sim`, `gnp`, `neuro` are lazy, their light modules only) but
import no kernel. Start-up is timed in bench/cli_startup.py, never here."""

from __future__ import annotations

import argparse
import ast
import importlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from app.cli.parser import COMMANDS, build_parser

ROOT = Path(__file__).resolve().parents[3]

ENTRY = "import sys; from app.cli import main; sys.exit(main())"  # the gnp-lab script

HEAVY = ("numba", "sim", "gnp", "neuro", "dask", "viser", "gymnasium", "app.dashboard")
KERNELS = (
    *("numba", "llvmlite", "scipy", "pymunk", "cma", "neat", "dask", "viser", "gymnasium"),
    *("sim.rays", "sim.sensors", "sim.world", "gnp.engine", "gnp.kernel", "neuro.nets"),
    *("app.loop.fused", "app.loop.rollout", "app.brains.gnp_fused", "app.phases.warm"),
    "app.dashboard",
)
"""What reading run configs never needs: numba and what imports it, the optimisers' and the
physics' libraries."""
LAZY_PACKAGES = ("sim", "gnp", "neuro")


def heavy_imported(code: str, heavy: tuple[str, ...] = HEAVY) -> list[str]:
    """The `heavy` modules a fresh interpreter holds after running `code`."""
    listing = f"[m for m in {heavy!r} if m in sys.modules]"
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


def test_runs_lists_a_real_run_without_kernels(tmp_path: Path) -> None:
    """`gnp-lab runs` describes each run by its family (`CS fuzzy`) from its config alone."""
    shutil.copy(ROOT / "saved_runs" / "demo.h5", tmp_path / "demo.h5")
    code = f"from app.cli import main\nassert main(['runs', '--runs-dir', {str(tmp_path)!r}]) == 0"
    assert heavy_imported(code, KERNELS) == []
    listed = subprocess.run(
        [sys.executable, "-c", ENTRY, "runs", "--runs-dir", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert listed.returncode == 0, listed.stderr
    assert "demo" in listed.stdout and "CS fuzzy" in listed.stdout


@pytest.mark.parametrize("command", ["train", "implement", "replay"])
def test_a_compiling_commands_help_imports_no_kernel(command: str) -> None:
    code = f"from app.cli import main\nassert main([{command!r}, '--help']) == 0"
    assert heavy_imported(code, KERNELS) == []


def test_every_familys_description_needs_no_kernel() -> None:
    """What `runs` says of a run of each built-in family, from its settings only."""
    code = (
        "from app.brains.registry import BUILT_IN, family_class\n"
        "from app.settings.config import RunConfig\n"
        "for name in BUILT_IN:\n"
        "    config = RunConfig.model_validate(family_class(name).selection())\n"
        "    print(family_class(name)(config).description)"
    )
    assert heavy_imported(code, KERNELS) == []


def test_importing_the_packages_imports_none_of_their_modules() -> None:
    modules = tuple(f"{package}.{m}" for package in LAZY_PACKAGES for m in _homes(package))
    assert heavy_imported("import sim, gnp, neuro", (*KERNELS, *modules)) == []


def _homes(package: str) -> dict[str, tuple[str, ...]]:
    """What the imports under `TYPE_CHECKING` of `package`'s `__init__` name: submodule → names."""
    tree = ast.parse((ROOT / package / "__init__.py").read_text(encoding="utf-8"))
    (block,) = (
        n for n in tree.body if isinstance(n, ast.If) and ast.unparse(n.test) == "TYPE_CHECKING"
    )
    found: dict[str, tuple[str, ...]] = {}
    for node in block.body:
        assert isinstance(node, ast.ImportFrom) and node.module is not None
        found[node.module.removeprefix(f"{package}.")] = tuple(a.name for a in node.names)
    return found


@pytest.mark.parametrize("package", LAZY_PACKAGES)
def test_a_lazy_package_gives_what_its_type_checking_imports_say(package: str) -> None:
    """Each public name comes from the module the type checker is told it comes from, and is
    that module's object; `__all__` lists them all; a submodule is an attribute too."""
    module = importlib.import_module(package)
    homes = _homes(package)
    assert homes == {m: tuple(names) for m, names in module._HOMES.items()}
    assert sorted(module.__all__) == sorted(n for names in homes.values() for n in names)
    for home, names in homes.items():
        source = importlib.import_module(f"{package}.{home}")
        for name in names:
            assert getattr(module, name) is getattr(source, name), name
        assert getattr(module, home) is source
    for submodule in module._SUBMODULES:
        assert getattr(module, submodule) is importlib.import_module(f"{package}.{submodule}")
    with pytest.raises(AttributeError, match="no attribute 'nosuch'"):
        _ = module.nosuch
