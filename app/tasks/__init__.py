"""GNP brains on any Gymnasium task with a Box observation and a Discrete or Box action.

`spaces` reads a task's spaces (features scaled to 0..1023, outputs to actions), `faults` breaks
observation features, `lives` steps a population through a vector env, `training` trains,
resumes and replays, `store` writes the run file.
"""

from app.tasks.config import TaskRunConfig, TaskSettings, TaskTraining, make_env
from app.tasks.faults import ObservationFault, ObservationFaults
from app.tasks.lives import BatchEnv, TaskLives, live
from app.tasks.spaces import KNOWN_BOUNDS, TaskAdapter, TaskError, task_adapter
from app.tasks.store import is_task_run, read_task_run
from app.tasks.training import replay_episodes, replay_task, resume_task, train_task

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
