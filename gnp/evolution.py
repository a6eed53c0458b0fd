"""Evolution (§2.3.3, Table 2.4): tournament selection, node-gene crossover, mutation, elitism.

Every operator is a pure function of its inputs and an explicit numpy Generator: inputs are
never modified. Q tables travel with their node genes (copied, crossed, inherited).
"""

from __future__ import annotations

import numpy as np

from gnp.config import (
    JUDGMENT,
    PROCESSING,
    SENSOR_MAX,
    SPEED_MAX,
    EvolutionConfig,
    GnpConfig,
    GnpError,
    JudgmentPair,
)
from gnp.population import FIELDS, Population, concat, population_to_arrays, take
from gnp.structure import add_delete_nodes


def evolve(
    cfg: GnpConfig,
    pop: Population,
    fitness: np.ndarray,
    generation: int,
    n_generations: int,
    rng: np.random.Generator,
    evo: EvolutionConfig | None = None,
) -> Population:
    """The next generation: elites, then crossover offspring, then mutants (same size as pop);
    the mutants also add or delete a node with `evo.p_add_delete` (`gnp.structure`).

    Args:
        cfg: the configuration of `pop`.
        pop: the current generation (not modified).
        fitness: (N,) fitness per individual (Eq. 2.8); higher is better.
        generation: current generation g (0-based), for non-uniform mutation.
        n_generations: total generations G.
        rng: the only source of randomness.
        evo: evolution settings (Table 2.4 defaults).
    """
    evo = evo or EvolutionConfig()
    fit = np.asarray(fitness, dtype=np.float64)
    n = pop.size
    if fit.shape != (n,):
        raise GnpError(f"fitness must have shape ({n},), got {fit.shape}")
    if not np.all(np.isfinite(fit)):
        raise GnpError("fitness must be finite")
    if n_generations < 1 or not 0 <= generation <= n_generations:
        raise GnpError(f"need 0 ≤ generation ≤ n_generations ≥ 1, got {generation}/{n_generations}")
    n_elite, n_cross, n_mut = evo.split(n)
    elite = np.argsort(-fit, kind="stable")[:n_elite]
    parts = [take(pop, elite)]
    if n_cross:
        mothers = tournament(fit, n_cross // 2, evo.tournament_size, rng)
        fathers = tournament(fit, n_cross // 2, evo.tournament_size, rng)
        parts.append(crossover(take(pop, mothers), take(pop, fathers), evo.p_crossover, rng))
    if n_mut:
        parents = tournament(fit, n_mut, evo.tournament_size, rng)
        parts.append(mutants(cfg, take(pop, parents), generation, n_generations, rng, evo))
    return concat(parts)


def mutants(
    cfg: GnpConfig,
    parents: Population,
    generation: int,
    n_generations: int,
    rng: np.random.Generator,
    evo: EvolutionConfig,
) -> Population:
    """`evolve`'s mutants of `parents` (copies): `mutate` at `evo`'s rates, then add/delete-node
    mutation (`gnp.structure`) where `evo.p_add_delete` > 0 (no draw when off: the robot's
    stream as before)."""
    made = mutate(
        cfg,
        parents,
        generation,
        n_generations,
        rng,
        evo.p_mutation,
        evo.nonuniform_b,
        evo.judgment_pair,
    )
    if evo.p_add_delete > 0:
        made = add_delete_nodes(cfg, made, evo.p_add_delete, rng).population
    return made


def tournament(fitness: np.ndarray, count: int, size: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of `count` winners, each the fittest of `size` distinct random individuals.

    Ties go to the contestant drawn first. The tournament shrinks to N when N < size.
    """
    n = fitness.shape[0]
    k = min(size, n)
    winners = np.empty(count, dtype=np.intp)
    for i in range(count):
        contestants = rng.choice(n, size=k, replace=False)
        winners[i] = contestants[np.argmax(fitness[contestants])]
    return winners


def crossover(
    mothers: Population, fathers: Population, p_crossover: float, rng: np.random.Generator
) -> Population:
    """Uniform node-gene crossover: pair i swaps each node (all its genes and Q values) with
    probability P_c. Returns 2·pairs offspring, the two children of pair i at 2i and 2i+1."""
    pairs, n_nodes = mothers.function.shape[:2]
    swap = rng.random((pairs, n_nodes)) < p_crossover
    out = {}
    for f in FIELDS:
        a, b = getattr(mothers, f), getattr(fathers, f)
        mask = swap.reshape(swap.shape + (1,) * (a.ndim - 2))
        first = np.where(mask, b, a)
        second = np.where(mask, a, b)
        out[f] = np.stack((first, second), axis=1).reshape(2 * pairs, *a.shape[1:])
    return Population(**out)


def mutate(
    cfg: GnpConfig,
    parents: Population,
    generation: int,
    n_generations: int,
    rng: np.random.Generator,
    p_mutation: float = 0.01,
    b: float = 2.0,
    judgment_pair: JudgmentPair = "joint",
) -> Population:
    """One mutant per parent: each connection, function and parameter changes with P_m.

    - connection (branches, branch connections, credit branches): rewired to another node
      among 1..V−1;
    - function: another sensor (judgment) or the other wheel (processing);
    - processing speed: redrawn uniformly in −10..10;
    - judgment parameter a = {β, α}, non-uniform mutation (Eq. 2.4–2.5), β ≤ α kept:
      "joint" (the thesis's one parameter): with P_m per sub node, the pair moves by Eq. 2.4
      with one ζ and one r, α within [0, 1023] and β within [0, α] (see `mutate_judgment_pair`);
      "independent": α with P_m within [β, 1023], then β with its own P_m within [0, α].
    Q values are inherited unchanged.
    """
    out = {f: a.copy() for f, a in population_to_arrays(parents).items()}
    n_nodes = cfg.n_nodes
    for f in ("conn", "credit"):
        a = out[f]
        hit = rng.random(a.shape) < p_mutation
        # Uniform over the V−2 nodes other than the current target (and the start node).
        r = rng.integers(1, n_nodes - 1, size=int(hit.sum()))
        cur = a[hit]
        a[hit] = np.where(r >= cur, r + 1, r)
    judg = np.flatnonzero(cfg.node_type == JUDGMENT)
    proc = np.flatnonzero(cfg.node_type == PROCESSING)
    fn = out["function"]

    def chosen(nodes: np.ndarray) -> np.ndarray:
        """(N, V, m) mask picking each sub node of `nodes` with probability P_m."""
        mask = np.zeros(fn.shape, dtype=bool)
        mask[:, nodes] = rng.random((fn.shape[0], nodes.size, fn.shape[2])) < p_mutation
        return mask

    hit = chosen(judg)  # another sensor: uniform over the 7 others (n_inputs − 1)
    if cfg.n_inputs > 1:
        r = rng.integers(0, cfg.n_inputs - 1, size=int(hit.sum()))
        fn[hit] = np.where(r >= fn[hit], r + 1, r)
    hit = chosen(proc)  # the other wheel; of k > 2 outputs, uniform over the k − 1 others
    if cfg.n_outputs == 2:
        fn[hit] = 1 - fn[hit]
    elif cfg.n_outputs > 2:
        r = rng.integers(0, cfg.n_outputs - 1, size=int(hit.sum()))
        fn[hit] = np.where(r >= fn[hit], r + 1, r)
    hit = chosen(proc)
    out["speed"][hit] = rng.integers(-SPEED_MAX, SPEED_MAX + 1, size=int(hit.sum()))
    alpha, beta = out["mu_alpha"], out["mu_beta"]
    if judgment_pair == "joint":
        hit = chosen(judg)  # the pair {β, α}, one parameter
        alpha[hit], beta[hit] = mutate_judgment_pair(
            alpha[hit], beta[hit], generation, n_generations, b, rng
        )
    elif judgment_pair == "independent":
        hit = chosen(judg)  # α within [β, 1023]
        upper = np.full(int(hit.sum()), SENSOR_MAX)
        alpha[hit] = nonuniform_mutation(
            alpha[hit], beta[hit], upper, generation, n_generations, b, rng
        )
        hit = chosen(judg)  # then β within [0, α]
        lower = np.zeros(int(hit.sum()))
        beta[hit] = nonuniform_mutation(
            beta[hit], lower, alpha[hit], generation, n_generations, b, rng
        )
    else:
        raise GnpError(f"unknown judgment_pair {judgment_pair!r}")
    return Population(**out)


def mutate_judgment_pair(
    alpha: np.ndarray,
    beta: np.ndarray,
    generation: int,
    n_generations: int,
    b: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 2.4 applied to a = {β, α} as one parameter: one ζ and one r per pair.

    ζ = 0: α' = α + Δ(g, 1023 − α), β' = β + Δ(g, α − β) (UB = α for β);
    ζ = 1: α' = α − Δ(g, α − 0),    β' = β − Δ(g, β − 0)  (LB = 0 for both),
    with the same Δ(g, y) = y·(1 − r^((1 − g/G)^b)) factor for both, rounded to integers.
    The bounds are the thesis's as printed, and since both values move by the same fraction of
    their room, β ≤ α holds without clipping (rounding is monotone).
    """
    a = np.asarray(alpha, dtype=np.float64)
    be = np.asarray(beta, dtype=np.float64)
    if a.shape != be.shape:
        raise GnpError(f"α and β must have one shape, got {a.shape} and {be.shape}")
    if a.size == 0:
        return np.asarray(alpha).copy(), np.asarray(beta).copy()
    zeta = rng.integers(0, 2, size=a.shape)
    r = rng.random(a.shape)
    shrink = 1.0 - r ** ((1.0 - _progress(generation, n_generations)) ** b)
    up = zeta == 0
    new_alpha = np.where(up, a + shrink * (SENSOR_MAX - a), a - shrink * a)
    new_beta = np.where(up, be + shrink * (a - be), be - shrink * be)
    new_alpha = np.clip(np.rint(new_alpha), 0, SENSOR_MAX)
    new_beta = np.clip(np.rint(new_beta), 0, new_alpha)
    return (
        new_alpha.astype(np.asarray(alpha).dtype),
        new_beta.astype(np.asarray(beta).dtype),
    )


def _progress(generation: int, n_generations: int) -> float:
    """g/G of Eq. 2.5, clamped to [0, 1]."""
    return min(1.0, max(0.0, generation / n_generations))


def nonuniform_mutation(
    values: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    generation: int,
    n_generations: int,
    b: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Non-uniform mutation (Eq. 2.4–2.5) of integer parameters within [lower, upper].

    a' = a + Δ(g, UB − a) if ζ = 0, a − Δ(g, a − LB) if ζ = 1, with
    Δ(g, y) = y·(1 − r^((1 − g/G)^b)) (Michalewicz's form: long jumps early, fine tuning as
    g → G), rounded to the nearest integer. ζ and r are drawn per value.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.size == 0:
        return np.asarray(values).copy()
    lo = np.asarray(lower, dtype=np.float64)
    hi = np.asarray(upper, dtype=np.float64)
    zeta = rng.integers(0, 2, size=v.shape)
    r = rng.random(v.shape)
    shrink = 1.0 - r ** ((1.0 - _progress(generation, n_generations)) ** b)
    new = np.where(zeta == 0, v + shrink * (hi - v), v - shrink * (v - lo))
    return np.clip(np.rint(new), lo, hi).astype(np.asarray(values).dtype)
