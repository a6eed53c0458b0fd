"""The lab's tests mirror its packages (issue #46): `tests/app/<package>/` holds the tests of
`app/<package>/`, `tests/app/design/` the lints over the whole source; fixtures stay at the top."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
TESTS = ROOT / "tests" / "app"
WHOLE_SOURCE = "design"  # lints over every package: layers, facts once, sim/gnp boundary


def app_packages() -> set[str]:
    return {p.parent.name for p in (ROOT / "app").glob("*/__init__.py")}


def test_each_test_folder_is_an_app_package() -> None:
    folders = {p.name for p in TESTS.iterdir() if p.is_dir() and not p.name.startswith(("_", "."))}
    assert folders, "tests/app has no test folders"
    strays = folders - app_packages() - {WHOLE_SOURCE}
    assert not strays, f"test folders with no app package of that name: {sorted(strays)}"


def test_no_test_module_sits_at_the_top() -> None:
    loose = sorted(p.name for p in TESTS.glob("test_*.py"))
    assert not loose, f"put these in tests/app/<package>/: {loose}"
