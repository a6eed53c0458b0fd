"""The simplified graph (counting by hand, then drawn) and the second stage's live switch."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from page_helpers import dashboard_in_process

import gnp
import sim
from app.brains.gnp_brain import VISIT_CAPACITY, GnpFamily
from app.dashboard.status import set_value
from app.phases.live import LiveSession, RobotSpec
from app.views.graph_counts import FULL, SIMPLIFIED, edge_shades, graph_counts


def history(*nodes: int) -> np.ndarray:
    """A visit history (node, sub, branch, u, skipped) visiting `nodes` in order."""
    visits = np.zeros((len(nodes), 5), np.int64)
    visits[:, 0] = nodes
    return visits


def test_counts_by_hand() -> None:
    # start → 3 → 5 → 3 → 5 → 7, a new episode (start) → 3
    counts = graph_counts(history(0, 3, 5, 3, 5, 7, 0, 3), n_nodes=8, window=100)
    assert counts.window == 8
    assert counts.node_visits.tolist() == [2, 0, 0, 3, 0, 2, 0, 1]
    taken = dict(zip(map(tuple, counts.edges.tolist()), counts.edge_counts.tolist(), strict=True))
    # 7 → 0 is a new episode, not a connection.
    assert taken == {(0, 3): 2, (3, 5): 2, (5, 3): 1, (5, 7): 1}


def test_counts_only_the_window() -> None:
    counts = graph_counts(history(0, 1, 2, 1, 2, 4, 4), n_nodes=5, window=3)
    assert counts.window == 3
    assert counts.node_visits.tolist() == [0, 0, 1, 0, 2]
    assert counts.edges.tolist() == [[2, 4], [4, 4]]  # a self-loop is a transition too
    assert counts.edge_counts.tolist() == [1, 1]


def test_counts_of_short_and_bad_histories() -> None:
    empty = graph_counts(np.zeros((0, 5), np.int64), n_nodes=4)
    assert empty.node_visits.tolist() == [0, 0, 0, 0] and empty.edges.shape == (0, 2)
    single = graph_counts(history(0), n_nodes=4)
    assert single.node_visits.tolist() == [1, 0, 0, 0] and len(single.edge_counts) == 0
    with pytest.raises(ValueError, match="window"):
        graph_counts(history(0, 1), n_nodes=4, window=0)
    with pytest.raises(ValueError, match=r"0\.\.3"):
        graph_counts(history(0, 4), n_nodes=4)


def test_edge_shades_grow_with_use() -> None:
    shades = edge_shades(np.array([1, 3, 9]), (0, 0, 100), background=(200, 200, 200), faintest=0.1)
    assert shades[-1].tolist() == [0, 0, 100]  # the most taken: the full colour
    # strength 0.1 + 0.9 · count / 9: 0.2 and 0.4 of the way from the background
    assert shades[:2].tolist() == [[160, 160, 180], [120, 120, 160]]
    faint = edge_shades(np.array([1, 1]), (0, 0, 0), background=(200, 200, 200))
    assert faint.tolist() == [[0, 0, 0], [0, 0, 0]]  # all alike: all the full colour
    assert edge_shades(np.zeros(0), (0, 0, 0)).shape == (0, 3)


@pytest.fixture(scope="module")
def server() -> Iterator[object]:
    import viser

    served = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield served
    served.stop()


def live_robot(method: str, steps: int) -> LiveSession:
    cfg = gnp.GnpConfig(method=method)  # type: ignore[arg-type]
    population = gnp.init_population(cfg, 1, np.random.default_rng(4))
    session = LiveSession(
        sim.load_arena("training"), [RobotSpec("r", GnpFamily.of(cfg), population)]
    )
    session.step(steps)
    return session


def test_the_simplified_graph_draws_what_the_robot_runs(server: object) -> None:
    from app.views.genome import genome_view
    from app.views.graph_view import GraphView

    graph = GraphView(server, (0.0, -1.0), 1.0, 0.6)  # type: ignore[arg-type]
    session = live_robot("CS", 150)
    robot = session.robots[0]
    graph.set_genome(genome_view(robot.family.graph_config, robot.population))
    snapshot = session.snapshot()[0]
    graph.update(snapshot)
    full = graph.drawn()
    assert (full.mode, full.nodes) == (FULL, robot.family.graph_config.n_nodes)
    graph.set_mode(SIMPLIFIED)
    simple = graph.drawn()
    visited = np.flatnonzero(snapshot.node_visits)
    assert simple.nodes == len(visited) < full.nodes
    taken = graph_counts(snapshot.visits, robot.family.graph_config.n_nodes)
    assert simple.edges == len(taken.edges) < full.edges
    assert simple.segments < full.segments
    # Still marked: the current node (ringed), the last transition (the newest arrow).
    positions = graph._origin + graph.layout.positions  # type: ignore[union-attr]
    ring = graph._current.points.reshape(-1, 3)[:, :2]
    assert np.allclose(ring.mean(axis=0), positions[snapshot.current_node], atol=1e-3)
    last_from, last_to = snapshot.visits[-2, 0], snapshot.visits[-1, 0]
    shaft = graph._recent.points[-3]
    (dx, dy), (ex, ey) = shaft[1, :2] - shaft[0, :2], positions[last_to] - positions[last_from]
    assert abs(dx * ey - dy * ex) < 1e-4 and dx * ex + dy * ey >= 0  # along it, same way
    assert {last_from, last_to} <= set(graph._shown_nodes.tolist())
    # Only drawn nodes answer a click; the full view is one switch away.
    hidden = next(i for i in range(robot.family.graph_config.n_nodes) if i not in set(visited))
    assert graph.node_at(positions[hidden]) is None
    assert graph.node_at(positions[visited[-1]]) == visited[-1]
    graph.set_mode(FULL)
    assert graph.drawn() == full
    assert graph.node_at(positions[hidden]) == hidden


@pytest.fixture
def dashboard(tmp_path: Path) -> Iterator[object]:
    """A dashboard on an untrained random individual, its loop paused (the tests step it)."""
    with dashboard_in_process(tmp_path) as board:
        board.stage.playing = False
        yield board


def show_random(board: object, method: str) -> LiveSession:
    from app.dashboard.app import Dashboard

    assert isinstance(board, Dashboard)
    cfg = gnp.GnpConfig(method=method)  # type: ignore[arg-type]
    population = gnp.init_population(cfg, 1, np.random.default_rng(1))
    with board.lock:
        return board.stage.swap_in(
            f"random {method}", RobotSpec(method, GnpFamily.of(cfg), population)
        )


def switch_second_stage(board: object, on: bool) -> None:
    from app.dashboard.app import Dashboard

    assert isinstance(board, Dashboard)
    set_value(board.faults.second_stage, on)  # its callback applies it, as a click does
    assert board.stage.learning.second_stage is on
    assert board.stage.session is not None and board.stage.session.learning.second_stage is on
    assert ("second stage on" if on else "second stage off") in board.status.text


def visits_of(session: LiveSession, steps: int) -> np.ndarray:
    """The visits made in the next `steps` steps (20 at a time: fewer than the ring holds)."""
    rows = []
    for _ in range(steps // 20):
        before = int(session.robots[0].snapshot().node_visits.sum())
        session.step(20)
        after = session.robots[0].snapshot()
        new = int(after.node_visits.sum()) - before
        assert 0 < new <= len(after.visits) and new < VISIT_CAPACITY
        rows.append(after.visits[-new:])
    return np.concatenate(rows)


def test_second_stage_off_a_cs_robot_never_skips(dashboard: object) -> None:
    session = show_random(dashboard, "CS")
    on = visits_of(session, 400)
    assert on[:, 4].sum() > 0  # on: ε explores the credit branch now and then
    switch_second_stage(dashboard, False)
    q_cs = session.robots[0].population.q_cs.copy()
    off = visits_of(session, 400)
    assert len(off) > 400 and off[:, 4].sum() == 0  # off: never a credit skip
    np.testing.assert_array_equal(session.robots[0].population.q_cs, q_cs)  # Q_CS frozen
    switch_second_stage(dashboard, True)
    assert visits_of(session, 400)[:, 4].sum() > 0


def test_second_stage_off_a_bs_robot_takes_the_greedy_branch(dashboard: object) -> None:
    session = show_random(dashboard, "BS")
    population = session.robots[0].population

    def greedy(visits: np.ndarray) -> np.ndarray:
        rows = visits[visits[:, 0] > 0]
        node, sub, branch, u = rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3]
        return u == np.argmax(population.q_bs[0, node, sub, branch], axis=-1)

    on = visits_of(session, 400)
    assert not greedy(on).all()  # on: ε explores other branch connections
    switch_second_stage(dashboard, False)
    q_bs = population.q_bs.copy()
    off = visits_of(session, 400)
    assert greedy(off).all()  # Q_BS is frozen, so the greedy u of then is the greedy u of now
    np.testing.assert_array_equal(population.q_bs, q_bs)
    # The switch holds for the next show (a new life) too.
    assert show_random(dashboard, "BS").learning.second_stage is False


@pytest.mark.parametrize("method", ["BS", "CS"])
def test_rollout_carries_the_second_stage_switch(method: str) -> None:
    """Controllers with `second_stage` off step in `rollout` as `gnp.step` does with it off."""
    from app.brains.gnp_controllers import gnp_batch, gnp_of
    from app.loop.rollout import rollout

    cfg = gnp.GnpConfig(method=method)  # type: ignore[arg-type]
    arena = sim.load_arena("training")
    results = []
    for off_in_rollout in (True, False):
        population = gnp.init_population(cfg, 3, np.random.default_rng(2))
        world = sim.World(arena, n=3, seed=5)
        world.reset(arena.start_poses[:3])
        batch = gnp_batch(world, cfg, population, np.arange(3))
        gnp_of(batch).second_stage = False  # GNP's own switch, not the loop's
        if off_in_rollout:
            rollout(batch, 60, 0.2, 0.1)
        else:  # the same, step by step through gnp.step
            for _ in range(60):
                batch.step(0.2, 0.1)
        results.append((world.poses.copy(), population.q_ss.copy(), population.q_bs.copy()))
        # Off: the second stage's Q table never moves; Q_SS learns.
        fresh = gnp.init_population(cfg, 3, np.random.default_rng(2))
        np.testing.assert_array_equal(population.q_bs, fresh.q_bs)
        np.testing.assert_array_equal(population.q_cs, fresh.q_cs)
        assert not np.array_equal(population.q_ss, fresh.q_ss)
    for a, b in zip(*results, strict=True):
        np.testing.assert_array_equal(a, b)
