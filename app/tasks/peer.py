"""One run of a task experiment: a brain (ours or fracnetics) trained on a Gymnasium task, then
its final elite tested on K fixed episode seeds (the same for every arm).

GNP runs are task run files (`app.tasks.store`: run files of kind "task", or of the old task
run format), resumable, with a `test` group added when
training is done: the final elite (the best of the last generation, or the generation best
chosen on K validation episodes: `elite_generation`) lives one episode per test seed under each
test protocol (`TEST_PROTOCOLS`: as trained, its generation's ε and α, Sarsa on, each episode
from the Q tables it ended training with; and greedy, ε = α = 0, Sarsa frozen). `test/returns`
holds the returns of the run's own `test_protocol` (the metric `test_return`), and
`test/returns_<protocol>` each protocol's (the metrics `test_return_<protocol>`; a file tested
before #45 holds `returns` only, as trained). fracnetics' elite is a fixed policy (its library
has no learning): its returns are every protocol's. Env-steps, for either brain: the steps
each generation's episodes took (`generations/env_steps` of a task run, `history/env_steps` of
a fracnetics run and of an old task run file), and
`test/lengths_<protocol>` (K,) int64 each test episode's length (a file written before #45 holds
neither: `PeerResult.env_steps` and `test_lengths` read None). fracnetics runs
(`app.tasks.fracnetics_arm`) write a file of their own format with their results only. Both
carry the `PeerRun` they ran as the root attribute `peer`, and `read_peer` reads either.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import h5py
import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from app.settings.user_files import check_regular, loads_json
from app.store.files import LIBVER, RunFileError, open_for_read
from app.store.schema import ENV_STEPS_UNIT, EPISODE_RETURN, package_version
from app.store.validation import check_progress, plain_dataset
from app.tasks.common import is_task_run
from app.tasks.config import TEST_PROTOCOLS, TaskRunConfig
from app.tasks.fracnetics_arm import FracneticsResult, FracneticsSettings
from app.tasks.store import read_task_run

FRACNETICS_FORMAT = "gnp-lab-fracnetics-run"
PeerBrain = Literal["gnp", "fracnetics"]


class PeerRun(BaseModel):
    """Everything one run of a task experiment depends on."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    brain: PeerBrain = "gnp"
    run: TaskRunConfig = Field(description="seed, task, population, generations, cap (both)")
    fracnetics: FracneticsSettings | None = None
    test_seeds: tuple[int, ...] = Field(min_length=1, description="the elite's test episodes")


@dataclass(frozen=True)
class PeerResult:
    """What a run file holds of its run (test_returns None until tested)."""

    peer_json: str  # "" until a GNP run is tested
    run: TaskRunConfig
    generations_done: int
    generations: int
    best_curve: np.ndarray  # (generations_done,) best return per generation
    test_returns: np.ndarray | None
    #: test returns per protocol (`TEST_PROTOCOLS`) the file holds (none before #45)
    protocol_returns: dict[str, np.ndarray] | None = None
    #: (generations_done,) env-steps each generation's episodes took (None before #45)
    env_steps: np.ndarray | None = None
    #: test episode lengths (env-steps) per protocol the file holds (None before #45)
    test_lengths: dict[str, np.ndarray] | None = None

    @property
    def training_env_steps(self) -> int | None:
        """The env-steps training spent, over every generation done (None: not recorded)."""
        return None if self.env_steps is None else int(self.env_steps.sum())

    @property
    def finished(self) -> bool:
        return self.generations_done >= self.generations and self.test_returns is not None


def is_fracnetics_run(path: str | Path) -> bool:
    """Whether `path` is a fracnetics arm's run file (`_write_fracnetics`' format); False for
    anything else, and for what is not a regular file or not HDF5."""
    try:
        with open_for_read(Path(path)) as handle:
            return bool(handle.attrs.get("format") == FRACNETICS_FORMAT)
    except (RunFileError, OSError):
        return False


