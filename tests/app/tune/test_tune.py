"""`gnp-lab tune`: a real (tiny) Optuna study on CartPole, its preset into `train --preset`, a
cut study resumed to its declared trials with the trials an uncut one draws, fracnetics tuned
by the same command, and every bad input on one line."""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

import pytest

from app.cli.main import main
from app.experiments.planning import plan
from app.experiments.spec import ExperimentError
from app.experiments.spec_loading import parse
from app.phases.generations import Interrupted
from app.tasks.config import TaskSettings
from app.tasks.peer import PeerRun
from app.tasks.store import read_task_run
from app.tune import space as space_module
from app.tune import study as tuning
from app.tune.preset import TuningRecord, read_preset, write_preset
from app.tune.space import TuneError

# A study of seconds: CartPole, 10 lives of up to 500 steps, 4 generations (20,000 env-steps).
TINY = ["--population", "10", "--budget", "20000", "--validation", "3"]
CRISP_RL = ["--method", "RL", "--set", "controller.fuzzy=false"]


def tune(tmp_path: Path, *words: str) -> int:
    return main(["tune", "--task", "CartPole-v1", *TINY, "--runs-dir", str(tmp_path), *words])


def test_a_study_writes_a_preset_that_train_takes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    elite_on_2 = [
        "--set",
        "task.validation_episodes=2",
        "--set",
        "task.obs_high=[4.8, 3, 0.42, nan]",
    ]
    assert tune(tmp_path, *CRISP_RL, *elite_on_2, "--trials", "3", "--quiet") == 0
    preset = tmp_path / "tuning" / "CartPole-v1-gnp-RL.toml"
    out = capsys.readouterr().out
    assert str(preset) in out and "train with: gnp-lab train --task CartPole-v1" in out
    layer, record = read_preset(preset)
    assert record is not None
    assert (record.task, record.brain, record.trials, record.complete) == (
        "CartPole-v1",
        "gnp",
        3,
        3,
    )
    assert record.budget_env_steps == 20_000 and record.generations == 4
    assert record.run_seeds == [tuning.run_seeds(1)[0]]
    assert record.optuna_version and record.sampler_seed == 0
    text = preset.read_text(encoding="utf-8")  # layout 2: the brain's sections in [brain]
    assert "\n[brain.controller]\n" in text and "\n[brain.evolution]\n" in text
    assert "\n[brain]\n" not in text and "\n[controller]\n" not in text
    brain = layer["brain"]
    assert brain["controller"]["method"] == "RL" and brain["controller"]["fuzzy"] is False
    searched = {p.path for p in tuning.space("gnp", method="RL")} - {
        "training.epsilon_min",
        "training.alpha_min",
    }
    tables = brain | {s: table for s, table in layer.items() if s != "brain"}
    flat = {f"{s}.{k}" for s, table in tables.items() for k in table}  # the study's names
    assert searched <= flat

    run = tmp_path / "cp.h5"
    argv = ["train", "--task", "CartPole-v1", "--preset", str(preset), "--seed", "5"]
    assert main([*argv, "--out", str(run), "--quiet"]) == 0
    config = read_task_run(run).config
    assert config.brain.evolution.p_mutation == brain["evolution"]["p_mutation"]
    assert config.brain.controller.n_judgment == brain["controller"]["n_judgment"]
    assert config.training.generations == 4 and config.training.population == 10
    assert config.training.epsilon.max == layer["training"]["epsilon_max"]
    assert config.seed == 5
    bounds = layer["task"].pop("obs_high")
    assert bounds[:3] == [4.8, 3, 0.42] and bounds[3] != bounds[3]  # NaN: the space's
    assert layer["task"] == {"test_protocol": "greedy", "validation_episodes": 2,
                             "shared_episodes": False}  # fmt: skip
    assert config.task.obs_high == (4.8, 3.0, 0.42, None)
    assert config.training.test_protocol == "greedy"
    assert config.training.validation_episodes == 2

    # Rerunning a finished study trains nothing and writes the same preset.
    before = preset.read_text()
    assert tune(tmp_path, *CRISP_RL, *elite_on_2, "--trials", "3", "--quiet") == 0
    after = preset.read_text()
    strip = [line for line in before.splitlines() if not line.startswith("written")]
    assert strip == [line for line in after.splitlines() if not line.startswith("written")]


def _declared(name: str) -> tuning.Declared:
    return tuning.Declared(
        task="CartPole-v1", brain="gnp", name=name, budget=20_000, population=10, steps=500,
        seeds=1, validation=3, sampler_seed=7,
        fixed={"controller.method": "RL", "controller.fuzzy": False},
    )  # fmt: skip


