"""The packages import only downwards, and no module imports itself back through others.

Every `import` and `from … import` in sim/, gnp/, neuro/ and app/ is read with `ast` (those inside
functions too: a lazy import is still a dependency). Layers, lowest first:

0. `sim`, `gnp`, `neuro`: the world and the brains' arithmetic; none imports another nor anything
   above.
1. `app.settings` (the run configuration, its fields, presets, arenas, CLI options) and
   `app.system` (worker processes, safe names, exit codes); `app` itself (its `__init__`).
2. `app.loop`: the one loop (`rollout`), its compiled world half, recording, random streams.
3. `app.store`: run files and controller files' envelope.

4. `app.brains`: the brain contract, its registry and the families behind it.
5. `app.phases`: training, implementation and live robots, each a use of the loop through the
   contract.
6. `app.views` (what the dashboard and the export both draw) and `app.tasks` (GNP on
   Gymnasium tasks).
7. `app.experiments` (which runs task experiments through `app.tasks.peer`), `app.export` and
   `app.tune` (Optuna studies of task runs).
8. `app.dashboard`.
9. `app.cli`, which wires everything into `gnp-lab`.

A folder may import its own modules and any folder of a lower layer, never one of its own layer
or above, so the folders cannot import each other in a loop.

`app.settings`, `app.loop` and `app.store` import neither `gnp` nor `neuro`: the settings know a
family by its name and entry points, the loop and the store ask the contract (`FAMILY_FREE`).
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
PACKAGES = ("sim", "gnp", "neuro", "app")
CORE = "app"
FAMILY_FREE = ("app.settings", "app.loop", "app.store")
"""Folders below the brain families that import no family's package (`gnp`, `neuro`): they ask
`app.brains`' contract instead (issue #46)."""
LAYER = {
    "sim": 0,
    "gnp": 0,
    "neuro": 0,
    CORE: 1,
    "app.settings": 1,
    "app.system": 1,
    "app.loop": 2,
    "app.store": 3,
    "app.brains": 4,
    "app.phases": 5,
    "app.views": 6,
    "app.tasks": 6,
    "app.experiments": 7,
    "app.export": 7,
    "app.tune": 7,
    "app.dashboard": 8,
    "app.cli": 9,
}


def module_name(path: Path, root: Path = ROOT) -> str:
    """`app/views/scene.py` → `app.views.scene`; a package's `__init__.py` → the package."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Each module of the packages → the modules of the packages it imports (itself excluded).

    `from a.b import c` counts as an import of `a.b.c` when that is a module, else of `a.b`.
    """
    files = {
        module_name(p, root): p for pkg in PACKAGES for p in sorted((root / pkg).rglob("*.py"))
    }
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                assert node.level == 0, f"{name}: relative import (the project imports absolutely)"
                assert node.module is not None
                for alias in node.names:
                    full = f"{node.module}.{alias.name}"
                    targets.add(full if full in files else node.module)
        graph[name] = {t for t in targets if t in files and t != name}
    return graph


def folder(module: str) -> str:
    """The layer-bearing folder of a module: `sim.world` → `sim`, `app.views.scene` →
    `app.views`, `app.store.reader` → `app.store`, `app/__init__.py` → the core."""
    parts = module.split(".")
    if parts[0] != "app":
        return parts[0]
    candidate = ".".join(parts[:2])
    return candidate if candidate in LAYER else CORE


def layer_violations(graph: Mapping[str, Iterable[str]]) -> list[str]:
    """Imports from one folder into another of the same or a higher layer."""
    bad = []
    for source, targets in graph.items():
        for target in targets:
            a, b = folder(source), folder(target)
            if a != b and LAYER[b] >= LAYER[a]:
                bad.append(f"{source} (layer {LAYER[a]}) imports {target} (layer {LAYER[b]})")
    return sorted(bad)


def family_imports(graph: Mapping[str, Iterable[str]]) -> list[str]:
    """Imports of `gnp` or `neuro` (the package or any module of it) from `FAMILY_FREE`."""
    return sorted(
        f"{source} imports {target}"
        for source, targets in graph.items()
        if folder(source) in FAMILY_FREE
        for target in targets
        if folder(target) in ("gnp", "neuro")
    )


