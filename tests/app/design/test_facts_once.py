"""Each fact is written once (issue #33): lints over the source that keep it so.

Every module of app/ (and, for the literals, of sim/, gnp/ and neuro/) is parsed with `ast`; a
fact written a second time (an exit code, a `sim.World(...)` built outside its factory, a private
name of another package) fails here.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import sim
from sim import faults

ROOT = Path(__file__).resolve().parents[3]


def _modules(*folders: str) -> dict[str, ast.Module]:
    return {
        str(path.relative_to(ROOT)): ast.parse(path.read_text(encoding="utf-8"), str(path))
        for folder in folders
        for path in sorted((ROOT / folder).rglob("*.py"))
    }


MODULES = _modules("app")


def test_exit_codes_are_assigned_in_app_exit_codes_only() -> None:
    found = []
    for name, tree in MODULES.items():
        for node in ast.walk(tree):
            targets = node.targets if isinstance(node, ast.Assign) else []
            if isinstance(node, ast.AnnAssign):
                targets = [node.target]
            for target in targets:
                for leaf in ast.walk(target):
                    if isinstance(leaf, ast.Name) and leaf.id.startswith("EXIT_"):
                        found.append(f"{name}: {leaf.id}")
    assert found and all(f.startswith("app/system/exit_codes.py: ") for f in found), found


def test_no_private_module_of_another_package_is_imported() -> None:
    found = []
    for name, tree in MODULES.items():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                modules = [node.module]
            elif isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            else:
                continue
            for module in modules:
                top, *rest = module.split(".")
                ours = top in {"app", "gnp", "sim", "neuro"}
                if not ours and any(part.startswith("_") for part in rest):
                    found.append(f"{name}: {module}")
    assert found == []


def _literal_aliases(tree: ast.Module) -> dict[str, set[object]]:
    """Each `Name = Literal[...]` of a module → its values."""
    return {
        node.targets[0].id: set(ast.literal_eval(node.value.slice))
        if isinstance(node.value.slice, ast.Tuple)
        else {ast.literal_eval(node.value.slice)}
        for node in tree.body
        if isinstance(node, ast.Assign)
        and isinstance(node.targets[0], ast.Name)
        and isinstance(node.value, ast.Subscript)
        and isinstance(node.value.value, ast.Name)
        and node.value.value.id == "Literal"
    }


def test_a_tuple_of_a_literals_values_is_get_args_of_it() -> None:
    """`NAMES: tuple[L, ...] = get_args(L)`, never all the literal's values written again (a
    subset, such as the verdicts without "exploratory", is a fact of its own)."""
    checked, found = [], []
    for name, tree in _modules("app", "sim", "gnp", "neuro").items():
        aliases = _literal_aliases(tree)
        for node in tree.body:
            if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)):
                continue
            annotation = node.annotation
            if not (
                isinstance(annotation, ast.Subscript)
                and isinstance(annotation.value, ast.Name)
                and annotation.value.id == "tuple"
                and isinstance(annotation.slice, ast.Tuple)
                and isinstance(annotation.slice.elts[0], ast.Name)
                and annotation.slice.elts[0].id in aliases
            ):
                continue
            alias = annotation.slice.elts[0].id
            value = node.value
            checked.append(node.target.id)
            if (
                isinstance(value, ast.Call)
                and isinstance(value.func, ast.Name)
                and value.func.id == "get_args"
                and isinstance(value.args[0], ast.Name)
                and value.args[0].id == alias
            ):
                continue
            if isinstance(value, ast.Tuple) and set(ast.literal_eval(value)) == aliases[alias]:
                found.append(f"{name}: {node.target.id}")
    assert {"SCALES", "FAULT_MODES", "PHYSICS", "METHODS", "NOISE_STREAMS"} <= set(checked)
    assert found == []


def test_the_labs_method_default_is_its_presets() -> None:
    from app.brains.gnp_settings import ControllerSettings
    from app.settings.config import METHOD_PRESET
    from app.settings.loading import load_preset

    assert ControllerSettings().method == load_preset(METHOD_PRESET).brain.controller.method == "CS"


def test_the_settings_progress_of_eq_4_1_is_gnps() -> None:
    """`training.schedule_progress`'s values are gnp's (app/settings imports no gnp, #46)."""
    from typing import get_args

    import gnp.config
    from app.settings import config

    assert get_args(config.GenerationProgress) == get_args(gnp.config.GenerationProgress)


def test_the_lab_builds_its_worlds_in_one_factory() -> None:
    """`sim.World(...)` is called in `app.settings.arenas.new_world` only."""
    found = []
    for name, tree in MODULES.items():
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                func = node.func
                called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
                if called == "World":
                    found.append(f"{name}:{node.lineno}")
    assert len(found) == 1 and found[0].startswith("app/settings/arenas.py:"), found


def test_a_fault_is_worded_by_one_function() -> None:
    from app.phases.implementation import describe_fault, fault_text
    from app.settings.config import ImplementationSettings

    assert fault_text((2, 3), "dead", 500) == "sensors 2,3 broken (dead) since step 500"
    assert fault_text([5], "stuck", None) == "sensors 5 broken (stuck)"
    fixed = ImplementationSettings(broken_sensors=(3, 2), fault_mode="saturated")
    assert describe_fault(fixed) == "sensors 2,3 broken (saturated) since step 500"
    drawn = ImplementationSettings(break_count=2, fault_step=40)
    assert describe_fault(drawn) == "2 random sensor(s) per trial broken (dead) since step 40"
    assert describe_fault(ImplementationSettings()) == "no fault"
    worded = {
        name
        for name, tree in MODULES.items()
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and " broken (" in node.value
    }
    assert worded == {"app/phases/implementation.py"}


def test_both_phases_take_their_rates_from_one_place() -> None:
    """The ε/α fields of both phases come from `app.settings.config._rate`: the same names in
    the same order (the stored configs' layout), types and bounds; only defaults and wording
    differ."""
    from app.settings.config import RATE_FIELDS, ImplementationSettings, TrainingSettings

    for model in (TrainingSettings, ImplementationSettings):
        names = list(model.model_fields)
        start = names.index(RATE_FIELDS[0])
        assert tuple(names[start : start + len(RATE_FIELDS)]) == RATE_FIELDS
    for name in RATE_FIELDS:
        ours = TrainingSettings.model_fields[name]
        theirs = ImplementationSettings.model_fields[name]
        assert (ours.annotation, ours.metadata) == (theirs.annotation, theirs.metadata), name
    made = [
        (node.target.id, node.value.func.id)
        for node in ast.walk(MODULES["app/settings/config.py"])
        if isinstance(node, ast.AnnAssign)
        and isinstance(node.target, ast.Name)
        and node.target.id in RATE_FIELDS
        and isinstance(node.value, ast.Call)
        and isinstance(node.value.func, ast.Name)
    ]
    assert sorted(made) == sorted((name, "_rate") for name in RATE_FIELDS * 2)


def test_the_training_life_is_the_envs_episode() -> None:
    import gymnasium

    import sim.gym_env  # noqa: F401  (registers the env)
    from app.settings.config import TrainingSettings
    from sim import LIFE_STEPS

    spec = gymnasium.spec("GnpLab/WallFollow-v0")
    assert TrainingSettings().steps == LIFE_STEPS == spec.max_episode_steps == 1000


# --- the world's defaults and fault codes (#46 item 4) -----------------------------------------

FACT_SOURCES = ("sim", "gnp", "neuro", "app", "bench", "examples")
HOME = "sim/kinds.py"
FACTS = {sim.DEFAULT_PHYSICS: "DEFAULT_PHYSICS", sim.DEFAULT_NOISE_STREAM: "DEFAULT_NOISE_STREAM"}


def _strings(node: ast.expr | None) -> Iterator[str]:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        yield node.value


def written_defaults(tree: ast.AST) -> Iterator[str]:
    """Every string given as a default: a parameter's default, a `default=` argument (argparse,
    pydantic's `Field`), or a name's or a field's value (`X = "..."`, `x: T = "..."`)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
            for default in [*node.args.defaults, *node.args.kw_defaults]:
                yield from _strings(default)
        elif isinstance(node, ast.Call):
            for keyword in node.keywords:
                if keyword.arg == "default":
                    yield from _strings(keyword.value)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            yield from _strings(node.value)


def modules_writing(fact: str) -> set[str]:
    found = set()
    for package in FACT_SOURCES:
        for path in sorted((ROOT / package).rglob("*.py")):
            if fact in written_defaults(ast.parse(path.read_text(encoding="utf-8"))):
                found.add(path.relative_to(ROOT).as_posix())
    return found


def test_the_default_physics_and_noise_stream_are_written_in_one_module() -> None:
    assert sim.DEFAULT_PHYSICS in sim.PHYSICS
    assert sim.DEFAULT_NOISE_STREAM in sim.NOISE_STREAMS
    for fact, name in FACTS.items():
        assert modules_writing(fact) == {HOME}, (
            f"{fact!r} is a default in one module, {HOME}: elsewhere write sim.{name}"
        )


def test_the_noise_kernel_names_the_fault_codes() -> None:
    """The codes are 1 + each mode's index in `FAULT_MODES`, and the kernels compare a sensor's
    mode with those names, never with a bare number."""
    codes = dict(faults.FAULT_CODES)
    assert codes == {m: i + 1 for i, m in enumerate(sim.FAULT_MODES)}
    assert faults.HEALTHY_CODE == 0 not in codes.values()
    tree = ast.parse((ROOT / "sim" / "noise.py").read_text(encoding="utf-8"))
    kernels = {
        node.name: node
        for node in ast.walk(tree)
        if isinstance(node, ast.FunctionDef) and node.name in ("_seen", "observe_pair")
    }
    assert set(kernels) == {"_seen", "observe_pair"}
    for name, kernel in kernels.items():
        compared = [
            side
            for node in ast.walk(kernel)
            if isinstance(node, ast.Compare)
            for side in (node.left, *node.comparators)
        ]
        numbers = [s.value for s in compared if isinstance(s, ast.Constant)]
        assert not [n for n in numbers if isinstance(n, int)], f"{name} compares with {numbers}"
        named = {s.id for s in compared if isinstance(s, ast.Name)}
        assert named & {"DEAD_CODE", "SATURATED_CODE", "STUCK_CODE", "RANDOM_CODE"}, name
