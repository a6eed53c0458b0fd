"""Any brain family on a Gymnasium task (#46 item 2): CMA-ES and NEAT nets train, resume to the
bit, replay, list and export through `gnp-lab`, and the generic lives are checked against an
episode lived by hand with Gymnasium's single env."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import h5py
import numpy as np
import pytest
from lab_fixtures import assert_same_data, finish, gnp_lab

import gnp
import neuro
import sim
from app.brains.nets import CmaesFamily
from app.brains.registry import load_controller
from app.loop.seeds import life_seeds
from app.phases.generations import Control, Interrupted
from app.settings.loading import build_config
from app.tasks.common import TaskError
from app.tasks.config import TaskRunConfig, TaskSettings
from app.tasks.gnp_lives import live as gnp_live
from app.tasks.lives import BatchEnv, generic_lives
from app.tasks.store import read_task_run
from app.tasks.training import first_population, replay_task, train_task

SIZES = ("--population", "8", "--generations", "3", "--steps", "60", "--seed", "5")


def _config(family: str, task: str = "CartPole-v1", **training: Any) -> TaskRunConfig:
    sizes = {"population": 8, "generations": 3, "steps": 60} | training
    run = build_config({"seed": 5, "brain": {"family": family}, "training": sizes})
    return TaskRunConfig.from_run_config(run, TaskSettings(id=task))


@pytest.fixture(scope="module", params=["cmaes", "neat"])
def runs(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`whole.h5` trained by `gnp-lab`; `cut.h5` of the same config cut after its first
    generation (in this process) and resumed by `gnp-lab`."""
    family = request.param
    folder = tmp_path_factory.mktemp(family)
    whole, cut = folder / "whole.h5", folder / "cut.h5"
    argv = ("train", "--task", "CartPole-v1", "--brain", family, *SIZES)
    code, err = finish(gnp_lab(*argv, "--out", whole, "--quiet"))
    assert code == 0, err
    config = read_task_run(whole).config
    assert config == _config(family)  # what the command line made of its options
    control = Control()

    def stop_after_the_first(summary: Any) -> None:
        if summary.generation == 0:
            control.stop()

    with pytest.raises(Interrupted):
        train_task(config, cut, progress=stop_after_the_first, control=control)
    assert read_task_run(cut).generation_done == 1
    code, err = finish(gnp_lab("train", "--resume", cut, "--quiet"))
    assert code == 0, err
    return folder


def test_a_cut_run_resumed_equals_one_never_cut_in_every_dataset(runs: Path) -> None:
    assert_same_data(runs / "whole.h5", runs / "cut.h5")
    run = read_task_run(runs / "cut.h5")
    assert run.generation_done == 3 and run.fitness.shape == (3, 8)
    assert np.isnan(run.epsilon).all() and np.isnan(run.alpha).all()  # no online learning
    family = run.config.family
    with h5py.File(runs / "cut.h5", "r") as handle:
        stored = {name: handle["genomes/best"][name].shape[1:] for name in handle["genomes/best"]}
    assert stored == {name: shape for name, (shape, _) in family.genome_layout.items()}
    assert family.network_config is not None
    assert (family.network_config.n_inputs, family.network_config.n_outputs) == (4, 1)


def test_the_elite_replayed_from_its_training_episode_gets_its_training_return(
    runs: Path,
) -> None:
    path = runs / "whole.h5"
    run = read_task_run(path)
    g = run.generation_done - 1
    best = int(np.argmax(run.fitness[g]))
    episode = int(life_seeds(run.config.seed, g, np.array([best]), 1, 1).world[0])
    assert replay_task(path, episode).episode_return == run.fitness[g, best]
    process = gnp_lab("replay", "whole", "--runs-dir", runs, "--seed", str(episode))
    out, err = process.communicate(timeout=240)
    assert process.returncode == 0, err.decode()
    assert out.decode().startswith(f"return {run.fitness[g, best]:.1f} in ")


