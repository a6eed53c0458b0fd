"""A controller written as JSON and read back steps bit-identically, for either brain family;
bad files say why on one line, in one error type."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import gnp
import neuro
from app.brains.gnp_file import GnpController
from app.brains.net_file import NetController
from app.brains.registry import load_controller
from app.store.controller_file import ControllerFileError, save_controller


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


def _load_gnp(path: Path) -> GnpController:
    controller = load_controller(path)
    assert isinstance(controller, GnpController)
    return controller


@pytest.mark.parametrize("method", gnp.METHODS)
def test_a_saved_controller_steps_as_the_original(tmp_path: Path, method: str) -> None:
    cfg, pop = _learned(method)
    assert np.any(pop.q_ss != 0)
    path = save_controller(tmp_path / "c.json", GnpController(cfg, pop, {"control_period": 0.064}))
    loaded = _load_gnp(path)
    assert loaded.cfg == cfg  # equal by settings, cached arrays and all
    assert loaded.settings == {"control_period": 0.064}
    for name, values in gnp.population_to_arrays(pop).items():
        assert np.array_equal(getattr(loaded.individual, name), values), name
    assert np.array_equal(_steps(cfg, pop.copy()), _steps(loaded.cfg, loaded.individual))


def test_the_document_reads_as_the_thesis_names_things(tmp_path: Path) -> None:
    cfg, pop = _learned("BS")
    document = json.loads(save_controller(tmp_path / "c.json", GnpController(cfg, pop)).read_text())
    assert list(document) == ["format", "version", "gnp", "settings", "nodes"]
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
    good = json.loads(save_controller(tmp_path / "c.json", GnpController(cfg, pop)).read_text())
    cases = {
        "not found": None,
        "is not JSON": "{oops",
        "not a gnp-lab controller": json.dumps({"hello": 1}),
        "version 7": json.dumps(dict(good, version=7)),
        "has 60 nodes": json.dumps(dict(good, nodes=good["nodes"][:-1])),
        "malformed controller": json.dumps(dict(good, nodes=[{"id": 0}] * len(good["nodes"]))),
        "malformed controller .KeyError: 'net'": json.dumps(
            dict(good, format="gnp-lab-neural-controller")
        ),
    }
    for needle, text in cases.items():
        path = tmp_path / "bad.json"
        path.unlink(missing_ok=True)
        if text is not None:
            path.write_text(text)
        with pytest.raises(ControllerFileError, match=needle) as caught:
            load_controller(path)
        assert "\n" not in str(caught.value)
    into_start = json.loads(json.dumps(good))
    into_start["nodes"][5]["sub_nodes"][0]["next"]["A"] = [0]  # no connection into the start
    (tmp_path / "bad.json").write_text(json.dumps(into_start))
    with pytest.raises(ControllerFileError, match="conn"):
        load_controller(tmp_path / "bad.json")
    with pytest.raises(ControllerFileError, match="one individual"):
        save_controller(tmp_path / "two.json", GnpController(cfg, gnp.concat([pop, pop])))


@pytest.mark.parametrize("net", [neuro.ElmanConfig(hidden=4), neuro.RecurrentConfig()])
def test_a_saved_net_loads_bit_identical_and_bad_files_are_named(
    tmp_path: Path, net: neuro.NetConfig
) -> None:
    rng = np.random.default_rng(5)
    arrays = neuro.zeros(net, 1)
    for name, a in arrays.items():
        a[...] = rng.integers(0, 2, a.shape) if name == "active" else rng.normal(0, 1, a.shape)
    first = next(iter(net.shapes()))  # w_in or weights, float64
    arrays[first][0, 0, 0] = 0.1 + 0.2  # a float with no short decimal form
    path = save_controller(tmp_path / "net.json", NetController(net, arrays, {"run": "x"}))
    document = json.loads(path.read_text())
    assert list(document) == ["format", "version", "net", "settings", "arrays"]
    loaded = load_controller(path)
    assert isinstance(loaded, NetController)
    assert loaded.net == net and loaded.settings == {"run": "x"}
    assert sorted(loaded.arrays) == sorted(arrays)
    assert all(np.array_equal(loaded.arrays[k], arrays[k]) for k in arrays)
    assert all(loaded.arrays[k].dtype == arrays[k].dtype for k in arrays)
    document["arrays"][first] = document["arrays"][first][:-1]  # one row short
    (tmp_path / "broken.json").write_text(json.dumps(document))
    with pytest.raises(ControllerFileError, match=f"{first} must be"):
        load_controller(tmp_path / "broken.json")
    with pytest.raises(ControllerFileError, match="one net"):
        two = {k: np.concatenate([a, a]) for k, a in arrays.items()}
        save_controller(tmp_path / "two.json", NetController(net, two))


@pytest.mark.parametrize("family", ["gnp", "net"])
@pytest.mark.parametrize("bad", [[1, 2], 5, "x", {}, None, [[]], {"a": 1}])
def test_a_document_of_the_wrong_shape_is_a_controller_file_error(
    tmp_path: Path, family: str, bad: object
) -> None:
    if family == "gnp":
        cfg, pop = _learned("BS")
        path = save_controller(tmp_path / "c.json", GnpController(cfg, pop))
    else:
        path = save_controller(tmp_path / "c.json", NetController(*_net()))
    good = json.loads(path.read_text())
    for key in ("gnp", "net", "settings", "nodes", "arrays"):
        if key in good and not (key == "settings" and isinstance(bad, dict)):  # any mapping
            (tmp_path / "bad.json").write_text(json.dumps(dict(good, **{key: bad})))
            # e.g. "arrays": [1, 2] met `.items()` (an AttributeError before)
            with pytest.raises(ControllerFileError, match=r"bad\.json"):
                load_controller(tmp_path / "bad.json")


def _net() -> tuple[neuro.NetConfig, dict[str, np.ndarray]]:
    net = neuro.ElmanConfig(hidden=2)
    return net, neuro.zeros(net, 1)
