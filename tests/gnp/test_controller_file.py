"""A controller written as JSON and read back steps bit-identically; bad files say why."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import gnp


def _learned(method: str) -> tuple[gnp.GnpConfig, gnp.Population]:
    """An individual whose Q tables hold values learned over 60 steps."""
    cfg = gnp.GnpConfig(method=method, n_sub=2, n_branch=2)
    pop = gnp.init_population(cfg, 1, np.random.default_rng(5))
    state = gnp.init_state(cfg, 1, [9])
    rng = np.random.default_rng(6)
    for _ in range(60):
        gnp.step(cfg, pop, state, rng.uniform(0, 1023, (1, 8)), rng.uniform(0, 1, 1), 0.2, 0.3)
    return cfg, pop


def _steps(cfg: gnp.GnpConfig, pop: gnp.Population) -> np.ndarray:
    state = gnp.init_state(cfg, 1, [1])
    rng = np.random.default_rng(2)
    commands = [
        gnp.step(cfg, pop, state, rng.uniform(0, 1023, (1, 8)), rng.uniform(0, 1, 1), 0.1, 0.1)[0]
        for _ in range(200)
    ]
    return np.array(commands)


@pytest.mark.parametrize("method", gnp.METHODS)
def test_a_saved_controller_steps_as_the_original(tmp_path: Path, method: str) -> None:
    cfg, pop = _learned(method)
    assert np.any(pop.q_ss != 0)
    path = gnp.save_controller(tmp_path / "c.json", cfg, pop, {"control_period": 0.064})
    loaded_cfg, loaded, settings = gnp.load_controller(path)
    assert loaded_cfg == cfg  # equal by settings, cached arrays and all
    assert settings == {"control_period": 0.064}
    for name, values in gnp.population_to_arrays(pop).items():
        assert np.array_equal(getattr(loaded, name), values), name
    assert np.array_equal(_steps(cfg, pop.copy()), _steps(loaded_cfg, loaded))


def test_the_document_reads_as_the_thesis_names_things(tmp_path: Path) -> None:
    cfg, pop = _learned("BS")
    document = json.loads(gnp.save_controller(tmp_path / "c.json", cfg, pop).read_text())
    assert document["format"] == "gnp-lab-controller" and document["version"] == 1
    assert [n["type"] for n in document["nodes"][:2]] == ["start", "judgment"]
    assert document["nodes"][-1]["type"] == "processing"
    sub = document["nodes"][3]["sub_nodes"][1]
    assert sub["function"] == int(pop.function[0, 3, 1])  # the sensor judged
    assert (sub["beta"], sub["alpha"]) == (int(pop.mu_beta[0, 3, 1]), int(pop.mu_alpha[0, 3, 1]))
    assert sub["next"]["B"] == [int(j) for j in pop.conn[0, 3, 1, 1]]  # U = 2 connections
    assert sub["q_bs"]["A"][1] == float(pop.q_bs[0, 3, 1, 0, 1])


def test_bad_controller_files_say_what_is_wrong(tmp_path: Path) -> None:
    cfg, pop = _learned("CS")
    good = json.loads(gnp.save_controller(tmp_path / "c.json", cfg, pop).read_text())
    cases = {
        "not found": None,
        "not a JSON controller file": "{oops",
        "not a gnp-lab controller": json.dumps({"hello": 1}),
        "version 7": json.dumps(dict(good, version=7)),
        "has 60 nodes": json.dumps(dict(good, nodes=good["nodes"][:-1])),
        "malformed controller": json.dumps(dict(good, nodes=[{"id": 0}] * len(good["nodes"]))),
    }
    for needle, text in cases.items():
        path = tmp_path / "bad.json"
        path.unlink(missing_ok=True)
        if text is not None:
            path.write_text(text)
        with pytest.raises(gnp.GnpError, match=needle):
            gnp.load_controller(path)
    into_start = json.loads(json.dumps(good))
    into_start["nodes"][5]["sub_nodes"][0]["next"]["A"] = [0]  # no connection into the start
    (tmp_path / "bad.json").write_text(json.dumps(into_start))
    with pytest.raises(gnp.GnpError, match="conn"):
        gnp.load_controller(tmp_path / "bad.json")
    with pytest.raises(gnp.GnpError, match="one individual"):
        gnp.save_controller(tmp_path / "two.json", cfg, gnp.concat([pop, pop]))
