"""`gnp-lab export`: a controller that steps as the run's, a readable graph, CSV tables that
round-trip, and bad input refused on one line with nothing overwritten."""

from __future__ import annotations

import csv
import json
import re
import shutil
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import gnp
from app.brains.gnp_file import GnpController
from app.brains.registry import family_of, load_controller
from app.cli import main
from app.export import ExportError, export_run
from app.export.graph import graph_dot, transition_counts, visit_sequence
from app.export.replay import CLIENT_BUILD, PLAY_RECORDING
from app.phases.implementation import implement
from app.settings.config import ImplementationSettings
from app.store import RunReader

EDGE = re.compile(r"^\s*n(\d+) -> n(\d+) \[(.*)\];$")
NODE = re.compile(r'^\s*n(\d+) \[label="([^"]*)"')


@pytest.fixture(scope="module")
def runs_dir(finished_run: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`tiny` (finished, with an implementation phase) and `unfinished` (1 of 3 generations)."""
    directory = tmp_path_factory.mktemp("export-runs")
    path = shutil.copy(finished_run, directory / "tiny.h5")
    with RunReader(path) as reader:
        settings: ImplementationSettings = reader.config.implementation
    implement(path, settings, name="fault")
    unfinished = directory / "unfinished.h5"
    shutil.copy(finished_run, unfinished)
    import h5py

    with h5py.File(unfinished, "r+") as handle:
        handle["progress/finished"][()] = 0
        handle["progress/generations_done"][()] = 1
    return directory


def _parse(text: str) -> tuple[dict[int, str], dict[tuple[int, int], str]]:
    nodes = {int(m[1]): m[2] for line in text.splitlines() if (m := NODE.match(line))}
    edges = {(int(m[1]), int(m[2])): m[3] for line in text.splitlines() if (m := EDGE.match(line))}
    return nodes, edges


DOT_LINES = (
    r"// .*",
    r"digraph gnp \{",
    r'  label="[^"]*"; labelloc=t; rankdir=LR; newrank=true;',
    r"  (node|edge) \[.*\];",
    r'  subgraph cluster_\d+ \{ label="[^"]+"; style=rounded; color=gray60;',
    r'    n\d+ \[label="[^"]*", fillcolor=\w+\];',
    r"  n\d+ -> n\d+ \[weight=\d+, .*\];",
    r"  \}",
    r"\}",
)


def _assert_dot_shape(text: str) -> None:
    """Every line is one of the forms graph.dot uses, and the braces balance (a DOT check that
    needs no GraphViz)."""
    for line in text.splitlines():
        assert any(re.fullmatch(form, line) for form in DOT_LINES), line
    assert text.count("{") == text.count("}")


def _weight(attrs: str) -> int:
    match = re.search(r"weight=(\d+)", attrs)
    assert match is not None
    return int(match[1])


def _best(reader: RunReader, generation: int) -> gnp.Population:
    return family_of(reader.config).best(reader, generation)


def _commands(cfg: gnp.GnpConfig, pop: gnp.Population) -> np.ndarray:
    state = gnp.init_state(cfg, 1, [4])
    rng = np.random.default_rng(11)
    return np.array(
        [
            gnp.step(cfg, pop, state, rng.uniform(0, 1023, (1, 8)), rng.uniform(0, 1, 1), 0.1, 0.2)[
                0
            ]
            for _ in range(300)
        ]
    )


def test_export_writes_every_file_and_the_controller_steps_as_the_run(
    runs_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "export"
    assert main(["export", "tiny", "--out", str(out), "--runs-dir", str(runs_dir)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "controller.json",
        "fitness.csv",
        "graph.dot",
        "implementation-fault.csv",
    ]
    assert str(out) in capsys.readouterr().out
    controller = load_controller(out / "controller.json")
    assert isinstance(controller, GnpController)
    cfg, loaded, settings = controller.cfg, controller.individual, controller.settings
    with RunReader(runs_dir / "tiny.h5") as reader:
        run_cfg, best = reader.config.brain.controller.gnp_config(), _best(reader, 2)
        control_period = reader.config.training.control_period
    assert cfg == run_cfg
    assert settings["generation"] == 2 and settings["run"] == "tiny"
    assert settings["control_period"] == control_period and settings["method"] == cfg.method
    assert np.array_equal(_commands(cfg, loaded), _commands(run_cfg, best))


def test_an_earlier_generation_exports_its_best_with_zero_weights(
    runs_dir: Path, tmp_path: Path
) -> None:
    out = export_run(runs_dir / "tiny.h5", tmp_path / "g0", generation=0)
    document = json.loads((out / "controller.json").read_text())
    assert document["settings"]["generation"] == 0
    with RunReader(runs_dir / "tiny.h5") as reader:
        cfg, best = reader.config.brain.controller.gnp_config(), _best(reader, 0)
    controller = load_controller(out / "controller.json")
    assert isinstance(controller, GnpController)
    loaded = controller.individual
    assert np.array_equal(_commands(cfg, loaded), _commands(cfg, best))
    text = (out / "graph.dot").read_text()
    _assert_dot_shape(text)
    assert "no recorded life" in text
    _, edges = _parse(text)
    assert edges and all(_weight(attrs) == 0 for attrs in edges.values())


def test_the_graph_of_the_final_elite_counts_its_recorded_transitions(
    runs_dir: Path, tmp_path: Path
) -> None:
    out = export_run(runs_dir / "tiny.h5", tmp_path / "final")
    nodes, edges = _parse((out / "graph.dot").read_text())
    with RunReader(runs_dir / "tiny.h5") as reader:
        cfg = reader.config.brain.controller.gnp_config()
        elite = reader.elite()
    assert elite is not None
    assert sorted(nodes) == list(range(cfg.n_nodes))
    visits = visit_sequence(elite.trace["node"][0], elite.trace["count"][0])
    taken = Counter(
        (a, b) for a, b in zip(visits[:-1].tolist(), visits[1:].tolist(), strict=True) if b
    )
    assert taken and set(taken) <= set(edges)  # every transition taken is a connection
    assert {e: _weight(a) for e, a in edges.items() if _weight(a)} == dict(taken)


def test_a_tiny_graph_counted_by_hand() -> None:
    # 1 judgment and 2 processing nodes, 1 sub node, RL: nodes 0 (start), 1 (J), 2, 3 (P).
    cfg = gnp.GnpConfig(method="RL", n_judgment=1, n_processing=2, n_sub=1)
    pop = gnp.init_population(cfg, 1, np.random.default_rng(0))
    pop.conn[0, 0, 0, 0, 0] = 1  # start -> J1
    pop.conn[0, 1, 0, 0, 0] = 2  # J1 A -> P2
    pop.conn[0, 1, 0, 1, 0] = 3  # J1 B -> P3
    pop.conn[0, 2, 0, 0, 0] = 1  # P2 -> J1
    pop.conn[0, 3, 0, 0, 0] = 1  # P3 -> J1
    pop.function[0, 1, 0], pop.mu_beta[0, 1, 0], pop.mu_alpha[0, 1, 0] = 2, 100, 600
    pop.function[0, 2, 0], pop.speed[0, 2, 0] = 0, 7
    pop.function[0, 3, 0], pop.speed[0, 3, 0] = 1, -3
    gnp.check_population(cfg, pop)
    # Three steps: start J1 P2 | J1 P3 | J1 P2, then a new episode: start J1 P3.
    node = np.array([[0, 1, 2, -1], [1, 3, -1, -1], [1, 2, -1, -1], [0, 1, 3, -1]], np.int32)
    count = np.array([3, 2, 2, 3])
    taken = transition_counts(node, count)
    # 0 1 2 1 3 1 2 | 0 1 3: the move back to the start is a new episode, not counted.
    assert taken == Counter({(0, 1): 2, (1, 2): 2, (2, 1): 1, (1, 3): 2, (3, 1): 1})
    nodes, edges = _parse(graph_dot(cfg, pop, taken, "tiny"))
    assert len(nodes) == 4 and len(edges) == 5
    assert nodes[1] == "J1\\ns2 100..600" and nodes[2] == "P2\\nP0 right +7"
    assert nodes[3] == "P3\\nP1 left -3" and nodes[0] == "start"
    assert {e: _weight(a) for e, a in edges.items()} == dict(taken)
    assert "penwidth=5.00" in edges[(1, 2)] and "penwidth=3.00" in edges[(3, 1)]
    text = graph_dot(cfg, pop, taken, "tiny")
    _assert_dot_shape(text)
    # Clusters as the dashboard's columns: start, sensor s2, wheels P0 and P1.
    assert re.findall(r'subgraph cluster_\d+ \{ label="([^"]+)"', text) == [
        "start",
        "s2",
        "P0 right",
        "P1 left",
    ]


def test_the_tables_round_trip_to_the_run_file(runs_dir: Path, tmp_path: Path) -> None:
    out = export_run(runs_dir / "tiny.h5", tmp_path / "tables")
    with RunReader(runs_dir / "tiny.h5") as reader:
        history = reader.history()
        reward = reader.implementation("fault").reward_per_step
    with (out / "fitness.csv").open(newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == [
        "generation",
        "best_fitness",
        "mean_fitness",
        "std_fitness",
        "epsilon",
        "alpha",
    ]
    table = np.array([[float(v) for v in row] for row in rows[1:]])
    assert np.array_equal(table[:, 0], np.arange(3))
    for column, values in enumerate(
        (
            history.best_fitness,
            history.mean_fitness,
            history.std_fitness,
            history.epsilon,
            history.alpha,
        ),
        start=1,
    ):
        assert np.array_equal(table[:, column], values)
    with (out / "implementation-fault.csv").open(newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["step", "reward_per_step"]
    assert [int(r[0]) for r in rows[1:]] == list(range(len(reward)))
    assert np.array_equal([float(r[1]) for r in rows[1:]], reward)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["nope"], "no run named 'nope'"),
        (["tiny", "--generation", "3"], "has no generation 3 (generations 0..2)"),
        (["unfinished"], "has not finished training (1 of 3 generations)"),
        (["tiny", "--replay", "--generation", "0"], "only the final elite's life"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    runs_dir: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    argv: list[str],
    message: str,
) -> None:
    out = tmp_path / "out"
    status = main(["export", *argv, "--out", str(out), "--runs-dir", str(runs_dir)])
    err = capsys.readouterr().err
    assert status != 0
    assert err.startswith("gnp-lab: error: ") and err.count("\n") == 1 and message in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_an_existing_folder_is_never_overwritten(
    runs_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    for extra in ([], ["--replay"]):
        assert main(["export", "tiny", "--out", str(out), "--runs-dir", str(runs_dir), *extra]) == 1
        err = capsys.readouterr().err
        assert err == f"gnp-lab: error: {out} exists and is not empty; nothing was written\n"
    assert [p.name for p in out.iterdir()] == ["mine.txt"] and (
        out / "mine.txt"
    ).read_text() == "keep"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no staging folder left
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["export", "tiny", "--out", str(empty), "--runs-dir", str(runs_dir)]) == 0
    assert (empty / "controller.json").is_file()
    with pytest.raises(ExportError, match="not a folder"):
        export_run(runs_dir / "tiny.h5", out / "mine.txt")


def _recording(path: Path) -> tuple[dict[str, object], bytes]:
    """The metadata and msgpack payload of a .viser recording (zstd: inner size, then
    msgpack length, msgpack, binary buffers)."""
    import msgspec
    import zstandard

    data = path.read_bytes()
    inner = zstandard.ZstdDecompressor().decompress(
        data[8:], max_output_size=int.from_bytes(data[:8], "little")
    )
    length = int.from_bytes(inner[:8], "little")
    payload = inner[8 : 8 + length]
    return msgspec.msgpack.decode(payload), payload


def test_the_replay_folder_holds_the_client_and_a_recording_of_both_lives(
    runs_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "replay"
    argv = ["export", "tiny", "--replay", "--out", str(out), "--runs-dir", str(runs_dir)]
    assert main(argv) == 0
    assert capsys.readouterr().out == f"{out}: README.txt, index.html, replay.viser\n"
    index = (out / "index.html").read_text()
    client = (CLIENT_BUILD / "index.html").read_text()
    assert index.replace(PLAY_RECORDING, "") == client  # viser's own client, told what to play
    assert "playbackPath=replay.viser" in PLAY_RECORDING
    assert (out / "replay.viser").stat().st_size < 5_000_000
    meta, payload = _recording(out / "replay.viser")
    with RunReader(runs_dir / "tiny.h5") as reader:
        period = reader.config.training.control_period
    # The elite's 60 steps, then the implementation trial's 120, at the recorded pace.
    assert meta["durationSeconds"] == pytest.approx((60 + 120) * period)
    assert b"run tiny: final elite (generation 2)" in payload
    assert b"step 60/60" in payload and b"step 120/120" in payload
    assert b"implementation fault, trial 0" in payload
    assert b"sensors 2,3 broken (dead) since step 60" in payload