def test_runs_and_inspect_describe_the_family(runs: Path) -> None:
    family = read_task_run(runs / "whole.h5").config.brain.family
    listing = gnp_lab("runs", "--runs-dir", runs)
    out, _ = listing.communicate(timeout=240)
    assert f"task CartPole-v1 ({family})" in out.decode()
    inspect = gnp_lab("runs", "whole", "--runs-dir", runs)
    out, _ = inspect.communicate(timeout=240)
    lines = out.decode().splitlines()
    assert lines[0].startswith("task run whole.h5: CartPole-v1, seed 5")
    assert lines[1].startswith(f"brain: {family}: ")
    assert "ε" not in lines[3]  # no ε/α of a family that does not learn them


def test_export_writes_a_controller_the_family_reads_back(runs: Path, tmp_path: Path) -> None:
    out = tmp_path / "export"
    code, err = finish(gnp_lab("export", "whole", "--runs-dir", runs, "--out", out))
    assert code == 0, err
    run = read_task_run(runs / "whole.h5")
    controller = load_controller(out / "controller.json")
    best = run.best_arrays()
    assert controller.settings["task"]["id"] == "CartPole-v1"  # type: ignore[union-attr]
    assert controller.settings["fitness"] == run.fitness[-1].max()  # type: ignore[union-attr]
    assert "epsilon" not in controller.settings  # type: ignore[union-attr]
    assert controller.net == run.config.family.network_config  # type: ignore[union-attr]
    for name, value in best.items():
        np.testing.assert_array_equal(controller.arrays[name], value)  # type: ignore[union-attr]
    assert (out / "fitness.csv").read_text(encoding="utf-8").count("\n") == 3 + 1


def _by_hand(config: TaskRunConfig, arrays: dict[str, np.ndarray], seed: int) -> float:
    """One episode of a net with Gymnasium's single env, step by step: the adapter's readings
    in, the net's outputs as commands, the adapter's actions out."""
    adapter, net = config.adapter, config.family.network_config
    assert net is not None
    env = gym.make(config.task.id)
    obs, _ = env.reset(seed=seed)
    state = neuro.init_state(net, 1)
    total = 0.0
    for _ in range(config.training.steps):
        outputs = neuro.step(net, arrays, state, adapter.observe(obs[None]) / sim.IR_MAX)
        action = adapter.act(outputs * sim.MAX_COMMAND)[0]
        obs, reward, terminated, truncated, _ = env.step(action)
        total += float(reward)
        if terminated or truncated:
            break
    env.close()
    return total


@pytest.mark.parametrize(("family", "task"), [("neat", "CartPole-v1"), ("cmaes", "Pendulum-v1")])
def test_generic_lives_are_episodes_lived_by_hand(family: str, task: str) -> None:
    config = _config(family, task, steps=40)
    individuals = first_population(config)
    seeds = [3 + 11 * i for i in range(8)]
    got = replay_lives(config, individuals, seeds)
    for i, seed in enumerate(seeds):
        one = config.family.take(individuals, [i])
        assert got.returns[i] == _by_hand(config, one, seed)
    if task == "CartPole-v1":
        assert len(set(got.lengths.tolist())) > 1  # episodes ended apart


def replay_lives(config: TaskRunConfig, individuals: Any, seeds: list[int]) -> Any:
    env = BatchEnv(config.task.id, len(seeds), config.adapter, twins=False)
    try:
        return generic_lives(
            config.family, config.adapter, env, individuals, np.array(seeds),
            np.array(seeds, np.uint64), float("nan"), float("nan"), config.training.steps,
        )  # fmt: skip
    finally:
        env.close()


@pytest.mark.parametrize(("task", "steps"), [("Pendulum-v1", 30), ("CartPole-v1", 200)])
def test_gnp_through_the_generic_lives_learns_as_through_its_own(task: str, steps: int) -> None:
    """GNP's own lives (a subset as episodes end, the terminal update) and the contract's path
    (every controller every step, a learner kept as its episode ended, `TerminalLearner`'s
    update) are the same lives: on Pendulum no episode terminates and all end at the cap, on
    CartPole they terminate apart."""
    config = TaskRunConfig(seed=2, task=TaskSettings(id=task))
    config = config.model_copy(
        update={"training": config.training.model_copy(update={"steps": steps, "population": 6})}
    )
    pop = first_population(config)
    seeds = np.arange(6) * 7 + 1
    env = BatchEnv(task, 6, config.adapter, twins=False)
    try:
        own = gnp_live(
            config.gnp_config(), config.adapter, env, pop, seeds, seeds + 1, 0.2, 0.3, steps
        )
        generic = generic_lives(
            config.family, config.adapter, env, pop, seeds, (seeds + 1).astype(np.uint64),
            0.2, 0.3, steps,
        )  # fmt: skip
    finally:
        env.close()
    np.testing.assert_array_equal(own.returns, generic.returns)
    if task == "CartPole-v1":
        assert len(set(own.lengths.tolist())) > 1 and own.lengths.max() < steps  # apart
    for name, value in gnp.population_to_arrays(own.learned).items():
        np.testing.assert_array_equal(getattr(generic.learned, name), value, err_msg=name)
    assert not np.array_equal(generic.learned.q_ss, pop.q_ss)  # it learned; pop left alone
    assert not pop.q_ss.any()


