"""The Faults tab: live noise, breaking and repairing sensors, online learning's ε and α, and
the second stage's switch (live ablation of BS's branch connections / CS's credit branch)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import viser

import gnp
from app.brains.learning import learning as learning_of
from app.dashboard.controls import build, parse_sensors
from app.dashboard.setting_controls import (
    SettingControls,
    add_choice,
    add_control,
    add_number,
    check,
    implementation_settings,
)
from app.dashboard.stage import Stage
from app.dashboard.status import Status
from app.settings.config import ImplementationSettings

FIXED = "fixed"
SCHEDULED = "scheduled from the fault (Eq. 4.3–4.4)"
SECOND_STAGE = "Second stage (BS branch / CS credit)"
LEARNING_LABELS = {
    "epsilon": "ε (fixed)",
    "alpha": "α (fixed)",
    "epsilon_max": "ε max (scheduled)",
    "epsilon_min": "ε min (scheduled)",
    "alpha_max": "α max (scheduled)",
    "alpha_min": "α min (scheduled)",
    "schedule_n": "n (exponent)",
}
"""The implementation phase's settings online learning takes, with their labels here; their
range, step, default and hint come from `ImplementationSettings`."""


@dataclass
class FaultsTab:
    """The Faults tab's handles; its methods act on the robots on show."""

    stage: Stage
    status: Status
    on_break: Callable[[], None]
    noise: viser.GuiSliderHandle[float]
    sensors: viser.GuiTextHandle
    mode: viser.GuiDropdownHandle[str]
    learn: viser.GuiCheckboxHandle
    second_stage: viser.GuiCheckboxHandle
    schedule: viser.GuiDropdownHandle[str]
    rates: SettingControls  # ε, α and their schedule, by ImplementationSettings' field
    horizon: viser.GuiNumberHandle[int]
    buttons: viser.GuiButtonGroupHandle | None = None  # Break now, Repair all

    def set_noise(self) -> None:
        self.stage.set_noise(self.noise.value)  # the live session's check of the model's bounds
        self.status.set(f"noise σ = {self.stage.noise_sigma:g} applied")

    def break_now(self) -> None:
        sensors = parse_sensors(self.sensors.value)
        mode = self.mode.value
        self.stage.break_sensors(sensors, mode)  # the world refuses a bad sensor or mode
        self.on_break()
        self.status.set(f"broke s{', s'.join(map(str, sensors))} ({mode})")

    def repair(self) -> None:
        self.stage.repair()
        self.status.set("all sensors repaired")

    def apply_learning(self) -> None:
        """ε/α are the fixed values before any fault, and after it unless scheduled; the
        values are checked by building the implementation phase's settings."""
        horizon = check(ImplementationSettings, "steps", self.horizon.value, "T − t'")
        values = {path[-1]: value for path, value in self.rates.values().items()}
        scheduled = self.schedule.value != FIXED
        values["schedule"] = "changing" if scheduled else "fixed"
        settings = build(ImplementationSettings, values, "online learning")
        learning = replace(
            learning_of(settings),
            online=bool(self.learn.value),
            horizon=horizon,
            second_stage=bool(self.second_stage.value),
        )
        mode = f"fixed ε {settings.epsilon}, α {settings.alpha}"
        if scheduled:
            mode += (
                f" until a fault, then ε {settings.epsilon_max}→{settings.epsilon_min}, "
                f"α {settings.alpha_max}→{settings.alpha_min}"
            )
        self.stage.set_learning(learning)
        self.status.set(
            f"online learning {'on' if learning.online else 'off'}, {mode}; "
            f"{second_stage_words(self.stage, learning.second_stage)}"
        )


def second_stage_words(stage: Stage, on: bool) -> str:
    """What the second-stage switch means for the robots on show, in words."""
    robots = stage.show.robots if stage.show is not None else ()
    methods = {r.family.label for r in robots}
    fixed = any(not r.family.learns_online for r in robots)
    net = " (a brain on show that does not learn online has no second stage)" if fixed else ""
    if on:
        return "second stage on" + net
    parts = [f"{m} {gnp.TRAITS[m].ablated}" for m in sorted(gnp.METHODS) if m in methods]
    return "second stage off" + (f" ({'; '.join(parts)})" if parts else "") + net


def populate_faults_tab(
    gui: viser.GuiApi, stage: Stage, status: Status, on_break: Callable[[], None]
) -> FaultsTab:
    """Add the Faults tab's controls (inside the current tab) and attach their callbacks.

    `on_break` is called after sensors broke (the Show tab echoes that new lives are off).
    """
    defaults = ImplementationSettings()
    fields = implementation_settings()
    sigma = fields["noise_sigma"]  # the slider spans the setting's range (0..sim.IR_MAX)
    assert sigma.low is not None and sigma.high is not None
    noise = gui.add_slider(
        "Noise σ (live)",
        min=sigma.low,
        max=sigma.high,
        step=1,
        initial_value=defaults.noise_sigma,
        hint=sigma.help(),
    )
    sensors = gui.add_text("Sensors to break", "2,3")
    mode = add_choice(gui, fields["fault_mode"], defaults.fault_mode, "Fault mode")
    buttons = gui.add_button_group("Faults", ("Break now", "Repair all"))
    gui.add_markdown("**Online learning** (Sarsa while on show)")
    learn = gui.add_checkbox("Learn online", initial_value=stage.learning.online)
    second_stage = gui.add_checkbox(
        SECOND_STAGE,
        initial_value=stage.learning.second_stage,
        hint="Live ablation. Off: a BS robot takes the greedy branch connection and stops "
        "learning Q_BS; a CS robot never skips through its credit branch and stops learning "
        "Q_CS; sub node selection (Q_SS) goes on. RL has no second stage.",
    )
    rates = SettingControls({})

    def add_rate(name: str) -> None:
        label = LEARNING_LABELS[name]
        rates.controls[(name,)] = add_control(gui, fields[name], getattr(defaults, name), label)

    add_rate("epsilon")
    add_rate("alpha")
    schedule = gui.add_dropdown("After a fault", (FIXED, SCHEDULED))
    for name in ("epsilon_max", "epsilon_min", "alpha_max", "alpha_min", "schedule_n"):
        add_rate(name)
    # T − t' as the implementation phase's defaults give it, within the bounds of its T.
    horizon = add_number(gui, fields["steps"], learning_of(defaults).horizon, "T − t' (steps)")
    apply = gui.add_button("Apply learning settings")
    tab = FaultsTab(
        stage=stage,
        status=status,
        on_break=on_break,
        noise=noise,
        sensors=sensors,
        mode=mode,
        learn=learn,
        second_stage=second_stage,
        schedule=schedule,
        rates=rates,
        horizon=horizon,
        buttons=buttons,
    )

    tab.noise.on_update(status.guard(tab.set_noise))
    actions = {"Break now": tab.break_now, "Repair all": tab.repair}
    buttons.on_click(lambda event: status.guarded(event.client, actions[buttons.value]))
    tab.learn.on_update(status.guard(tab.apply_learning))
    tab.second_stage.on_update(status.guard(tab.apply_learning))
    apply.on_click(status.guard(tab.apply_learning))
    return tab
