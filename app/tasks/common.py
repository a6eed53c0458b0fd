"""What the lab knows of task runs without importing Gymnasium: which run files are task runs,
the error a task raises, and `gnp-lab replay`'s options. `gnp-lab` imports this module alone and
the rest of `app.tasks` (and Gymnasium) only when a task is asked for."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field

from app.settings.cli_options import add_run_name, add_runs_dir
from app.store.files import RunFileError
from app.store.reader import file_kind
from sim import FAULT_MODES


class TaskError(ValueError):
    """A task the lab cannot run (unknown id, a space it cannot judge or emit, bad bounds), or a
    brain family that cannot run on it."""


#: How a task run's final elite lives its test (and validation) episodes: "as-trained" (its
#: generation's ε and α, Sarsa on, as it lived in training) or "greedy" (ε = α = 0, Sarsa frozen).
TestProtocol = Literal["as-trained", "greedy"]
TEST_PROTOCOLS: tuple[TestProtocol, ...] = get_args(TestProtocol)


class EpisodeProtocol(BaseModel):
    """How a task run's episodes are seeded and its final elite chosen and tested: settings of
    a task run's training (`app.tasks.config.TaskTraining`) and of a task experiment's `[task]`
    (`app.experiments.spec_tables.TaskSpec`), written here once. The defaults are the runs
    before issue #45: one episode seed per individual, the last generation's best, tested as
    trained."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    test_protocol: TestProtocol = Field(
        default="as-trained",
        description="how the final elite lives its test and validation episodes: as-trained "
        "(its generation's ε and α, Sarsa on) or greedy (ε = α = 0, Sarsa frozen)",
    )
    validation_episodes: int = Field(
        default=1,
        ge=1,
        le=1000,
        description="K: the final elite is the generation's best (of every generation) with "
        "the highest mean return over K validation episodes; 1 = the last generation's best "
        "by its training episode",
    )
    shared_episodes: bool = Field(
        default=False,
        description="every individual of a generation lives the same episode (one episode "
        "seed per generation, fracnetics' scheme); off: one seed per individual",
    )


def is_task_run(path: str | Path) -> bool:
    """Whether `path` is a task run file, as its kind says (`app.store.file_kind`; an old task
    run file's format too): False for anything else, a robot run included, and for what is not
    a regular file (h5py would wait on a FIFO)."""
    try:
        return file_kind(path) == "task"
    except RunFileError:
        return False


def add_replay_parser(commands: Any) -> argparse.ArgumentParser:
    """`gnp-lab replay`: live a task run's best individual again."""
    replay = commands.add_parser(
        "replay",
        help="live a task run's best individual one episode again and print its return",
        description="Live the best individual of a generation (default: the last) of a task "
        "run for one episode from --seed, learning online as in training, with observation "
        "faults if asked.",
    )
    add_run_name(replay)
    add_runs_dir(replay)
    replay.add_argument("--seed", type=int, default=0, help="episode and controller seed")
    replay.add_argument(
        "--episodes", type=int, default=1, metavar="K", help="K episodes, seeds SEED..SEED+K-1"
    )
    replay.add_argument("--generation", type=int, metavar="G", help="the best of this one")
    replay.add_argument("--greedy", action="store_true", help="ε = 0 (no exploration)")
    replay.add_argument("--fault-step", type=int, default=0, metavar="T", help="faults from T")
    replay.add_argument(
        "--fault-features", default="", metavar="J,K", help="observation features that break"
    )
    replay.add_argument("--fault-mode", choices=FAULT_MODES, default="dead")
    return replay
