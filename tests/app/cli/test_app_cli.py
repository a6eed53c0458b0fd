"""`gnp-lab`: the happy path and every user mistake (one line, non-zero, nothing damaged)."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from lab_fixtures import file_digest, one_error_line

from app.cli import main
from app.store import BEST_OF_RUN, LAST_BEST, RunReader


@pytest.fixture
def runs_dir(tmp_path: Path, finished_run: Path) -> Path:
    runs = tmp_path / "runs"
    runs.mkdir()
    shutil.copy(finished_run, runs / "tiny.h5")
    with h5py.File(runs / "foreign.h5", "w") as handle:
        handle["data"] = np.arange(4)
    (runs / "corrupt.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(200))
    (runs / "notes.h5").write_text("hello")
    (tmp_path / "bad.toml").write_text("[training]\npopulation = 'many'\n")
    (tmp_path / "broken.toml").write_text("[training\n")
    return runs


def test_train_implement_and_inspect(runs_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = runs_dir / "new.h5"
    argv = ["train", "--population", "8", "--generations", "2", "--steps", "30", "--seed", "3"]
    argv += ["--method", "BS", "--crisp", "--noise", "20", "--out", str(out), "--workers", "1"]
    assert main([*argv, "--quiet"]) == 0
    with RunReader(out) as run:
        assert run.finished and run.seed == 3
        assert run.config.brain.controller.method == "BS" and not run.config.brain.controller.fuzzy
        assert run.config.training.noise_sigma == 20
        best = run.history().best_fitness
    # both bests, named: the run's over all generations (what `runs` lists) and the last one's
    said = capsys.readouterr().out
    at = int(best.argmax())
    assert f"{BEST_OF_RUN} {best[at]:.4f} (generation {at}); " in said
    assert f"{LAST_BEST} {best[-1]:.4f}" in said
    argv = ["implement", "new", "--runs-dir", str(runs_dir), "--break", "2,3", "--mode", "stuck"]
    argv += ["--fault-step", "10", "--steps", "40", "--repeats", "1", "--schedule", "changing"]
    assert main([*argv, "--quiet"]) == 0
    assert "implementation/break-2-3-stuck-changing" in capsys.readouterr().out
    with RunReader(out) as run:
        settings = run.implementation("break-2-3-stuck-changing").settings
        assert settings.fault_step == 10 and settings.fault_mode == "stuck"
    assert main(["runs", "--runs-dir", str(runs_dir)]) == 0
    listing = capsys.readouterr().out
    assert "new" in listing and "BS crisp" in listing and "unreadable" in listing
    assert main(["runs", "new", "--runs-dir", str(runs_dir)]) == 0
    assert "implementation break-2-3-stuck-changing" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "needles"),
    [
        (["train", "--preset", "nope"], ["unknown preset 'nope'"]),
        (["train", "--population", "1"], ["training.population", "greater than or equal to 2"]),
        (["train", "--population", "lots"], ["invalid int value: 'lots'"]),
        (["train", "--noise", "2000"], ["training.noise_sigma"]),
        (["train", "--set", "training.nope=1"], ["training.nope: unknown setting"]),
        (["train", "--set", "justakey"], ["SECTION.KEY=VALUE"]),
        (["train", "--config", "{tmp}/missing.toml"], ["config file not found"]),
        (["train", "--config", "{tmp}/bad.toml"], ["training.population"]),
        (["train", "--config", "{tmp}/broken.toml"], ["not valid TOML"]),
        (["train", "--workers", "0"], ["--workers must be at least 1"]),
        (["train", "--out", "{runs}/tiny.h5"], ["already exists"]),
        (["train", "--resume", "{runs}/tiny.h5"], ["finished run"]),
        (["train", "--resume", "{runs}/foreign.h5"], ["not a gnp-lab run"]),
        (["train", "--resume", "{runs}/corrupt.h5"], ["cannot open"]),
        (["train", "--resume", "{runs}/notes.h5"], ["not an HDF5 file"]),
        (["train", "--resume", "{runs}/missing.h5"], ["not found"]),
        (["train", "--resume", "{runs}/tiny.h5", "--population", "9"], ["drop --population"]),
        (["train", "--resume", "{runs}/tiny.h5", "--crisp"], ["drop --crisp"]),
        (["train", "--resume", "{runs}/tiny.h5", "--fuzzy"], ["drop --fuzzy"]),
        (["implement", "../tiny"], ["plain file name"]),
        (["implement", "sub/tiny"], ["plain file name"]),
        (["implement", "missing"], ["no run named 'missing'"]),
        (["implement", "foreign"], ["not a gnp-lab run"]),
        (["implement", "corrupt"], ["cannot open"]),
        (["implement", "tiny", "--break", "9"], ["sensors are numbered 0..7"]),
        (["implement", "tiny", "--break", "two"], ["sensor numbers separated by commas"]),
        (["implement", "tiny", "--name", "a/b"], ["implementation name 'a/b'"]),
        (["implement", "tiny", "--repeats", "0"], ["implementation.repeats"]),
        (["implement", "tiny", "--generation", "7"], ["generation 7 is not complete"]),
        (["runs", "../etc"], ["plain file name"]),
        (["serve", "--run", "../tiny"], ["plain file name"]),
        (["serve", "--run", "missing"], ["no run named"]),
        (["serve", "--port", "99999"], ["TCP port in 1..65535", "'99999'"]),
        (["serve", "--port", "web"], ["TCP port in 1..65535", "'web'"]),
        (["serve", "--host", "no-such-host.invalid"], ["not an address of this machine"]),
        # TEST-NET-1 (RFC 5737): no address of this machine (a bind attempt only, no traffic).
        (["serve", "--host", "192.0.2.1"], ["cannot listen on --host '192.0.2.1'"]),
        # every interface, no --allow-remote: refused, the tunnel hint names the port asked for
        (["serve", "--host", "0.0.0.0", "--port", "8123"], ["ssh -L 8123:127.0.0.1:8123"]),
    ],
)
def test_user_mistakes(
    argv: list[str],
    needles: list[str],
    tmp_path: Path,
    runs_dir: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    before = {p.name: file_digest(p) for p in runs_dir.iterdir()}
    argv = [a.replace("{tmp}", str(tmp_path)).replace("{runs}", str(runs_dir)) for a in argv]
    if argv[0] in ("implement", "runs", "serve"):
        argv += ["--runs-dir", str(runs_dir)]
    if argv[0] == "train" and "--out" not in argv and "--resume" not in argv:
        argv += ["--out", str(runs_dir / "fresh.h5")]
    assert main(argv) != 0
    one_error_line(capsys, *needles)
    assert {p.name: file_digest(p) for p in runs_dir.iterdir()} == before


def test_implementation_name_taken(runs_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["implement", "tiny", "--runs-dir", str(runs_dir), "--steps", "20", "--repeats", "1"]
    argv += ["--break", "none", "--name", "baseline", "--quiet"]
    assert main(argv) == 0
    capsys.readouterr()
    before = file_digest(runs_dir / "tiny.h5")
    assert main(argv) == 1
    one_error_line(capsys, "already has an implementation named 'baseline'")
    assert file_digest(runs_dir / "tiny.h5") == before


def test_help_for_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    for command in ("train", "implement", "runs", "serve"):
        assert main([command, "--help"]) == 0
        assert f"usage: gnp-lab {command}" in capsys.readouterr().out


def test_serve_passes_its_options_to_the_dashboard(
    monkeypatch: pytest.MonkeyPatch, runs_dir: Path
) -> None:
    import app.dashboard

    calls: list[dict[str, object]] = []
    monkeypatch.setattr(app.dashboard, "serve", lambda **kwargs: calls.append(kwargs))
    assert main(["serve", "--runs-dir", str(runs_dir), "--run", "tiny", "--port", "8123"]) == 0
    assert calls == [{"host": "127.0.0.1", "port": 8123, "runs_dir": str(runs_dir), "run": "tiny"}]


def test_a_reader_that_stops_early_gets_no_error_line() -> None:
    """`gnp-lab experiment list | head -1`: the closed pipe ends the command quietly."""
    import subprocess
    import sys

    command = [sys.executable, "-m", "app.cli", "experiment", "list"]
    with subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE) as child:
        assert child.stdout is not None and child.stderr is not None
        child.stdout.close()  # what `head` does once it has its lines: every write fails
        errors = child.stderr.read().decode()
        status = child.wait(timeout=120)
    assert status == 141
    assert errors == ""
