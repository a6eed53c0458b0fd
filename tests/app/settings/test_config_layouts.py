"""A run config's two layouts (#46 item 1): every layout-1 shape ever written is moved to the
`brain` section and reads as the same config; layers in either layout merge by precedence; the
bundled runs read; errors name `brain.…` fields; an unknown family lists but does not bind."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import pytest

from app.brains import family_of, run_kind
from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.brains.net_settings import NetSettings
from app.settings.config import ConfigError, RunConfig, preset_layer
from app.settings.families import UnregisteredBrain
from app.settings.layouts import layout_1, layout_2
from app.settings.loading import build_config, stored_config
from app.store import RunReader, list_runs
from gnp import EvolutionConfig
from neuro.neat_params import NeatParams

ROOT = Path(__file__).resolve().parents[3]
BUNDLED = sorted((ROOT / "saved_runs").glob("demo*.h5"))

#: Layout 1 as every file before #46 wrote it, and the same config in layout 2.
SHAPES: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {
    "gnp": (
        {"seed": 4, "controller": {"method": "BS", "fuzzy": False},
         "evolution": {"p_mutation": 0.02}},
        {"seed": 4, "brain": {"controller": {"method": "BS", "fuzzy": False},
                              "evolution": {"p_mutation": 0.02}}},
    ),
    "gnp selected": (
        {"controller": {"method": "RL"}, "neuro": None, "family": None},
        {"brain": {"family": "gnp", "controller": {"method": "RL"}}},
    ),
    "cmaes": (
        {"controller": {"method": "CS"}, "evolution": {},
         "neuro": {"optimiser": "cmaes", "hidden": 3}},
        {"brain": {"family": "cmaes", "hidden": 3}},
    ),
    "neat": (
        {"neuro": {"optimiser": "neat", "neat": {"max_hidden": 5}}, "training": {"population": 9}},
        {"brain": {"family": "neat", "neat": {"max_hidden": 5}}, "training": {"population": 9}},
    ),
    "outside family": (
        {"controller": {}, "family": {"name": "vehicle", "sigma": 0.5}},
        {"brain": {"family": "vehicle", "sigma": 0.5}},
    ),
}  # fmt: skip


@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_every_layout_1_shape_moves_to_layout_2_and_reads_the_same(shape: str) -> None:
    old, new = SHAPES[shape]
    assert layout_2(old) == new
    assert layout_2(new) == new  # layout 2 is left as it is
    assert RunConfig.model_validate(old) == RunConfig.model_validate(new) == build_config(old)


def test_the_families_read_with_their_own_models() -> None:
    gnp = RunConfig.model_validate(SHAPES["gnp"][0])
    assert gnp.brain == GnpSettings(
        controller=ControllerSettings(method="BS", fuzzy=False),
        evolution=EvolutionConfig(p_mutation=0.02),
    )
    net = RunConfig.model_validate(SHAPES["neat"][0])
    assert net.brain == NetSettings(family="neat", neat=NeatParams(max_hidden=5))
    outside = RunConfig.model_validate(SHAPES["outside family"][0])
    assert isinstance(outside.brain, UnregisteredBrain)
    assert outside.brain.model_dump() == {"family": "vehicle", "sigma": 0.5}


def test_a_stored_layout_1_config_reads_and_its_identity_maps_back() -> None:
    """A file of older code: its JSON in layout 1 (GNP's sections always, no `neuro`)."""
    new = build_config(preset_layer("thesis-ch3"), {"seed": 7})
    data = json.loads(new.model_dump_json())
    old = layout_1(data, "gnp")
    assert list(old) == ["seed", "controller", "evolution", "training", "implementation", "reward"]
    assert stored_config(json.dumps(old)) == new
    dumped = json.loads(new.model_dump_json())
    assert list(dumped) == ["seed", "brain", "training", "implementation", "reward"]
    assert list(dumped["brain"]) == ["family", "controller", "evolution"]
    net = build_config({"neuro": {"optimiser": "cmaes", "hidden": 3}})
    assert layout_1(net.model_dump(exclude_defaults=True), "cmaes") == {
        "neuro": {"optimiser": "cmaes", "hidden": 3}
    }


def test_a_layout_1_preset_under_a_layout_2_arm_merges_by_precedence() -> None:
    preset = {"controller": {"method": "BS", "n_branch": 3}, "training": {"population": 20}}
    arm = {"brain": {"controller": {"method": "RL"}}}
    config = build_config(preset, arm)
    assert (config.brain.controller.method, config.brain.controller.n_branch) == ("RL", 3)  # type: ignore[attr-defined]
    back = build_config(arm, preset)  # the later layer wins, whatever its layout
    assert back.brain.controller.method == "BS"  # type: ignore[attr-defined]
    # A layer naming another family replaces the brain: GNP's settings are not a net's.
    net = build_config(preset, {"neuro": {"optimiser": "cmaes"}}, {"brain": {"hidden": 2}})
    assert net.brain == NetSettings(family="cmaes", hidden=2) and net.training.population == 20
    with pytest.raises(ConfigError, match=r"brain\.controller: unknown setting"):
        build_config({"brain": {"family": "cmaes"}}, preset)


@pytest.mark.parametrize(
    ("layer", "problem"),
    [
        ({"brain": {"controller": {"n_judgment": 3}}}, "brain.controller.n_judgment: Input should"),
        ({"controller": {"methd": "RL"}}, "brain.controller.methd: unknown setting"),
        ({"brain": {"evolution": {"p_mutation": 2}}}, "brain.evolution.p_mutation: Input should"),
        ({"evolution": {"p_add_delete": -1}}, "brain.evolution.p_add_delete: Input should"),
        ({"brain": {"family": "neat", "sigma0": 0}}, "brain.sigma0: Input should be greater"),
        ({"brain": 3}, "brain: a table of settings"),
        ({"neuro": 3}, "neuro: unknown setting"),
    ],
)
def test_errors_name_the_brain_field(layer: dict[str, Any], problem: str) -> None:
    with pytest.raises(ConfigError, match="invalid configuration in test: ") as caught:
        build_config(layer, source="test")
    assert problem in str(caught.value) and "\n" not in str(caught.value)


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_the_bundled_runs_read(path: Path) -> None:
    with h5py.File(path, "r", locking=False) as handle:
        stored = json.loads(str(handle.attrs["config"]))
    assert "controller" in stored and "brain" not in stored  # written in layout 1
    with RunReader(path) as run:
        config = run.config
    assert isinstance(config.brain, GnpSettings)
    controller, evolution = (
        s.model_dump() for s in (config.brain.controller, config.brain.evolution)
    )
    assert {k: controller[k] for k in stored["controller"]} == stored["controller"]
    assert {k: evolution[k] for k in stored["evolution"]} == stored["evolution"]
    assert family_of(config).description.startswith(config.brain.controller.method)


def test_an_unknown_family_is_listed_and_refused_when_bound(tmp_path: Path) -> None:
    """A run of a family not installed here (its file in layout 1, as older code wrote it)."""
    copy = tmp_path / "vehicle.h5"
    copy.write_bytes(BUNDLED[0].read_bytes())
    with h5py.File(copy, "r+", locking=False) as handle:
        data = json.loads(str(handle.attrs["config"]))
        data["family"] = {"name": "vehicle", "sigma": 0.5}
        handle.attrs["config"] = json.dumps(data)
    config = stored_config(json.dumps(data))
    assert config.brain.family == "vehicle" and isinstance(config.brain, UnregisteredBrain)
    assert json.loads(config.model_dump_json())["brain"] == {"family": "vehicle", "sigma": 0.5}
    with pytest.raises(ConfigError, match="unknown brain family 'vehicle'"):
        family_of(config)
    (summary,) = list_runs(tmp_path)
    assert summary.error is None, summary.error
    assert summary.brain == "vehicle" and run_kind(summary) == "vehicle (not registered)"


def test_the_cli_selects_a_family_beside_its_options() -> None:
    from app.cli.parser import build_parser
    from app.cli.train import config_from_args

    def config(*argv: str) -> RunConfig:
        return config_from_args(build_parser().parse_args(["train", *argv]))

    assert config("--brain", "cmaes", "--set", "brain.hidden=3").brain == NetSettings(
        family="cmaes", hidden=3
    )
    assert config("--preset", "thesis-ch3", "--brain", "neat").brain == NetSettings(family="neat")
    assert config("--brain", "gnp", "--crisp").brain.controller.fuzzy is False  # type: ignore[attr-defined]
    with pytest.raises(ConfigError, match=r"brain\.controller: unknown setting"):
        config("--brain", "cmaes", "--method", "RL")  # GNP's option is not a net's


def test_a_plugin_that_cannot_be_imported_is_named_whenever_a_config_is_read(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("GNP_LAB_BRAINS", "no_such_family_module")
    for _ in range(2):  # not once only: every read says so
        with pytest.raises(ConfigError, match="'no_such_family_module', which cannot be imported"):
            build_config({})