def test_a_net_trains_on_a_box_action_task(tmp_path: Path) -> None:
    out = tmp_path / "pendulum.h5"
    argv = ("train", "--task", "Pendulum-v1", "--brain", "cmaes", "--population", "6")
    code, err = finish(gnp_lab(*argv, "--generations", "2", "--steps", "20", "--out", out))
    assert code == 0, err
    run = read_task_run(out)
    assert run.fitness.shape == (2, 6) and np.all(run.fitness < 0)  # Pendulum's costs
    family = run.config.family
    net = family.network_config
    assert net is not None and (net.n_inputs, net.n_outputs) == (3, 1)
    seed = 4
    arrays = run.best_arrays()
    assert replay_task(out, seed).episode_return == _by_hand(run.config, arrays, seed)


def test_an_unknown_family_and_one_that_cannot_size_itself_are_one_line(tmp_path: Path) -> None:
    out = tmp_path / "x.h5"
    code, err = finish(gnp_lab("train", "--task", "CartPole-v1", "--brain", "nope", "--out", out))
    assert code == 1 and err.count("\n") == 1, err
    assert err.startswith("gnp-lab: error: ") and "unknown brain family 'nope'" in err
    assert not out.exists()
    config = _config("cmaes")
    robot_only = type("RobotOnly", (CmaesFamily,), {"any_io": False})
    with pytest.raises(ValueError, match="runs on the robot only") as raised:
        robot_only(config.run_config(), config.io)
    assert "\n" not in str(raised.value)
    stored = json.loads(config.model_dump_json()) | {"brain": {"family": "nope"}}
    with pytest.raises(TaskError, match="CartPole-v1: unknown brain family 'nope'"):
        _ = TaskRunConfig.model_validate(stored).family


def test_a_task_experiment_trains_and_tests_a_net_arm(tmp_path: Path) -> None:
    from experiment_fixtures import in_process_client
    from test_peer import _spec

    from app.experiments.runner import RunOptions, run_experiment
    from app.experiments.spec_loading import parse

    data = _spec()
    data["task"]["test_protocol"] = "greedy"
    data["arms"][0] = {"name": "GNP", "label": "CMA-ES", "config": {"brain": {"family": "cmaes"}}}
    data["comparisons"][1]["metric"] = "test_return_as_trained"
    with in_process_client() as client:
        options = RunOptions(client=client, quiet=True)
        results = run_experiment(parse(data, "tiny"), "smoke", tmp_path, options=options)
    greedy = results.scalar("test_return_greedy", "GNP")
    assert np.isfinite(greedy).all()  # a net's protocols are the same lives
    np.testing.assert_array_equal(greedy, results.scalar("test_return_as_trained", "GNP"))
    run = read_task_run(next(tmp_path.rglob("GNP-seed40.h5")))
    assert run.config.brain.family == "cmaes" and np.isnan(run.epsilon).all()


def test_a_best_individual_not_of_the_familys_layout_is_one_run_file_error(tmp_path: Path) -> None:
    from app.store import RunFileError

    path = train_task(_config("cmaes", generations=1, population=4, steps=10), tmp_path / "c.h5")
    with h5py.File(path, "r+") as handle:
        del handle["genomes/best/w_in"]
        handle["genomes/best/w_in"] = np.zeros((1, 3, 3))
    with pytest.raises(RunFileError, match=r"genome array w_in must be \(1, 8, 4\)") as raised:
        read_task_run(path).best_individual()
    assert "\n" not in str(raised.value)
