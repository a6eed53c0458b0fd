"""CMA-ES (pycma) and NEAT (neat-python): seeded, isolated from global RNGs, rebuilt by replay."""

from __future__ import annotations

import hashlib
import random
import subprocess
import sys

import neat
import numpy as np
import pytest

import neuro
from neuro.cmaes import Cmaes
from neuro.cmaes import replay as cmaes_replay
from neuro.neat_evolution import NeatParams, NeatSearch, encode
from neuro.neat_evolution import replay as neat_replay


def _sphere(x: np.ndarray) -> np.ndarray:
    return -np.sum((x - 0.3) ** 2, axis=1)


def test_cmaes_improves_leaves_numpy_global_rng_alone_and_replays() -> None:
    np.random.seed(11)  # noqa: NPY002 (the global RNG is what must stay untouched)
    before = np.random.get_state()[1].copy()  # noqa: NPY002
    es = Cmaes(n=6, sigma0=0.5, popsize=12, seed=[4, 2])
    history, best = [], []
    for _ in range(40):
        f = _sphere(es.ask())
        history.append(f)
        best.append(f.max())
        es.tell(f)
    assert np.array_equal(np.random.get_state()[1], before)  # noqa: NPY002
    assert best[-1] > best[0] + 0.1  # it optimises (a sphere at 0.3: from ≈ −0.5 to ≈ 0)
    again = cmaes_replay(6, 0.5, 12, [4, 2], np.array(history[:25]))
    for f in history[25:]:
        again.tell(f)  # told the same fitness, it asks the same candidates
    assert np.array_equal(again.ask(), es.ask())
    other = Cmaes(n=6, sigma0=0.5, popsize=12, seed=[4, 3])
    assert not np.array_equal(other.ask(), Cmaes(n=6, sigma0=0.5, popsize=12, seed=[4, 2]).ask())


def test_cmaes_refuses_bad_fitness() -> None:
    es = Cmaes(n=3, sigma0=0.1, popsize=4, seed=0)
    with pytest.raises(neuro.NeuroError, match="fitness must be"):
        es.tell(np.array([1.0, np.nan, 0.0, 0.0]))


def _neat_fitness(arrays: dict[str, np.ndarray]) -> np.ndarray:
    return arrays["weights"][:, 0, :8].sum(axis=1) - arrays["weights"][:, 1, :8].sum(axis=1)


def test_neat_leaves_python_random_alone_and_replays() -> None:
    random.seed(5)
    outer = random.getstate()
    search = NeatSearch(NeatParams(), 30, seed=9)
    history = []
    for _ in range(12):
        f = _neat_fitness(search.arrays())
        history.append(f)
        search.tell(f)
    assert random.getstate() == outer
    assert search.generation == 12
    again = neat_replay(NeatParams(), 30, 9, np.array(history))
    a, b = search.arrays(), again.arrays()
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert again.random_state() == search.random_state()


def test_neat_search_is_the_same_under_any_hash_seed() -> None:
    code = (
        "import hashlib, numpy as np\n"
        "from neuro.neat_evolution import NeatParams, NeatSearch\n"
        "s = NeatSearch(NeatParams(node_add_prob=0.5), 20, seed=1)\n"
        "for _ in range(8):\n"
        "    a = s.arrays(); s.tell(a['weights'].sum(axis=(1, 2)))\n"
        "a = s.arrays()\n"
        "print(hashlib.sha256(b''.join(a[k].tobytes() for k in sorted(a))).hexdigest())\n"
    )
    digests = {
        subprocess.run(
            [sys.executable, "-c", code],
            capture_output=True,
            text=True,
            check=True,
            env={"PYTHONHASHSEED": str(h), "PATH": ""},
        ).stdout
        for h in (1, 2)
    }
    assert len(digests) == 1
    assert hashlib.sha256(b"").hexdigest() not in digests


def test_dense_nets_match_neat_pythons_own_recurrent_network() -> None:
    params = NeatParams(node_add_prob=0.6, conn_add_prob=0.7, max_hidden=40)
    search = NeatSearch(params, 20, seed=3)
    for _ in range(10):
        search.tell(_neat_fitness(search.arrays()))
    cfg = params.net_config()
    inputs = np.random.default_rng(0).uniform(0, 1, (5, 8))
    grown = 0
    for _, genome in search.genomes():
        arrays = encode(genome, search.config.genome_config, cfg)
        grown += int(arrays["active"][0, 2:].sum())
        oracle = neat.nn.RecurrentNetwork.create(genome, search.config)
        state = neuro.init_state(cfg, 1)
        for x in inputs:
            ours = neuro.step(cfg, arrays, state, x[None])[0]
            # Same sums in another order: equal up to rounding.
            np.testing.assert_allclose(ours, oracle.activate(x.tolist()), rtol=0, atol=1e-12)
    assert grown > 0  # hidden nodes took part


def test_a_genome_beyond_the_capacity_is_named() -> None:
    search = NeatSearch(NeatParams(node_add_prob=1.0, conn_delete_prob=0.0, max_hidden=40), 6, 2)
    for _ in range(4):
        search.tell(np.arange(6.0))
    genome = max((g for _, g in search.genomes()), key=lambda g: len(g.nodes))
    with pytest.raises(neuro.NeuroError, match="more than max_hidden = 0"):
        encode(genome, search.config.genome_config, neuro.RecurrentConfig(max_hidden=0))
