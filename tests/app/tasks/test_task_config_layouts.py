"""A task run's config names its brain as a robot run's does (layout 2, `brain`); a task run
file or preset of layout 1 (`controller`, `evolution` at the top) reads the same (#46)."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import pydantic_core
import pytest
from pydantic import ValidationError

from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.brains.net_settings import NetSettings
from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, read_task_run, train_task
from app.tasks.config import task_layout_1
from app.tasks.peer import read_peer
from gnp import EvolutionConfig


def _config() -> TaskRunConfig:
    return TaskRunConfig(
        seed=3,
        task=TaskSettings(id="CartPole-v1"),
        brain=GnpSettings(
            controller=ControllerSettings(method="BS", fuzzy=False, n_judgment=9, q0=0.5),
            evolution=EvolutionConfig(p_mutation=0.03),
        ),
        training=TaskTraining(population=4, generations=2, steps=30),
    )


def test_a_layout_2_task_config_round_trips() -> None:
    config = _config()
    data = config.model_dump(mode="json")
    assert list(data) == ["seed", "task", "brain", "training"]
    assert set(data["brain"]) == {"family", "controller", "evolution"}
    assert TaskRunConfig.model_validate_json(config.model_dump_json()) == config
    assert TaskRunConfig.model_validate(data) == config


def test_layout_1_maps_back_in_its_order_and_moves_to_the_same_config() -> None:
    config = _config()
    old = task_layout_1(config.model_dump(mode="json"))
    assert list(old) == ["seed", "task", "controller", "evolution", "training"]
    assert old["controller"]["n_judgment"] == 9 and old["evolution"]["p_mutation"] == 0.03
    assert TaskRunConfig.model_validate(old) == config
    assert TaskRunConfig.model_validate_json(pydantic_core.to_json(old)) == config


def test_a_task_run_file_of_layout_1_reads_back_equal(tmp_path: Path) -> None:
    config = _config()
    new = train_task(config, tmp_path / "new.h5")
    old = tmp_path / "old.h5"
    shutil.copyfile(new, old)
    with h5py.File(old, "r+") as handle:
        text = pydantic_core.to_json(task_layout_1(config.model_dump(mode="json"))).decode()
        assert '"brain"' not in text and '"controller"' in text
        handle.attrs["config"] = text
    before, after = read_task_run(new), read_task_run(old)
    assert before.config == after.config == config
    assert before.generation_done == after.generation_done == 2
    assert read_peer(old).run == read_peer(new).run == config
    with h5py.File(new, "r") as handle:  # written in layout 2
        assert '"brain":{' in str(handle.attrs["config"])


@pytest.mark.parametrize(
    ("brain", "family"),
    [({"brain": {"family": "cmaes"}}, "cmaes"), ({"neuro": {"optimiser": "neat"}}, "neat")],
)
def test_a_task_config_of_another_family_holds_its_settings(
    brain: dict[str, object], family: str
) -> None:
    config = TaskRunConfig.model_validate({"task": {"id": "CartPole-v1"}, **brain})
    assert config.brain == NetSettings(family=family)  # type: ignore[arg-type]
    with pytest.raises(ValidationError, match=r"brain\.hidden"):
        TaskRunConfig.model_validate(
            {"task": {"id": "CartPole-v1"}, "brain": {"family": family, "hidden": 0}}
        )
