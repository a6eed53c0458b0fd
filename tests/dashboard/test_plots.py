"""The reward chart: one point per block of steps, hand-computed."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import viser

import gnp
import sim
from app.brains.gnp_brain import GnpFamily
from app.dashboard import plots
from app.phases.live import LiveSession, RobotSpec


def test_blocks_are_aligned_on_whole_multiples() -> None:
    # Steps 8..27 in blocks of 10: [8, 9], [10..19], [20..27].
    np.testing.assert_array_equal(plots.step_bins(np.arange(8, 28), 10), [0, 2, 12])
    np.testing.assert_array_equal(plots.step_bins(np.arange(0, 3), 10), [0])


def test_the_chart_gets_block_means_the_smooth_mean_and_the_broken_count() -> None:
    cfg = gnp.GnpConfig(method="RL")
    session = LiveSession(
        sim.load_arena("training"),
        [RobotSpec("r", GnpFamily.of(cfg), gnp.init_population(cfg, 1, np.random.default_rng(0)))],
    )
    steps = np.arange(8, 28)
    rewards = (steps % 2 == 0).astype(np.float64)  # 1 on even steps
    rewards[steps >= 20] = 1.0
    broken = np.where(steps >= 15, 2, 0)
    robot = dataclasses.replace(
        session.snapshot()[0], reward_steps=steps, rewards=rewards, broken_counts=broken
    )
    plot = SimpleNamespace(series=plots._reward_series(["r"]), data=None)
    plots.set_rewards(plot, [robot])  # type: ignore[arg-type]
    x, block, smooth, n_broken = plot.data
    np.testing.assert_array_equal(x, [9, 19, 27])  # each block's last step
    np.testing.assert_allclose(block, [0.5, 0.5, 1.0])
    # The trailing 50-step mean at each block's end: all the history so far.
    np.testing.assert_allclose(smooth, [1 / 2, 6 / 12, 14 / 20])
    np.testing.assert_array_equal(n_broken, [0, 2, 2])


def test_the_fitness_chart_shares_the_reward_charts_y_range_with_its_top_tick() -> None:
    """A fitness is a mean reward per step (Eq. 2.8): the fitness chart's y axis is the reward
    chart's, read from both handles, and it holds the 1.0 tick with room above it (uPlot puts
    ticks at multiples of the increment from 0, so 1.0 must be a multiple of each)."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        fitness, reward = plots.fitness_plot(server.gui), plots.reward_plot(server.gui)
        assert fitness.scales is not None and reward.scales is not None
        assert fitness.axes is not None and reward.axes is not None
        low, high = fitness.scales["y"]["range"]
        assert (low, high) == tuple(reward.scales["y"]["range"])
        assert fitness.axes[1] == reward.axes[1] and fitness.axes[1]["scale"] == "y"
        assert low <= 0.0 and high > 1.0  # every fitness, and the top tick not at the edge
        increments = fitness.axes[1]["incrs"]
        assert increments and all((1.0 / step).is_integer() for step in increments)
    finally:
        server.stop()
