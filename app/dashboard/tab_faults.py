"""The Faults tab: live noise, breaking and repairing sensors, online learning's ε and α, and
the second stage's switch (live ablation of BS's branch connections / CS's credit branch)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import viser

import gnp
import sim
from app.dashboard.controls import DashboardInputError, finite, parse_mode, parse_sensors, whole
from app.dashboard.stage import Stage
from app.dashboard.status import Status
from app.live import LearningSettings, brain_name

FIXED = "fixed"
SCHEDULED = "scheduled from the fault (Eq. 4.3–4.4)"
MAX_LIVE_NOISE = 300  # the slider's end; the training field goes up to sim.IR_MAX
SECOND_STAGE = "Second stage (BS branch / CS credit)"


@dataclass
class FaultsTab:
    """The Faults tab's handles; its methods act on the robots on show."""

    stage: Stage
    status: Status
    on_break: Callable[[], None]
    noise: viser.GuiSliderHandle[int]
    sensors: viser.GuiTextHandle
    mode: viser.GuiDropdownHandle[sim.FaultMode]
    learn: viser.GuiCheckboxHandle
    second_stage: viser.GuiCheckboxHandle
    schedule: viser.GuiDropdownHandle[str]
    eps_fixed: viser.GuiNumberHandle[float]
    alpha_fixed: viser.GuiNumberHandle[float]
    eps_max: viser.GuiNumberHandle[float]
    eps_min: viser.GuiNumberHandle[float]
    alpha_max: viser.GuiNumberHandle[float]
    alpha_min: viser.GuiNumberHandle[float]
    n: viser.GuiNumberHandle[float]
    horizon: viser.GuiNumberHandle[int]

    def set_noise(self) -> None:
        sigma = finite(self.noise.value, "noise σ", 0.0, sim.IR_MAX)
        self.stage.set_noise(sigma)
        self.status.set(f"noise σ = {sigma:g} applied")

    def break_now(self) -> None:
        sensors = parse_sensors(self.sensors.value)
        mode = parse_mode(self.mode.value)
        self.stage.break_sensors(sensors, mode)
        self.on_break()
        self.status.set(f"broke s{', s'.join(map(str, sensors))} ({mode})")

    def repair(self) -> None:
        self.stage.repair()
        self.status.set("all sensors repaired")

    def apply_learning(self) -> None:
        """ε/α are the fixed values before any fault, and after it unless scheduled."""
        eps = finite(self.eps_fixed.value, "ε", 0.0, 1.0)
        alpha = finite(self.alpha_fixed.value, "α", 0.0, 1.0)
        after_fault = None
        mode = f"fixed ε {eps}, α {alpha}"
        if self.schedule.value != FIXED:
            eps_max = finite(self.eps_max.value, "ε max", 0.0, 1.0)
            alpha_max = finite(self.alpha_max.value, "α max", 0.0, 1.0)
            eps_min = finite(self.eps_min.value, "ε min", 0.0, 1.0)
            alpha_min = finite(self.alpha_min.value, "α min", 0.0, 1.0)
            if eps_min > eps_max or alpha_min > alpha_max:
                raise DashboardInputError("a schedule's min must not exceed its max")
            n = finite(self.n.value, "n", 0.01, 100.0)
            after_fault = (
                gnp.Schedule(max=eps_max, min=eps_min, n=n),
                gnp.Schedule(max=alpha_max, min=alpha_min, n=n),
            )
            mode += f" until a fault, then ε {eps_max}→{eps_min}, α {alpha_max}→{alpha_min}"
        learning = LearningSettings(
            online=bool(self.learn.value),
            epsilon=eps,
            alpha=alpha,
            after_fault=after_fault,
            horizon=whole(self.horizon.value, "T − t'", 1, 10**6),
            second_stage=bool(self.second_stage.value),
        )
        self.stage.set_learning(learning)
        self.status.set(
            f"online learning {'on' if learning.online else 'off'}, {mode}; "
            f"{second_stage_words(self.stage, learning.second_stage)}"
        )


def second_stage_words(stage: Stage, on: bool) -> str:
    """What the second-stage switch means for the robots on show, in words."""
    methods = {brain_name(r.cfg) for r in stage.show.robots} if stage.show is not None else set()
    nets = " (a neural net on show neither learns online nor has a second stage)"
    net = nets if methods & {"Elman", "NEAT"} else ""
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
    noise = gui.add_slider("Noise σ (live)", min=0, max=MAX_LIVE_NOISE, step=1, initial_value=0)
    sensors = gui.add_text("Sensors to break", "2,3")
    mode = gui.add_dropdown("Fault mode", sim.FAULT_MODES)
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
    eps_fixed = gui.add_number("ε (fixed)", 0.1, min=0.0, max=1.0, step=0.005)
    alpha_fixed = gui.add_number("α (fixed)", 0.1, min=0.0, max=1.0, step=0.005)
    schedule = gui.add_dropdown("After a fault", (FIXED, SCHEDULED))
    eps_max = gui.add_number("ε max (scheduled)", 0.015, min=0.0, max=1.0, step=0.005)
    eps_min = gui.add_number("ε min (scheduled)", 0.0, min=0.0, max=1.0, step=0.005)
    alpha_max = gui.add_number("α max (scheduled)", 0.15, min=0.0, max=1.0, step=0.005)
    alpha_min = gui.add_number("α min (scheduled)", 0.0, min=0.0, max=1.0, step=0.005)
    n = gui.add_number("n (exponent)", 1.0, min=0.01, max=100.0, step=0.1)
    horizon = gui.add_number("T − t' (steps)", 2500, min=1, max=10**6, step=1)
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
        eps_fixed=eps_fixed,
        alpha_fixed=alpha_fixed,
        eps_max=eps_max,
        eps_min=eps_min,
        alpha_max=alpha_max,
        alpha_min=alpha_min,
        n=n,
        horizon=horizon,
    )

    tab.noise.on_update(status.guard(tab.set_noise))
    actions = {"Break now": tab.break_now, "Repair all": tab.repair}
    buttons.on_click(lambda event: status.guarded(event.client, actions[buttons.value]))
    tab.learn.on_update(status.guard(tab.apply_learning))
    tab.second_stage.on_update(status.guard(tab.apply_learning))
    apply.on_click(status.guard(tab.apply_learning))
    return tab
