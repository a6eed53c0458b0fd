"""ε and α schedules: fixed, over generations (Eq. 4.1–4.2), after a fault (Eq. 4.3–4.4)."""

from __future__ import annotations

from gnp.config import GenerationProgress, GnpError, Schedule


def _value(schedule: Schedule, progress: float) -> float:
    """(max − min)·(1 − progress)^n + min, with progress clamped to [0, 1]."""
    p = min(1.0, max(0.0, float(progress)))
    return (schedule.max - schedule.min) * (1.0 - p) ** schedule.n + schedule.min


def generation_progress(
    generation: int, n_generations: int, progress: GenerationProgress = "last-generation-min"
) -> float:
    """Progress of Eq. 4.1–4.2 at generation g (0-based) of a run of G generations.

    "last-generation-min": g/(G−1), so generation 0 uses max and the last one evaluated,
    g = G−1, uses exactly min (§4.3.1: max "at the first generation", decreased "until" min);
    with G = 1 the only generation uses max. "g-over-G": g/G as printed, so the last evaluated
    generation stays (max − min)/G above min. Clamped to [0, 1].
    """
    if n_generations < 1:
        raise GnpError(f"n_generations must be ≥ 1, got {n_generations}")
    if progress == "last-generation-min":
        span = n_generations - 1
        value = generation / span if span > 0 else 0.0
    elif progress == "g-over-G":
        value = generation / n_generations
    else:
        raise GnpError(f"unknown generation progress {progress!r}")
    return min(1.0, max(0.0, float(value)))


def schedule_over_generations(
    schedule: Schedule,
    generation: int,
    n_generations: int,
    progress: GenerationProgress = "last-generation-min",
) -> float:
    """Eq. 4.1–4.2: the value at generation g (0-based) of G; see `generation_progress`."""
    return _value(schedule, generation_progress(generation, n_generations, progress))


def schedule_after_fault(schedule: Schedule, t: int, t_fault: int, lifetime: int) -> float:
    """Eq. 4.3–4.4: the value at step t of a lifetime T whose sensors broke at step t'.

    Before the fault (t ≤ t') the value is max: progress is clamped at 0. It decays to min at T.
    """
    if lifetime <= t_fault:
        raise GnpError(f"lifetime ({lifetime}) must exceed the fault step ({t_fault})")
    return _value(schedule, (t - t_fault) / (lifetime - t_fault))


def epsilon_alpha_over_generations(
    epsilon: Schedule,
    alpha: Schedule,
    generation: int,
    n_generations: int,
    progress: GenerationProgress = "last-generation-min",
) -> tuple[float, float]:
    """(ε_ev, α_ev) of Eq. 4.1–4.2 at a generation (0-based); see `generation_progress`."""
    return (
        schedule_over_generations(epsilon, generation, n_generations, progress),
        schedule_over_generations(alpha, generation, n_generations, progress),
    )


def epsilon_alpha_after_fault(
    epsilon: Schedule, alpha: Schedule, t: int, t_fault: int, lifetime: int
) -> tuple[float, float]:
    """(ε_t, α_t) of Eq. 4.3–4.4 at step t of the implementation phase."""
    return (
        schedule_after_fault(epsilon, t, t_fault, lifetime),
        schedule_after_fault(alpha, t, t_fault, lifetime),
    )