def read_peer(path: str | Path) -> PeerResult:
    """A task experiment's run file, either brain (a GNP run: a task run, read by
    `read_task_run`, its `test` group beside).

    Raises:
        RunFileError: unreadable, or not a task experiment's run file.
    """
    path = Path(path)
    check_regular(path, RunFileError, "run file")
    gnp = read_task_run(path) if is_task_run(path) else None
    handle = open_for_read(path)  # a killed GNP run's file needs a SWMR read
    with handle:
        if gnp is None and handle.attrs.get("format") != FRACNETICS_FORMAT:
            raise RunFileError(f"{path} is not a task experiment's run file")
        try:
            if gnp is None:
                config, done, fitness, steps = _fracnetics_training(path, handle)
            else:
                config, done, fitness, steps = (
                    gnp.config,
                    gnp.generation_done,
                    gnp.fitness,
                    gnp.env_steps,
                )
            return _peer(handle, config, done, fitness, steps)
        except (ValidationError, KeyError, ValueError, TypeError, OverflowError, OSError) as error:
            text = str(error).splitlines()[0] if str(error) else type(error).__name__
            raise RunFileError(f"corrupt task run file {path}: {text}") from None


def _fracnetics_training(
    path: Path, handle: h5py.File
) -> tuple[TaskRunConfig, int, np.ndarray, np.ndarray | None]:
    """(config, generations done, fitness, env-steps) of a fracnetics run's file, checked: its
    config, `generations_done` within the config's generations and the rows held, a (rows,
    population) float fitness table."""
    config = TaskRunConfig.model_validate(
        loads_json(handle.attrs["config"], RunFileError, "config")
    )
    generations = config.training.generations
    done = check_progress(
        "generations_done", handle.attrs["generations_done"], 0, generations, path
    )
    table = plain_dataset(handle, "history/fitness")
    if table.ndim != 2 or table.shape[0] < done or table.dtype.kind not in "iuf":
        raise RunFileError(f"{path}: history/fitness is {table.shape} {table.dtype}")
    steps = None
    if "history/env_steps" in handle:
        column = plain_dataset(handle, "history/env_steps")
        if column.ndim != 1 or column.shape[0] < done or column.dtype.kind not in "iu":
            raise RunFileError(f"{path}: history/env_steps is {column.shape} {column.dtype}")
        steps = np.asarray(column[:done], np.int64)
    return config, done, np.asarray(table[:done]), steps


def _peer(
    handle: h5py.File,
    config: TaskRunConfig,
    done: int,
    fitness: np.ndarray,
    steps: np.ndarray | None,
) -> PeerResult:
    """`read_peer` of an open file, its training read: its test group, if any."""
    test = (
        np.asarray(plain_dataset(handle, "test/returns")[()], float) if "test" in handle else None
    )
    protocols: dict[str, np.ndarray] = {
        p: np.asarray(plain_dataset(handle, _protocol_dataset(p))[()], float)
        for p in TEST_PROTOCOLS
        if _protocol_dataset(p) in handle
    }
    lengths: dict[str, np.ndarray] = {
        p: np.asarray(plain_dataset(handle, _protocol_dataset(p, "lengths"))[()], np.int64)
        for p in TEST_PROTOCOLS
        if _protocol_dataset(p, "lengths") in handle
    }
    return PeerResult(
        peer_json=str(handle.attrs.get("peer", "")),
        run=config,
        generations_done=done,
        generations=config.training.generations,
        best_curve=fitness.max(axis=1) if done else np.zeros(0),
        test_returns=test,
        protocol_returns=protocols or None,
        env_steps=steps,
        test_lengths=lengths or None,
    )


def _protocol_dataset(protocol: str, what: str = "returns") -> str:
    """Where a test protocol's returns (or episode lengths) are: test/returns_as_trained,
    test/returns_greedy, test/lengths_as_trained, test/lengths_greedy."""
    return f"test/{what}_" + protocol.replace("-", "_")


def _write_protocols(
    group: h5py.Group, returns: dict[str, np.ndarray], lengths: dict[str, np.ndarray]
) -> None:
    for protocol, values in returns.items():
        group.create_dataset(_protocol_dataset(protocol).split("/")[1], data=values)
    for protocol, values in lengths.items():
        name = _protocol_dataset(protocol, "lengths").split("/")[1]
        group.create_dataset(name, data=np.asarray(values, np.int64)).attrs["unit"] = ENV_STEPS_UNIT


