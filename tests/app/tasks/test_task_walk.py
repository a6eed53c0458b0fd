"""`app.tasks.walk`: a task run's elite seen from inside its graph (issue #45)."""

from __future__ import annotations

from pathlib import Path

import pytest

import gnp
from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.tasks.common import TestProtocol
from app.tasks.config import TaskRunConfig, TaskSettings, TaskTraining
from app.tasks.store import read_task_run
from app.tasks.training import protocol_episodes, train_task
from app.tasks.walk import walk_episode, walk_individual

SEEDS = (1_000_000, 1_000_001, 1_000_002)
CAP = 80


@pytest.fixture(scope="module")
def cs_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    config = TaskRunConfig(
        seed=7,
        task=TaskSettings(id="MountainCar-v0"),
        brain=GnpSettings(
            controller=ControllerSettings(
                method="CS", fuzzy=True, n_judgment=8, n_processing=4, skip_reward="step"
            )
        ),
        training=TaskTraining(
            population=6, generations=2, steps=CAP, epsilon=gnp.Schedule.fixed(0.1)
        ),
    )
    return train_task(config, tmp_path_factory.mktemp("walk") / "cs.h5")


@pytest.mark.parametrize("protocol", ["greedy", "as-trained"])
def test_a_walk_lives_the_episode_the_replay_lives(cs_run: Path, protocol: TestProtocol) -> None:
    replay = protocol_episodes(cs_run, SEEDS, None, protocol)
    for i, seed in enumerate(SEEDS):
        walk = walk_episode(cs_run, seed, protocol)
        assert walk.episode_return == replay.returns[i]
        assert walk.steps == replay.lengths[i]
        assert sum(walk.actions.values()) == walk.steps
        assert 0 <= walk.acting_steps <= walk.steps
        assert 0 <= walk.skips <= walk.visits


@pytest.mark.parametrize("skip", [True, False])
def test_a_walk_counts_skips_and_the_steps_that_act(cs_run: Path, skip: bool) -> None:
    """Hand-computed: an elite whose every node prefers its credit branch (greedy) skips five
    nodes a step (one time unit each), runs no processing node, and keeps output 0 at 0, the
    middle of MountainCar's three actions (1, no push) for the whole capped episode; one that
    never prefers it skips nothing."""
    run = read_task_run(cs_run)
    cfg, elite = run.best_genome()
    elite.q_cs[..., 1] = 100.0 if skip else -100.0
    elite.q_cs[..., 0] = 0.0
    walk = walk_individual(run.config, cfg, elite, SEEDS[0], 0.0, 0.0, learn=False)
    if skip:
        assert walk.skips == walk.visits == 5 * CAP
        assert walk.acting_steps == 0
        assert walk.actions == {1: CAP} and walk.episode_return == -CAP
    else:
        assert walk.skips == 0 and walk.visits >= CAP
