"""The Compare tab: two runs' best individuals in the same arena, start pose and fault."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import viser

import sim
from app.dashboard.controls import NO_RUNS, open_run, parse_sensors
from app.dashboard.setting_controls import add_choice, add_number, check, implementation_settings
from app.dashboard.stage import Show, Stage, run_robot
from app.dashboard.status import Status, set_value
from app.dashboard.tab_runs import set_options
from app.settings.config import ImplementationSettings


@dataclass
class CompareTab:
    """The Compare tab's handles."""

    stage: Stage
    status: Status
    runs_dir: Path
    run_a: viser.GuiDropdownHandle[str]
    run_b: viser.GuiDropdownHandle[str]
    arena: viser.GuiDropdownHandle[str]
    start: viser.GuiDropdownHandle[str]
    sensors: viser.GuiTextHandle
    mode: viser.GuiDropdownHandle[str]
    fault_step: viser.GuiNumberHandle[int]

    def list_runs(self, names: Sequence[str]) -> None:
        """Offer `names` as A and B; two different runs by default when there are two."""
        set_options(self.run_a, names)
        set_options(self.run_b, names)
        if len(names) > 1 and self.run_b.value == self.run_a.value:
            set_value(self.run_b, names[1])

    def compare(self) -> None:
        names = (self.run_a.value, self.run_b.value)
        robots, sources = [], []
        for name in names:
            with open_run(self.runs_dir, name) as reader:
                robots.append(run_robot(reader))
                sources.append(reader.path)
        sensors = parse_sensors(self.sensors.value)
        mode = self.mode.value
        step = check(ImplementationSettings, "fault_step", self.fault_step.value, "fault step")
        self.stage.present(
            Show(
                f"{names[0]} vs {names[1]}",
                tuple(robots),
                self.arena.value,
                int(self.start.value),
                fault=(step, sensors, mode),
                runs=names,
                sources=tuple(sources),
            )
        )
        self.status.set(f"comparing {names[0]} and {names[1]}")


def populate_compare_tab(
    gui: viser.GuiApi, stage: Stage, status: Status, runs_dir: Path
) -> CompareTab:
    """Add the Compare tab's controls (inside the current tab) and attach their callbacks."""
    gui.add_markdown("Two runs' best individuals, same arena, start pose and fault.")
    # A label another tab also has ends in a space, so each field is found by its own label.
    fields = implementation_settings()
    tab = CompareTab(
        stage=stage,
        status=status,
        runs_dir=runs_dir,
        run_a=gui.add_dropdown("Run A (blue)", (NO_RUNS,)),
        run_b=gui.add_dropdown("Run B (orange)", (NO_RUNS,)),
        arena=gui.add_dropdown("Arena ", sim.ARENA_NAMES, initial_value="implementation"),
        start=gui.add_dropdown("Start pose ", tuple(str(i) for i in range(sim.N_START_POSES))),
        sensors=gui.add_text("Break sensors ", "2,3"),
        mode=add_choice(gui, fields["fault_mode"], fields["fault_mode"].default, "Mode "),
        fault_step=add_number(gui, fields["fault_step"], 300, "At step"),
    )
    go = gui.add_button("Compare", icon=viser.Icon.ARROWS_LEFT_RIGHT)
    go.on_click(status.guard(tab.compare))
    return tab
