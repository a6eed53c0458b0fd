"""Online learning's rates: the ε/α schedules of a phase's settings (Eq. 4.1-4.4) and the
learning of a batch of lives (`LearningSettings`), in gnp's arithmetic (`gnp.Schedule`).

The settings (app/settings) hold the phases' ε/α fields; what they mean as schedules is here,
with the families that learn online.
"""

from __future__ import annotations

from dataclasses import dataclass

import gnp
from app.settings.config import ImplementationSettings, TrainingSettings
from app.settings.fields import settings_of
from gnp import Schedule


def schedules(settings: TrainingSettings | ImplementationSettings) -> tuple[Schedule, Schedule]:
    """(ε, α) of a phase: fixed values, or from max to min (training: over generations,
    Eq. 4.1-4.2; implementation: after the fault, Eq. 4.3-4.4)."""
    if settings.schedule == "fixed":
        return Schedule.fixed(settings.epsilon), Schedule.fixed(settings.alpha)
    return (
        Schedule(max=settings.epsilon_max, min=settings.epsilon_min, n=settings.schedule_n),
        Schedule(max=settings.alpha_max, min=settings.alpha_min, n=settings.schedule_n),
    )


_IMPLEMENTATION = ImplementationSettings.model_fields
_IMPLEMENTATION_FACTS = {s.name: s for s in settings_of(ImplementationSettings)}


@dataclass(frozen=True)
class LearningSettings:
    """Online Sarsa of a batch: ε and α at each step, given the step of the latest fault.

    Before any fault ε/α are the fixed values (thesis §4.5: fixed until t'); from a fault on they
    follow `after_fault`, the (ε, α) schedules of Eq. 4.3–4.4 from max to min over `horizon`
    steps (the implementation phase's T − t'), or stay fixed when it is None.
    """

    online: bool = True
    # Defaults: the implementation phase's (ImplementationSettings), written there once.
    epsilon: float = _IMPLEMENTATION["epsilon"].default
    alpha: float = _IMPLEMENTATION["alpha"].default
    after_fault: tuple[gnp.Schedule, gnp.Schedule] | None = None
    horizon: int = _IMPLEMENTATION["steps"].default - _IMPLEMENTATION["fault_step"].default
    second_stage: bool = True  # off: live ablation of BS's branch / CS's credit (gnp.step)

    def __post_init__(self) -> None:
        # Built directly too (the page's learning, a live session), not only from checked
        # settings: the same bounds as the implementation phase's fields.
        for name, field in (("ε", "epsilon"), ("α", "alpha")):
            value, fact = getattr(self, field), _IMPLEMENTATION_FACTS[field]
            low, high = fact.low, fact.high
            assert low is not None and high is not None  # both fields are bounded
            if not low <= value <= high:
                raise ValueError(f"{name} must be in {fact.range_text()}, got {value}")
        fewest = _IMPLEMENTATION_FACTS["steps"].low  # a horizon is some of the phase's steps
        assert fewest is not None
        if self.horizon < fewest:
            raise ValueError(f"the schedule horizon must be ≥ {fewest} step, got {self.horizon}")

    def rates(self, t: int, fault_step: int | None) -> tuple[float, float]:
        """ε and α at step `t`, the latest fault (or the phase's t') at `fault_step`."""
        if self.after_fault is None or fault_step is None or t < fault_step:
            return self.epsilon, self.alpha
        return gnp.epsilon_alpha_after_fault(
            *self.after_fault, t, fault_step, fault_step + self.horizon
        )


def learning(settings: ImplementationSettings) -> LearningSettings:
    """Online learning of the implementation phase's trials: fixed ε/α until t', then the
    configured schedule over T − t'."""
    return LearningSettings(
        epsilon=settings.epsilon,
        alpha=settings.alpha,
        after_fault=schedules(settings) if settings.schedule == "changing" else None,
        horizon=max(1, settings.steps - settings.fault_step),
    )