def cycles(graph: Mapping[str, Iterable[str]]) -> list[frozenset[str]]:
    """The strongly connected components of more than one node (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[frozenset[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(frozenset(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph()


def test_every_folder_imports_only_lower_layers(graph: dict[str, set[str]]) -> None:
    assert layer_violations(graph) == []


def test_no_import_loop_between_modules(graph: dict[str, set[str]]) -> None:
    assert [sorted(c) for c in cycles(graph)] == []  # lazy imports inside functions count too


def test_views_are_drawn_by_both_and_import_neither(graph: dict[str, set[str]]) -> None:
    into_views = {folder(s) for s, ts in graph.items() for t in ts if folder(t) == "app.views"}
    assert {"app.dashboard", "app.export"} <= into_views
    from_views = {folder(t) for s, ts in graph.items() if folder(s) == "app.views" for t in ts}
    assert not from_views & {"app.dashboard", "app.export"}
    # The export no longer reaches into the dashboard (it used to: a loop between folders).
    from_export = {folder(t) for s, ts in graph.items() if folder(s) == "app.export" for t in ts}
    assert "app.dashboard" not in from_export


def test_the_checks_catch_what_they_are_for() -> None:
    """A hand-made graph with an upward import and a loop: both are reported."""
    bad = {
        "app.views.scene": {"app.dashboard.stage"},  # views reaching up into the dashboard
        "app.dashboard.stage": {"app.views.scene"},
        "sim.world": {"gnp.engine"},  # sim and gnp never import each other
        "gnp.engine": set(),
        "app.store.reader": {"app.settings.config"},  # the store reads settings: downwards, fine
        "app.settings.config": set(),
    }
    assert layer_violations(bad) == [
        "app.views.scene (layer 6) imports app.dashboard.stage (layer 8)",
        "sim.world (layer 0) imports gnp.engine (layer 0)",
    ]
    assert cycles(bad) == [frozenset({"app.views.scene", "app.dashboard.stage"})]
    assert folder("app.store.reader") == "app.store"
    assert folder("app") == CORE
    assert folder("app.views.graph_view") == "app.views"


def test_the_settings_loop_and_store_import_no_brain_package(graph: dict[str, set[str]]) -> None:
    assert family_imports(graph) == []
    assert {folder(s) for s in graph} >= set(FAMILY_FREE)  # the folders are there to check


def test_the_family_check_catches_an_added_import(tmp_path: Path) -> None:
    """A tree whose loop imports `gnp` inside a function, and whose store imports a module of
    `neuro` for its types only: both are reported."""
    for package in PACKAGES:
        (tmp_path / package).mkdir()
        (tmp_path / package / "__init__.py").write_text("")
    (tmp_path / "gnp" / "engine.py").write_text("")
    (tmp_path / "neuro" / "nets.py").write_text("")
    for sub, code in (
        ("loop", "def f():\n    import gnp\n"),
        (
            "store",
            "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from neuro import nets\n",
        ),
    ):
        (tmp_path / "app" / sub).mkdir()
        (tmp_path / "app" / sub / "__init__.py").write_text("")
        (tmp_path / "app" / sub / "x.py").write_text(code)
    assert family_imports(import_graph(tmp_path)) == [
        "app.loop.x imports gnp",
        "app.store.x imports neuro.nets",
    ]


def test_gymnasium_stays_in_the_envs_modules() -> None:
    """The task's Gymnasium face (`sim.gym_env`, `sim.gym_vector`) imports the world, and GNP
    on Gymnasium tasks (`app.tasks`, issue #34 item 2) imports Gymnasium's tasks; nothing else
    in the packages imports Gymnasium, so the world, the brains and the lab run without it
    (`gnp-lab` loads `app.tasks` only for a task: tests/app/tasks/test_tasks.py)."""
    users = set()
    for pkg in PACKAGES:
        for path in (ROOT / pkg).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
                names = (
                    [alias.name for alias in node.names]
                    if isinstance(node, ast.Import)
                    else [node.module or ""]
                    if isinstance(node, ast.ImportFrom)
                    else []
                )
                if any(name.split(".")[0] == "gymnasium" for name in names):
                    users.add(module_name(path))
    tasks = {"app.tasks.config", "app.tasks.faults", "app.tasks.lives", "app.tasks.spaces"}
    tasks.add("app.tasks.fracnetics_arm")  # fracnetics' own loop, on gymnasium.make(task)
    tasks.add("app.tasks.twin_env")  # a compiled twin handed to fracnetics as a gymnasium.Env
    assert users == {"sim.gym_env", "sim.gym_vector", *tasks}
