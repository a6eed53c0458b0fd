"""ε and α schedules: fixed, over generations (Eq. 4.1–4.2), after a fault (Eq. 4.3–4.4)."""

from __future__ import annotations

from gnp.config import GnpError, Schedule


def _value(schedule: Schedule, progress: float) -> float:
    """(max − min)·(1 − progress)^n + min, with progress clamped to [0, 1]."""
    p = min(1.0, max(0.0, float(progress)))
    return (schedule.max - schedule.min) * (1.0 - p) ** schedule.n + schedule.min


def schedule_over_generations(schedule: Schedule, generation: int, n_generations: int) -> float:
    """Eq. 4.1–4.2: the value at generation g of G (g = 0 → max, g = G → min)."""
    if n_generations < 1:
        raise GnpError(f"n_generations must be ≥ 1, got {n_generations}")
    return _value(schedule, generation / n_generations)


def schedule_after_fault(schedule: Schedule, t: int, t_fault: int, lifetime: int) -> float:
    """Eq. 4.3–4.4: the value at step t of a lifetime T whose sensors broke at step t'.

    Before the fault (t ≤ t') the value is max: progress is clamped at 0. It decays to min at T.
    """
    if lifetime <= t_fault:
        raise GnpError(f"lifetime ({lifetime}) must exceed the fault step ({t_fault})")
    return _value(schedule, (t - t_fault) / (lifetime - t_fault))


def epsilon_alpha_over_generations(
    epsilon: Schedule, alpha: Schedule, generation: int, n_generations: int
) -> tuple[float, float]:
    """(ε_ev, α_ev) of Eq. 4.1–4.2 at a generation."""
    return (
        schedule_over_generations(epsilon, generation, n_generations),
        schedule_over_generations(alpha, generation, n_generations),
    )


def epsilon_alpha_after_fault(
    epsilon: Schedule, alpha: Schedule, t: int, t_fault: int, lifetime: int
) -> tuple[float, float]:
    """(ε_t, α_t) of Eq. 4.3–4.4 at step t of the implementation phase."""
    return (
        schedule_after_fault(epsilon, t, t_fault, lifetime),
        schedule_after_fault(alpha, t, t_fault, lifetime),
    )