def _write_test(
    path: Path,
    peer: PeerRun,
    by_protocol: dict[str, np.ndarray],
    lengths: dict[str, np.ndarray],
    elite_generation: int,
) -> None:
    with h5py.File(path, "r+", locking=False) as handle:
        handle.attrs["peer"] = peer.model_dump_json()
        if "test" in handle:
            del handle["test"]
        group = handle.create_group("test")
        group.attrs["unit"] = EPISODE_RETURN
        group.attrs["protocol"] = peer.run.training.test_protocol
        group.attrs["elite_generation"] = elite_generation
        group.create_dataset("seeds", data=np.asarray(peer.test_seeds, dtype=np.int64))
        group.create_dataset("returns", data=by_protocol[peer.run.training.test_protocol])
        _write_protocols(group, by_protocol, lengths)


def _write_fracnetics(path: Path, peer: PeerRun, result: FracneticsResult) -> None:
    fitness, test = result.fitness, result.test_returns
    tmp = path.with_name(path.name + ".part")
    tmp.unlink(missing_ok=True)
    with h5py.File(tmp, "w-", libver=LIBVER, locking=False) as handle:
        handle.attrs["format"] = FRACNETICS_FORMAT
        handle.attrs["schema_version"] = 1
        handle.attrs["package_version"] = package_version()
        handle.attrs["seed"] = peer.run.seed
        handle.attrs["task"] = peer.run.task.id
        handle.attrs["config"] = peer.run.model_dump_json()
        handle.attrs["peer"] = peer.model_dump_json()
        handle.attrs["generations_done"] = fitness.shape[0]
        history = handle.create_group("history")
        history.create_dataset("fitness", data=fitness).attrs["unit"] = EPISODE_RETURN
        steps = history.create_dataset("env_steps", data=np.asarray(result.env_steps, np.int64))
        steps.attrs["unit"] = ENV_STEPS_UNIT
        group = handle.create_group("test")
        group.attrs["unit"] = EPISODE_RETURN
        group.create_dataset("seeds", data=np.asarray(peer.test_seeds, dtype=np.int64))
        group.create_dataset("returns", data=test)
        _write_protocols(
            group,
            dict.fromkeys(TEST_PROTOCOLS, test),
            dict.fromkeys(TEST_PROTOCOLS, result.test_lengths),
        )
    tmp.replace(path)  # whole or absent: a fracnetics run is not resumable


def run_peer(
    peer: PeerRun, path: str | Path, progress: Callable[[int], None] | None = None
) -> PeerResult:
    """Train (GNP: or resume) and test one run into `path`; a finished run is left as it is."""
    from app.tasks.training import elite_generation, protocol_episodes, resume_task, train_task

    path = Path(path)
    if path.exists():
        done = read_peer(path)
        if done.finished:
            return done
    if peer.brain == "fracnetics":
        from app.tasks.fracnetics_arm import documented, train_fracnetics

        t = peer.run.training
        result = train_fracnetics(
            peer.run.task.id,
            peer.fracnetics or documented(peer.run.task.id),
            t.population,
            t.generations,
            peer.run.seed,
            t.steps,
            peer.test_seeds,
            progress=(lambda g, _best: progress(g)) if progress is not None else None,
        )
        _write_fracnetics(path, peer, result)
        return read_peer(path)

    def each(generation: object) -> None:
        if progress is not None:
            progress(int(generation.generation))  # type: ignore[attr-defined]

    if not path.exists():
        train_task(peer.run, path, progress=each)
    elif read_peer(path).generations_done < peer.run.training.generations:
        resume_task(path, progress=each)
    elite = elite_generation(path)
    lives = {p: protocol_episodes(path, peer.test_seeds, elite, p) for p in TEST_PROTOCOLS}
    by_protocol: dict[str, np.ndarray] = {
        p: np.asarray(life.returns, np.float64) for p, life in lives.items()
    }
    lengths: dict[str, np.ndarray] = {
        p: np.asarray(life.lengths, np.int64) for p, life in lives.items()
    }
    _write_test(path, peer, by_protocol, lengths, elite)
    return read_peer(path)