def _trials(path: Path, name: str) -> list[tuple[int, str, dict[str, object], float | None]]:
    study = tuning.open_study(path, _declared(name))
    return [(t.number, t.state.name, t.params, t.value) for t in study.get_trials(deepcopy=False)]


def test_a_cut_study_resumes_to_its_declared_trials_with_the_uncut_trials(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tuning, "STARTUP_TRIALS", 1)  # TPE's own draws from the second trial
    task = TaskSettings(id="CartPole-v1")
    uncut_path, cut_path = tmp_path / "uncut.db", tmp_path / "cut.db"
    uncut = tuning.open_study(uncut_path, _declared("s"))
    tuning.run_trials(uncut, _declared("s"), task, 4)

    def cut(number: int, step: int) -> None:
        if number == 2 and step == 1:
            raise KeyboardInterrupt

    study = tuning.open_study(cut_path, _declared("s"))
    with pytest.raises((KeyboardInterrupt, Interrupted)):  # as Ctrl-C stops a run
        tuning.run_trials(study, _declared("s"), task, 4, report_hook=cut)
    assert len(tuning.finished(study)) == 2
    again = tuning.open_study(cut_path, _declared("s"))  # a new process: the same command
    tuning.run_trials(again, _declared("s"), task, 4)

    trials = _trials(cut_path, "s")
    numbers = [t[0] for t in trials]
    assert len(numbers) == len(set(numbers)) == 5
    assert [t[1] for t in trials].count("FAIL") == 1
    done = [t[2:] for t in trials if t[1] != "FAIL"]
    assert len(done) == 4
    assert done == [t[2:] for t in _trials(uncut_path, "s")]  # the same draws and values


def test_a_study_left_running_by_a_killed_process_is_failed_and_continued(
    tmp_path: Path,
) -> None:
    path = tmp_path / "s.db"
    study = tuning.open_study(path, _declared("s"))
    study.ask()  # a trial a killed process left running
    tuning.run_trials(
        tuning.open_study(path, _declared("s")), _declared("s"), TaskSettings(id="CartPole-v1"), 1
    )
    states = [t[1] for t in _trials(path, "s")]
    assert states == ["FAIL", "COMPLETE"]


def test_fracnetics_is_tuned_by_the_same_command(tmp_path: Path) -> None:
    pytest.importorskip("fracnetics")
    assert tune(tmp_path, "--brain", "fracnetics", "--trials", "2", "--quiet") == 0
    layer, record = read_preset(tmp_path / "tuning" / "CartPole-v1-fracnetics.toml")
    assert record is not None and record.brain == "fracnetics"
    assert record.budget_env_steps == 20_000 and record.generations == 4
    assert set(layer) == {"fracnetics", "training"}
    assert layer["fracnetics"]["jnf"] == 4  # its documented bounds and functions stay
    study = tuning.open_study(Path(record.storage), _fracnetics_declared())
    assert all(0 < t.user_attrs["env_steps"] <= 20_000 for t in study.trials)
    preset = str(tmp_path / "tuning" / "CartPole-v1-fracnetics.toml")
    assert main(["train", "--task", "CartPole-v1", "--preset", preset]) == 1

    # A task experiment's fracnetics arm takes the preset's [fracnetics] table.
    spec = parse(_fracnetics_spec(layer["fracnetics"]), "tuned")
    (task,) = plan(spec, "smoke", tmp_path / "runs")
    peer = PeerRun.model_validate_json(task.task_json)
    assert peer.fracnetics is not None
    assert peer.fracnetics.model_dump(mode="json") == layer["fracnetics"]
    with pytest.raises(ExperimentError, match="nodes: unknown setting"):
        parse(_fracnetics_spec({"nodes": 3}), "tuned")
    with pytest.raises(ExperimentError, match="need brain = 'fracnetics'"):
        parse(_fracnetics_spec({"jn": 2}, brain="gnp"), "tuned")


def _fracnetics_declared() -> tuning.Declared:
    return tuning.Declared(
        task="CartPole-v1", brain="fracnetics", name="CartPole-v1-fracnetics", budget=20_000,
        population=10, steps=500, seeds=1, validation=3, sampler_seed=0,
    )  # fmt: skip


def _fracnetics_spec(settings: dict[str, Any], brain: str = "fracnetics") -> dict[str, Any]:
    arm = {"name": "tuned", "label": "fracnetics, tuned", "brain": brain, "fracnetics": settings}
    return {
        "name": "tuned-fracnetics", "description": "d", "source": "test", "kind": "beyond",
        "preset": "quick", "seeds": 1, "first_seed": 40, "task": {"id": "CartPole-v1"},
        "arms": [arm],
        "comparisons": [{"name": "c", "a": "tuned", "b": "tuned", "metric": "test_return",
                         "metric_b": "final_best_return", "direction": "greater",
                         "source": "s", "family": "exploratory"}],
        "scales": {"smoke": {"config": {"training": {"population": 10, "generations": 2}}}},
    }  # fmt: skip


