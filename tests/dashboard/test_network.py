"""A neural controller in the dashboard: its network's layout and colours, its live activations,
a neural run on the stage and in an implementation phase (no browser)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import neuro
import sim
from app import store
from app.brains.nets import NetFamily
from app.brains.registry import family_of
from app.dashboard.implementation_job import ImplementationRequest, implement_run
from app.dashboard.network import (
    CONTEXT,
    HIDDEN,
    INPUT,
    NEGATIVE,
    NEUTRAL,
    OUTPUT,
    POSITIVE,
    activation_colors,
    describe_layers,
    network_layout,
    node_values,
    weight_colors,
)
from app.dashboard.stage import Show, Stage, run_robot
from app.dashboard.tab_faults import second_stage_words
from app.dashboard.tab_plots import show_line
from app.dashboard.tab_runs import runs_table
from app.phases.implementation import run_implementation
from app.phases.live import LiveSession, RobotSpec


def elman(hidden: int, seed: int = 0) -> tuple[neuro.ElmanConfig, dict[str, np.ndarray]]:
    cfg = neuro.ElmanConfig(hidden=hidden)
    flat = np.random.default_rng(seed).normal(size=(1, cfg.n_params))
    return cfg, neuro.from_flat(cfg, flat)


def neat_net() -> tuple[neuro.RecurrentConfig, dict[str, np.ndarray]]:
    """Units 0 left, 1 right, slot 3 a hidden node (slots 2 and 4 unused):
    s0 → left 0.5, unit 3 → left −1.0, s7 → right 2.0, left → right −0.2,
    s3 → unit 3 0.3, unit 3 → unit 3 0.7."""
    cfg = neuro.RecurrentConfig(max_hidden=3)
    arrays = neuro.zeros(cfg, 1)
    w, n_in = arrays["weights"][0], neuro.N_INPUTS
    w[0, 0], w[0, n_in + 3], w[1, 7], w[1, n_in + 0] = 0.5, -1.0, 2.0, -0.2
    w[3, 3], w[3, n_in + 3] = 0.3, 0.7
    arrays["active"][0, [0, 1, 3]] = 1
    arrays["response"][0] = 1.0
    return cfg, arrays


def drawn_edges(
    cfg: neuro.NetConfig, arrays: dict[str, np.ndarray]
) -> dict[tuple[str, str], float]:
    layout = network_layout(cfg, arrays)
    return {
        (layout.names[a], layout.names[b]): float(w)
        for (a, b), w in zip(layout.edges, layout.weights, strict=True)
    }


def test_an_elman_net_draws_every_weight_from_input_and_context_to_hidden_to_wheels() -> None:
    cfg, arrays = elman(hidden=2)
    expected = {}
    for j in range(2):
        for i in range(8):
            expected[(f"s{i}", f"h{j}")] = arrays["w_in"][0, j, i]
        for k in range(2):
            expected[(f"h{k}(t−1)", f"h{j}")] = arrays["w_rec"][0, j, k]
        for o, wheel in enumerate(("left", "right")):
            expected[(f"h{j}", wheel)] = arrays["w_out"][0, o, j]
    assert drawn_edges(cfg, arrays) == expected  # 16 + 4 + 4 weights; biases are not edges

    layout = network_layout(cfg, arrays, width=2.0, height=1.0)
    assert [layout.count(k) for k in (INPUT, CONTEXT, HIDDEN, OUTPUT)] == [8, 2, 2, 2]
    assert describe_layers(layout) == (
        "Elman · 8 IR in · 2 context t−1 · 2 hidden · 2 wheels · 24 weights"
    )
    x, y = layout.positions.T
    column = {INPUT: 0.0, CONTEXT: 0.0, HIDDEN: 1.1, OUTPUT: 2.0}
    assert np.array_equal(x, [column[int(k)] for k in layout.kinds])
    assert y[layout.kinds == INPUT].min() > y[layout.kinds == CONTEXT].max()  # inputs on top
    assert np.all((y > 0.0) & (y < 1.0))
    strength = np.abs(layout.weights)
    assert np.all(np.diff(strength) >= 0.0)  # the strongest are drawn last, on top


def test_a_neat_net_draws_its_used_units_and_its_nonzero_weights_only() -> None:
    cfg, arrays = neat_net()
    assert drawn_edges(cfg, arrays) == {
        ("s0", "left"): 0.5,
        ("h1(t−1)", "left"): -1.0,
        ("s7", "right"): 2.0,
        ("left(t−1)", "right"): -0.2,
        ("s3", "h1"): 0.3,
        ("h1(t−1)", "h1"): 0.7,
    }
    layout = network_layout(cfg, arrays)
    assert layout.names[8:] == ("left(t−1)", "h1(t−1)", "h1", "left", "right")
    assert layout.index[8:].tolist() == [0, 3, 3, 0, 1]
    assert layout.weights.tolist() == [-0.2, 0.3, 0.5, 0.7, -1.0, 2.0]


def test_what_each_node_holds_after_a_step() -> None:
    layout = network_layout(*neat_net())
    readings = np.zeros(8)
    readings[0], readings[7] = 0.5 * sim.IR_MAX, 2000.0  # noise may push a reading past the top
    values = node_values(
        layout,
        activation=np.array([0.1, -0.4, 0.0, 0.9, 0.0]),
        context=np.array([0.2, 0.0, 0.0, -0.6, 0.0]),
        readings=readings,
        commands=np.array([1.0, -4.0]),
    )
    assert values.tolist() == [0.5, 0, 0, 0, 0, 0, 0, 1.0, 0.2, -0.6, 0.9, 0.1, -0.4]


def test_colours_by_sign_and_size() -> None:
    colors = activation_colors(np.array([-1.0, 0.0, 0.25, 3.0]))
    assert colors.tolist() == [list(NEGATIVE), list(NEUTRAL), [231, 197, 185], list(POSITIVE)]
    # |w| over the largest |w|, from 10% of the way from white (a weight of 0 is never drawn).
    assert weight_colors(np.array([2.0, -1.0])).tolist() == [list(POSITIVE), [131, 170, 233]]
    assert weight_colors(np.zeros(0)).shape == (0, 3)


@settings(max_examples=25, deadline=None)
@given(hidden=st.integers(1, 6), seed=st.integers(0, 2**16), zeroed=st.floats(0.0, 0.9))
def test_every_edge_runs_left_to_right_and_every_nonzero_weight_is_one(
    hidden: int, seed: int, zeroed: float
) -> None:
    cfg, arrays = elman(hidden, seed)
    rng = np.random.default_rng(seed + 1)
    for name in ("w_in", "w_rec", "w_out"):
        arrays[name][rng.random(arrays[name].shape) < zeroed] = 0.0
    layout = network_layout(cfg, arrays)
    source, target = layout.positions[layout.edges[:, 0]], layout.positions[layout.edges[:, 1]]
    assert np.all(source[:, 0] < target[:, 0])
    nonzero = sum(np.count_nonzero(arrays[n]) for n in ("w_in", "w_rec", "w_out"))
    assert len(layout.weights) == nonzero and np.all(layout.weights != 0.0)
    assert len({tuple(p) for p in layout.positions.round(9)}) == len(layout.positions)


@pytest.mark.parametrize("which", ["elman", "neat"])
def test_a_live_net_shows_the_values_its_net_computed(which: str) -> None:
    cfg, arrays = elman(3, seed=5) if which == "elman" else neat_net()
    kept = {k: v.copy() for k, v in arrays.items()}
    session = LiveSession(
        sim.load_arena("training"), [RobotSpec("net", NetFamily.of(cfg), arrays)], seed=2
    )
    state = neuro.init_state(cfg, 1)
    for _ in range(25):
        session.step(1)
        robot = session.snapshot()[0]
        before = state.copy()
        outputs = neuro.step(cfg, arrays, state, robot.seen_readings[None] / sim.IR_MAX)
        np.testing.assert_array_equal(robot.context, before[0])
        np.testing.assert_array_equal(robot.activation, state[0])
        np.testing.assert_array_equal(robot.commands, outputs[0] * sim.MAX_COMMAND)
    assert robot.method == ("Elman" if which == "elman" else "NEAT") and robot.t == 25
    assert len(robot.visits) == 0 and len(robot.node_visits) == 0  # no GNP nodes
    for name, values in kept.items():
        np.testing.assert_array_equal(arrays[name], values)
    line = show_line([robot], 0.0)
    left, right = robot.commands
    assert f"wheels {left:+.1f} {right:+.1f} · no online learning" in line
    assert "node" not in line and "ε" not in line


@pytest.fixture(scope="module")
def net(net_runs_dir: Path) -> Iterator[RobotSpec]:
    with store.RunReader(net_runs_dir / "elman.h5") as reader:
        yield run_robot(reader)


def test_a_neural_runs_best_goes_on_stage_in_either_arena(
    net_runs_dir: Path, net: RobotSpec
) -> None:
    with store.RunReader(net_runs_dir / "elman.h5") as reader:
        stored = reader.best_genome_arrays(-1)
        first = run_robot(reader, 0)
    assert (net.label, net.family.network_config) == ("elman", neuro.ElmanConfig(hidden=6))
    assert isinstance(net.population, dict) and isinstance(first.population, dict)
    for name, values in stored.items():
        np.testing.assert_array_equal(net.population[name], values)
    assert not np.array_equal(net.population["w_in"], first.population["w_in"])
    stage = Stage()
    for arena in sim.ARENA_NAMES:
        session = stage.present(Show("net", (net,), arena, 4, life=150))
        np.testing.assert_array_equal(
            session.robots[0].world.poses[0, :2], stage.arenas[arena].start_poses[4, :2]
        )
        stage.speed = 100.0
        assert stage.advance(0.2) == 20 and session.snapshot()[0].t == 20
    assert "does not learn online has no second stage" in second_stage_words(stage, on=False)
    assert "does not learn online has no second stage" in second_stage_words(stage, on=True)


def test_a_neural_runs_implementation_phase_runs_its_last_best(net_runs_dir: Path) -> None:
    path = net_runs_dir / "elman.h5"
    request = ImplementationRequest(path, (2, 3), "dead", 40, 80, 1, "changing")
    result = implement_run(request)
    with store.RunReader(path) as reader:
        config = reader.config
        family = family_of(config)
        expected = run_implementation(
            family,
            family.best(reader),
            request.settings(config.implementation),
            seed=config.seed,
            control_period=config.training.control_period,
            name="dashboard",
            generation=1,
        )
        summaries = store.list_runs(net_runs_dir)
    assert len(result.trial_mean_reward) == sim.N_START_POSES
    assert result.settings.broken_sensors == (2, 3) and result.settings.fault_step == 40
    np.testing.assert_array_equal(result.reward_per_step, expected.reward_per_step)
    table = runs_table(summaries, net_runs_dir)
    assert "| elman | cmaes: Elman net, 6 hidden | 2/2 |" in table


def test_the_network_view_draws_the_weights_and_recolours_the_nodes_live() -> None:
    import viser

    from app.dashboard.network_view import NetworkView

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        view = NetworkView(server, (0.0, -1.0), 2.0, 1.0)
        assert not view.visible and view.drawn().nodes == 0  # hidden until a net is shown
        cfg, arrays = elman(3, seed=9)
        view.set_network(cfg, arrays)
        layout = view.layout
        assert layout is not None
        drawn = view.drawn()
        assert (drawn.nodes, drawn.weights, drawn.segments) == (8 + 3 + 3 + 2, 8 * 3 + 9 + 6, 39)
        # Each segment lies on its edge, rim to rim, in its weight's colour.
        points = view._edges.points[:, :, :2]
        ends = np.array([0.0, -1.0]) + layout.positions[layout.edges]
        along = (ends[:, 1] - ends[:, 0]) / np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)[:, None]
        np.testing.assert_allclose(points[:, 0], ends[:, 0] + 0.025 * along, atol=1e-6)
        np.testing.assert_allclose(points[:, 1], ends[:, 1] - 0.025 * along, atol=1e-6)
        assert np.array_equal(view._edges.colors[:, 0], weight_colors(layout.weights))
        assert np.all(view.node_colors == NEUTRAL)  # nothing computed yet

        session = LiveSession(
            sim.load_arena("training"), [RobotSpec("net", NetFamily.of(cfg), arrays)]
        )
        session.step(30)
        robot = session.snapshot()[0]
        view.update(robot)
        values = node_values(
            layout, robot.activation, robot.context, robot.seen_readings, robot.commands
        )
        assert np.array_equal(view.node_colors, activation_colors(values))
        assert np.array_equal(view._nodes.batched_colors, view.node_colors)
        assert not np.all(view.node_colors == NEUTRAL)
    finally:
        server.stop()


def test_a_net_of_a_tasks_sizes_draws_its_own_inputs_and_outputs() -> None:
    """A net of other sizes than the robot's (a Gymnasium task's: 4 features, 3 actions) is
    laid out from its config's widths, its outputs named y0.. instead of wheels."""
    cfg = neuro.ElmanConfig(hidden=2, n_inputs=4, n_outputs=3)
    arrays = neuro.from_flat(cfg, np.random.default_rng(1).normal(size=(1, cfg.n_params)))
    layout = network_layout(cfg, arrays)
    assert [layout.count(k) for k in (INPUT, CONTEXT, HIDDEN, OUTPUT)] == [4, 2, 2, 3]
    assert layout.names[-3:] == ("y0", "y1", "y2")
    edges = drawn_edges(cfg, arrays)
    assert edges[("s3", "h1")] == arrays["w_in"][0, 1, 3]
    assert edges[("h0", "y2")] == arrays["w_out"][0, 2, 0]
    assert len(edges) == 2 * 4 + 2 * 2 + 3 * 2
