"""Any brain family on any Gymnasium task with a Box observation and a Discrete or Box action.

`spaces` reads a task's spaces (features scaled to 0..1023, outputs to actions), `config` binds
a family to the task (`TaskRunConfig.family`), `faults` breaks observation features, `lives`
steps a family's population through a batch env (the lab's compiled twins of CartPole,
MountainCar, Acrobot and Pendulum, `dynamics` and `pendulum`, else Gymnasium's vector env),
`gnp_lives` GNP's own lives (fused with the twins on the three discrete tasks), `training`
trains, resumes and replays, `store` writes the run file, `common` is what the lab needs without
Gymnasium. The names below load their module (and Gymnasium) on first use, so importing
`app.tasks.common` leaves Gymnasium unimported.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from app.tasks.common import TaskError, is_task_run
    from app.tasks.config import TaskRunConfig, TaskSettings, TaskTraining, make_env
    from app.tasks.faults import ObservationFault, ObservationFaults
    from app.tasks.lives import BatchEnv, TaskLives, live
    from app.tasks.spaces import KNOWN_BOUNDS, TaskAdapter, task_adapter
    from app.tasks.store import read_task_run
    from app.tasks.training import replay_episodes, replay_task, resume_task, train_task

_HOME = {
    "TaskError": "common",
    "is_task_run": "common",
    "TaskRunConfig": "config",
    "TaskSettings": "config",
    "TaskTraining": "config",
    "make_env": "config",
    "ObservationFault": "faults",
    "ObservationFaults": "faults",
    "BatchEnv": "lives",
    "TaskLives": "lives",
    "live": "lives",
    "KNOWN_BOUNDS": "spaces",
    "TaskAdapter": "spaces",
    "task_adapter": "spaces",
    "read_task_run": "store",
    "replay_episodes": "training",
    "replay_task": "training",
    "resume_task": "training",
    "train_task": "training",
}

__all__ = [
    "KNOWN_BOUNDS",
    "BatchEnv",
    "ObservationFault",
    "ObservationFaults",
    "TaskAdapter",
    "TaskError",
    "TaskLives",
    "TaskRunConfig",
    "TaskSettings",
    "TaskTraining",
    "is_task_run",
    "live",
    "make_env",
    "read_task_run",
    "replay_episodes",
    "replay_task",
    "resume_task",
    "task_adapter",
    "train_task",
]


def __getattr__(name: str) -> Any:
    home = _HOME.get(name)
    if home is None:
        raise AttributeError(f"module 'app.tasks' has no attribute {name!r}")
    return getattr(importlib.import_module(f"app.tasks.{home}"), name)