def _error(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("gnp-lab: error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_bad_input_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "tuning"
    folder.mkdir()
    assert main(["tune", "--task", "Nope-v0", "--runs-dir", str(tmp_path)]) == 1
    assert "unknown task 'Nope-v0'" in _error(capsys)
    assert tune(tmp_path, "--budget", "1000") == 1
    assert "holds no generation" in _error(capsys)
    assert tune(tmp_path, "--budget", "lots") == 2
    assert "--budget" in _error(capsys)
    assert tune(tmp_path, "--study", "../escape") == 1
    assert "study name '../escape'" in _error(capsys)
    assert tune(tmp_path, "--set", "training.population=5") == 1
    assert "--population" in _error(capsys)

    (folder / "junk.db").write_bytes(b"not a database at all")
    assert tune(tmp_path, "--study", "junk") == 1
    assert "not an Optuna study" in _error(capsys)
    db = sqlite3.connect(folder / "foreign.db")
    db.execute("CREATE TABLE notes (x)")
    db.commit()
    db.close()
    assert tune(tmp_path, "--study", "foreign") == 1
    assert "not an Optuna study's" in _error(capsys)
    assert sqlite3.connect(folder / "foreign.db").execute(
        "SELECT count(*) FROM sqlite_master"
    ).fetchone() == (1,)  # left as it was

    (tmp_path / "bad.toml").write_text("[tuning\n")
    argv = ["train", "--task", "CartPole-v1", "--preset", str(tmp_path / "bad.toml")]
    assert main(argv) == 1
    assert "not valid TOML" in _error(capsys)
    (tmp_path / "bad.toml").write_text('[tuning]\ntask = "CartPole-v1"\n')
    assert main(argv) == 1
    assert "[tuning]" in _error(capsys)
    (tmp_path / "bad.toml").write_text('[task]\ntest_protocol = "best"\n')
    assert main(argv) == 1
    assert "[task] test_protocol" in _error(capsys)
    assert main(["train", "--task", "CartPole-v1", "--preset", "nosuch"]) == 1
    assert "unknown preset 'nosuch'" in _error(capsys)


def test_a_study_declared_otherwise_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "tuning" / "s.db"
    path.parent.mkdir()
    tuning.open_study(path, _declared("s"))
    assert tune(tmp_path, *CRISP_RL, "--study", "s", "--trials", "1") == 1
    assert "was declared with" in _error(capsys)
    monkeypatch.setitem(space_module.SPACES, "gnp", space_module.GNP_SPACE[:-1])
    with pytest.raises(TuneError, match="searched another space"):
        tuning.open_study(path, _declared("s"))


def test_a_preset_tuned_on_another_task_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    record = TuningRecord(
        task="CartPole-v1", brain="gnp", study="s", storage="s.db", trials=1, complete=1,
        pruned=0, best_trial=0, best_value=20.0, objective="o", budget_env_steps=20_000,
        population=10, generations=4, steps=500, run_seeds=[700_000_000],
        validation_first_seed=710_000_000, validation_episodes=3, sampler="TPE",
        sampler_seed=0, pruner="median", optuna_version="5", gnp_lab_version="0", written="now",
    )  # fmt: skip
    preset = tmp_path / "p.toml"
    write_preset(preset, record, {"evolution": {"p_mutation": 0.05}})
    assert read_preset(preset) == ({"evolution": {"p_mutation": 0.05}}, record)
    assert main(["train", "--task", "Acrobot-v1", "--preset", str(preset)]) == 1
    assert "was tuned on CartPole-v1, not Acrobot-v1" in _error(capsys)
    assert main(["train", "--preset", str(preset)]) == 1
    assert "give --task CartPole-v1" in _error(capsys)


def test_a_study_searches_judgment_branches_only_when_its_judgment_is_crisp() -> None:
    crisp = {p.path for p in _declared("crisp").params()}
    assert "controller.judgment_branches" in crisp
    fuzzy = tuning.Declared(
        task="CartPole-v1", brain="gnp", name="fuzzy", budget=20_000, population=10, steps=500,
        seeds=1, validation=3, sampler_seed=7, fixed={"controller.method": "RL"},
    )  # fmt: skip  # fuzzy: the lab's default judgment
    assert {p.path for p in fuzzy.params()} == crisp - {"controller.judgment_branches"}
