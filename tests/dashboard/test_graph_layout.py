"""Graph layout, scene geometry and plot helpers: pure functions with hand-computed answers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import gnp
from app.dashboard.plots import block_mean, moving_mean
from app.views import geometry as geo
from app.views.graph_layout import GraphLayoutError, graph_layout
from app.views.graph_view import (
    BRANCH_SWITCH,
    CREDIT_SKIP,
    NORMAL,
    describe_visit,
    transition_kinds,
)
from gnp.config import JUDGMENT, PROCESSING, START


def test_columns_follow_sensor_and_wheel() -> None:
    kinds = gnp.GnpConfig(n_judgment=3, n_processing=2).node_type  # start, J, J, J, P, P
    functions = np.array([0, 5, 5, 1, 0, 1])
    layout = graph_layout(kinds, functions, width=2.0, height=1.0)
    assert layout.column_names[0] == "start" and layout.column_names[6] == "s5"
    assert layout.column_names[-2:] == ("P0 right", "P1 left")
    np.testing.assert_array_equal(layout.column_of, [0, 6, 6, 2, 9, 10])
    x = layout.positions[:, 0]
    assert x[0] == 0.0 and x[-1] == 2.0  # start at the left edge, P1 at the right edge
    assert x[1] == x[2] == layout.column_x[6]
    # Two nodes in a column sit at 3/4 and 1/4 of the height, in node order.
    np.testing.assert_allclose(layout.positions[[1, 2], 1], [0.75, 0.25])
    assert layout.positions[0, 1] == 0.5  # a lone node is centred


@settings(max_examples=60, deadline=None)
@given(
    n_judgment=st.integers(1, 60),
    n_processing=st.integers(1, 30),
    seed=st.integers(0, 2**32 - 1),
)
def test_every_node_gets_its_own_place_inside_the_box(
    n_judgment: int, n_processing: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    kinds = gnp.GnpConfig(n_judgment=n_judgment, n_processing=n_processing).node_type
    functions = np.where(
        kinds == JUDGMENT, rng.integers(0, 8, kinds.size), rng.integers(0, 2, kinds.size)
    )
    functions[kinds == START] = 0
    layout = graph_layout(kinds, functions, width=1.3, height=0.7)
    p = layout.positions
    assert np.all((p >= 0) & (p <= [1.3, 0.7]))
    assert len(np.unique(np.round(p, 9), axis=0)) == kinds.size
    # Judgment columns lie strictly between the start and the processing columns.
    assert p[kinds == JUDGMENT, 0].min() > p[0, 0]
    assert p[kinds == JUDGMENT, 0].max() < p[kinds == PROCESSING, 0].min()


@pytest.mark.parametrize(
    ("kinds", "functions", "message"),
    [
        ([0, 1], [0], "equal 1-D shapes"),
        ([1, 1], [0, 0], "exactly one start node"),
        ([0, 1, 7], [0, 0, 0], "unknown node kind"),
        ([0, 1], [0, 8], "sensor must be in 0..7"),
        ([0, 2], [0, 2], "wheel must be 0"),
    ],
)
def test_inconsistent_graphs_are_refused(
    kinds: list[int], functions: list[int], message: str
) -> None:
    with pytest.raises(GraphLayoutError, match=message):
        graph_layout(np.array(kinds), np.array(functions))


def test_arrow_is_a_shaft_and_two_head_strokes_at_the_tip() -> None:
    arrows = geo.arrow_segments(np.array([[0.0, 0.0]]), np.array([[2.0, 0.0]]), head=0.5)
    assert arrows.shape == (3, 2, 3)
    np.testing.assert_allclose(arrows[0], [[0, 0, 0], [2, 0, 0]])
    for stroke in arrows[1:]:
        np.testing.assert_allclose(stroke[0], [2, 0, 0])
        np.testing.assert_allclose(np.linalg.norm(stroke[1] - stroke[0]), 0.5)
        assert stroke[1, 0] < 2.0  # heads point back along the shaft
    # The two strokes mirror each other about the shaft.
    np.testing.assert_allclose(arrows[1, 1, 1], -arrows[2, 1, 1])
    shortened = geo.arrow_segments(np.array([[0.0, 0.0]]), np.array([[2.0, 0.0]]), 0.5, 0.25)
    np.testing.assert_allclose(shortened[0, :, 0], [0.25, 1.75])


def test_circle_is_closed_and_on_the_radius() -> None:
    ring = geo.circle_segments(np.array([[1.0, 2.0]]), 0.5, n_sides=12)
    assert ring.shape == (12, 2, 3)
    np.testing.assert_allclose(ring[0, 0], ring[-1, 1], atol=1e-12)
    np.testing.assert_allclose(ring[:, 1, 0], ring[np.r_[1:12, 0], 0, 0], atol=1e-12)
    radii = np.linalg.norm(ring[:, :, :2] - [1.0, 2.0], axis=-1)
    np.testing.assert_allclose(radii, 0.5)


def test_reward_colours_run_red_amber_green_and_clip() -> None:
    colors = geo.reward_colors(np.array([-1.0, 0.0, 0.5, 1.0, 3.0]))
    np.testing.assert_array_equal(colors[0], colors[1])
    np.testing.assert_array_equal(colors[1], [200, 40, 40])
    np.testing.assert_array_equal(colors[2], [235, 190, 40])
    np.testing.assert_array_equal(colors[3], [40, 170, 60])
    np.testing.assert_array_equal(colors[3], colors[4])


@settings(max_examples=50, deadline=None)
@given(
    values=st.lists(st.floats(-1, 1), min_size=1, max_size=80),
    window=st.integers(1, 30),
)
def test_moving_mean_matches_a_plain_loop(values: list[float], window: int) -> None:
    expected = [np.mean(values[max(0, i + 1 - window) : i + 1]) for i in range(len(values))]
    np.testing.assert_allclose(moving_mean(np.array(values), window), expected, atol=1e-9)


def test_block_mean_keeps_at_most_max_points() -> None:
    x, y = block_mean(np.arange(10.0), 4)  # blocks of 3: [0,1,2] [3,4,5] [6,7,8] [9]
    np.testing.assert_array_equal(x, [0, 3, 6, 9])
    np.testing.assert_allclose(y, [1, 4, 7, 9])
    x, y = block_mean(np.ones(3000), 600)
    assert len(x) == 600 and np.all(y == 1)


def test_transition_kinds() -> None:
    # rows: node, sub, branch, u, skipped
    visits = np.array(
        [
            [0, 0, 0, 0, 0],
            [5, 1, 0, 0, 0],  # normal 0 -> 5
            [9, 0, 1, 1, 0],  # 5 -> 9 normal; 9 leaves through branch connection u = 1
            [12, 0, 0, 0, 0],  # 9 -> 12: BS switch
            [20, 1, -1, -1, 1],  # 12 -> 20: 20 credit-skipped
            [3, 0, 0, 0, 0],  # 20 -> 3: leaving a skipped node
        ]
    )
    kinds = transition_kinds(visits[:-1], visits[1:])
    np.testing.assert_array_equal(kinds, [NORMAL, NORMAL, BRANCH_SWITCH, CREDIT_SKIP, CREDIT_SKIP])


def test_visits_in_words() -> None:
    assert describe_visit(np.array([0, 0, 0, 0, 0]), START) == "start node"
    assert describe_visit(np.array([7, 1, 1, 0, 0]), JUDGMENT) == "node 7: sub node 1, branch B"
    assert (
        describe_visit(np.array([7, 0, 0, 1, 0]), JUDGMENT)
        == "node 7: sub node 0, branch A, branch connection u = 1"
    )
    assert describe_visit(np.array([50, 1, 0, 0, 0]), PROCESSING) == "node 50: sub node 1"
    assert describe_visit(np.array([9, 0, -1, -1, 1]), JUDGMENT).endswith("credit branch")
    assert describe_visit(np.array([7, 0, 2, 0, 0]), JUDGMENT).endswith("branch C")


def test_a_judgment_node_with_k_branches_shows_every_branch() -> None:
    from app.views.genome import genome_view, node_markdown

    cfg = gnp.GnpConfig(
        method="BS", fuzzy=False, judgment_branches=3, n_judgment=2, n_processing=2
    )  # fmt: skip
    pop = gnp.init_population(cfg, 1, np.random.default_rng(0))
    pop.conn[0, 1, 0, 2] = 4  # branch C of node 1's sub node 0 into node 4
    text = node_markdown(cfg, pop, 1)
    assert "| → A | → B | → C |" in text and "Q_BS A / B / C (per u)" in text
    row = text.splitlines()[4]
    assert row.count("|") == text.splitlines()[2].count("|")  # a cell per column
    assert "| 4,4 |" in row
    assert (1, 4) in {tuple(e) for e in genome_view(cfg, pop).edges.tolist()}
