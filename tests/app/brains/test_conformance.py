"""`app.brains.check_family` passes on the lab's families and names what a broken one breaks."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, ClassVar, Literal

import numpy as np
import pytest

import sim
from app.brains import BrainFamily, BrainSettings, FamilyCheckError, check_family, register
from app.brains.conformance import tiny_config
from app.brains.gnp_brain import GnpFamily
from app.brains.nets import CmaesFamily, NeatFamily
from app.settings.config import RunConfig


class WandererSettings(BrainSettings):
    family: Literal["wanderer"] = "wanderer"


class Wheels:
    """Commands = gain × the mean reading / IR_MAX, per robot."""

    def __init__(self, gain: np.ndarray) -> None:
        self.gain = gain

    @property
    def size(self) -> int:
        return len(self.gain)

    def act(self, observations: np.ndarray, reward: np.ndarray, *, trace: bool) -> Any:
        del reward
        commands = self.gain * observations.mean(axis=1, keepdims=True) / sim.IR_MAX
        return commands, SimpleNamespace(commands=commands) if trace else None

    def reset_episode(self) -> None:
        pass


class Evolving:
    def __init__(self, arrays: dict[str, np.ndarray]) -> None:
        self.arrays_now = arrays

    def epsilon_alpha(self, generation: int) -> tuple[float, float]:
        del generation
        return float("nan"), float("nan")

    def individuals(self) -> dict[str, np.ndarray]:
        return self.arrays_now

    def arrays(self, individuals: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return individuals

    def advance(self, learned: Any, fitness: np.ndarray, generation: int) -> Any:
        del learned, generation
        self.arrays_now = {"gain": self.arrays_now["gain"] + fitness[:, None]}
        return self.arrays_now


class Wanderer(BrainFamily):
    """A keeping family of the least code: two gains per individual, evolved by adding fitness."""

    name = "wanderer"
    settings_model = WandererSettings
    genome_layout: ClassVar = {"gain": ((2,), np.float64)}
    trace_layout: ClassVar = {"commands": ((2,), np.float64)}

    def first(self) -> Evolving:
        rng = np.random.default_rng(self.config.seed)
        return Evolving({"gain": rng.uniform(-1, 1, (self.config.training.population, 2))})

    def rebuild(self, generation: int, arrays: dict[str, np.ndarray], fitness: Any) -> Evolving:
        del generation, fitness
        return Evolving(self.from_arrays(arrays))

    def controllers(self, individuals: dict[str, np.ndarray], engine_seeds: Any) -> Wheels:
        del engine_seeds
        return Wheels(individuals["gain"])

    def controller_document(self, individual: Any, settings: dict[str, Any]) -> dict[str, Any]:
        return {"format": "wanderer", "settings": settings, "gain": individual["gain"].tolist()}


register(Wanderer)


def problems_of(family: type[BrainFamily]) -> str:
    with pytest.raises(FamilyCheckError) as raised:
        check_family(family, tiny_config(Wanderer))
    return str(raised.value)


@pytest.mark.parametrize("method", ["RL", "BS", "CS"])
def test_gnp_keeps_the_contract(method: str) -> None:
    selection = GnpFamily.selection()
    selection["brain"]["controller"] = {"method": method}
    training = {"population": 4, "generations": 2, "steps": 5}
    check_family(GnpFamily, RunConfig.model_validate({**selection, "training": training}))


@pytest.mark.parametrize(
    ("controller", "described"),
    [
        ({"method": "CS"}, "CS fuzzy"),
        ({"method": "RL", "fuzzy": False}, "RL crisp"),
        ({"method": "RL", "fuzzy": False, "judgment_branches": 3}, "RL crisp, 3-way judgment"),
    ],
)
def test_gnp_runs_are_described_by_method_judgment_and_k_beyond_two(
    controller: dict[str, object], described: str
) -> None:
    selection = GnpFamily.selection()
    selection["brain"]["controller"] = controller
    assert GnpFamily(RunConfig.model_validate(selection)).description == described


@pytest.mark.parametrize("family", [CmaesFamily, NeatFamily, Wanderer])
def test_the_nets_and_a_family_of_the_least_code_keep_it(family: type[BrainFamily]) -> None:
    check_family(family)


def test_a_first_generation_not_drawn_from_the_seed_is_named() -> None:
    class Unseeded(Wanderer):
        def first(self) -> Evolving:
            gain = np.random.default_rng().uniform(-1, 1, (self.config.training.population, 2))
            return Evolving({"gain": gain})

    found = problems_of(Unseeded)
    assert "generation 0 is a function of the seed: two first() differ" in found
    assert "rebuild(1, ...) resumes to the bit" not in found  # the rest still pass


def test_wrong_commands_and_coupled_robots_are_named() -> None:
    class Three(Wheels):
        def act(self, observations: np.ndarray, reward: np.ndarray, *, trace: bool) -> Any:
            commands, step = super().act(observations, reward, trace=trace)
            return np.c_[commands, commands[:, :1]], step

    class Coupled(Wheels):
        def act(self, observations: np.ndarray, reward: np.ndarray, *, trace: bool) -> Any:
            commands, step = super().act(observations, reward, trace=trace)
            return commands + observations.mean() / sim.IR_MAX, step

    class WrongShape(Wanderer):
        def controllers(self, individuals: dict[str, np.ndarray], engine_seeds: Any) -> Wheels:
            del engine_seeds
            return Three(individuals["gain"])

    class Meddling(Wanderer):
        def controllers(self, individuals: dict[str, np.ndarray], engine_seeds: Any) -> Wheels:
            del engine_seeds
            return Coupled(individuals["gain"])

    wrong = "act: (N, n_outputs) finite commands in range: commands are (2, 3), not (2, 2)"
    assert wrong in problems_of(WrongShape)
    assert "act: rows independent: robot 0's commands depend" in problems_of(Meddling)


def test_names_that_disagree_are_named() -> None:
    class Renamed(Wanderer):
        name = "wanderer-2"

    found = problems_of(Renamed)
    assert "names agree: " in found
    assert "WandererSettings.family defaults to 'wanderer'" in found
    assert "no family is registered under 'wanderer-2'" in found
    with pytest.raises(ValueError, match="named otherwise"):
        register(Renamed)


def test_a_lazy_entry_whose_class_is_named_otherwise_is_refused_when_looked_up() -> None:
    from app.brains import family_class
    from app.settings import families
    from app.settings.errors import ConfigError

    register("elman", "app.brains.nets:CmaesFamily", "app.brains.net_settings:NetSettings")
    try:
        with pytest.raises(ConfigError) as raised:
            family_class("elman")
    finally:
        del families._table["elman"]
    found = str(raised.value)
    assert "'elman' is named otherwise" in found and "CmaesFamily.name is 'cmaes'" in found
    assert "NetSettings.family admits only 'cmaes', 'neat'" in found and "\n" not in found


def test_arrays_not_of_the_genome_layout_are_refused_on_one_line() -> None:
    from app.store import RunFileError

    family = Wanderer(tiny_config(Wanderer))
    with pytest.raises(RunFileError, match=r"^genome array gain must be \(3, 2\) float64, got"):
        family.from_arrays({"gain": np.zeros((3, 2), np.float32)})
    with pytest.raises(RunFileError, match=r"^genome arrays must be \['gain'\], got \['bias'\]$"):
        family.from_arrays({"bias": np.zeros((3, 2))})


def test_a_family_that_declares_any_io_is_checked_on_a_tasks_inputs_and_outputs() -> None:
    class Claims(Wanderer):  # two gains whatever `io` says
        any_io = True

    found = problems_of(Claims)
    assert "on TASK_IO: act: (N, n_outputs) finite commands in range: commands are (2, 2), " in (
        found
    )
    assert "not (2, 1)" in found
    # Its names aside (a subclass registered under none), the robot's checks all pass.
    assert found.count("\n- ") == found.count("\n- on TASK_IO: ") + found.count("names agree")

    class Sized(Wanderer):  # one gain per output
        any_io = True

        @property
        def genome_layout(self) -> Any:
            return {"gain": ((self.io.n_outputs,), np.float64)}

        @property
        def trace_layout(self) -> Any:
            return {"commands": ((self.io.n_outputs,), np.float64)}

        def first(self) -> Evolving:
            rng = np.random.default_rng(self.config.seed)
            shape = (self.config.training.population, self.io.n_outputs)
            return Evolving({"gain": rng.uniform(-1, 1, shape)})

    register(Sized)  # under Wanderer's name, as the checks need; Wanderer again after
    try:
        check_family(Sized, tiny_config(Wanderer))
    finally:
        register(Wanderer)
