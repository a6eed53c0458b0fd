"""RL, BS and CS side by side: the bundled runs of chapter 5's settings, one per method.

The three runs were made by the lab's own commands (README, "The bundled runs"): the same
preset (thesis-ch5), seed and 1000 generations, differing only in the method. The Show tab's
switch puts the final best of one of them, or of all three at once, on show in the arena,
start pose and faults on show now.
"""

from __future__ import annotations

from pathlib import Path

from app import store
from app.dashboard.controls import DashboardInputError
from app.dashboard.stage import Show, Stage, run_robot

BUNDLED: dict[str, str] = {"RL": "demo-rl", "BS": "demo-bs", "CS": "demo"}
"""The bundled run of each method, by its name in saved_runs/."""
ALL_THREE = "RL + BS + CS"
CHOICES = (*BUNDLED, ALL_THREE)
CHECKOUT_RUNS = Path(__file__).resolve().parents[2] / "saved_runs"
"""Where a checkout keeps the bundled runs (looked in when the runs dir lacks them)."""


def bundled_run(runs_dir: Path, method: str) -> tuple[str, Path]:
    """(name, file) of `method`'s bundled run: in the runs dir, else in the checkout's.

    Raises:
        DashboardInputError: an unknown method, or its run is in neither place.
    """
    if method not in BUNDLED:
        raise DashboardInputError(f"method must be one of {', '.join(BUNDLED)}, got {method!r}")
    name = BUNDLED[method]
    for folder, shown in ((runs_dir, name), (CHECKOUT_RUNS, f"{name} (bundled)")):
        path = folder / f"{name}.h5"
        if path.is_file():
            return shown, path
    raise DashboardInputError(
        f"the bundled {method} run {name}.h5 is in neither {runs_dir} nor {CHECKOUT_RUNS}"
    )


def method_show(stage: Stage, runs_dir: Path, choice: str) -> Show:
    """The final best of `choice`'s bundled run (or of all three, RL, BS, CS in that order)
    in the arena and from the start pose on show now."""
    if choice not in CHOICES:
        raise DashboardInputError(f"show must be one of {', '.join(CHOICES)}, got {choice!r}")
    methods = tuple(BUNDLED) if choice == ALL_THREE else (choice,)
    robots, names, sources, life, period = [], [], [], 0, 0.0
    for method in methods:
        name, path = bundled_run(runs_dir, method)
        with store.RunReader(path) as reader:
            robots.append(run_robot(reader))
            training = reader.config.training
            life, period = training.steps, training.control_period
        names.append(name)
        sources.append(path)
    title = f"the final best of {choice}" + (" side by side" if len(methods) > 1 else "")
    return Show(
        f"{title} (bundled chapter-5 runs)",
        tuple(robots),
        stage.arena,
        stage.start,
        life=life,
        control_period=period,
        runs=tuple(names),
        sources=tuple(sources),
    )


def show_methods(stage: Stage, runs_dir: Path, choice: str) -> None:
    """Put `choice` on show, keeping the sensors broken on show now broken."""
    stage.present(method_show(stage, runs_dir, choice), keep_faults=True)
