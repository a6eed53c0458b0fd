"""`app.phases.warm.warm_up` stops at Ctrl-C or SIGTERM even when numba's compiler swallowed
the KeyboardInterrupt and went on: seen in CI, where a SIGTERM in an experiment's warm-up was
lost inside a compile, the tiny run's only generation ended without a check of the stop, and
the experiment then ran to its end with status 0."""

from __future__ import annotations

import contextlib
import signal
from pathlib import Path
from typing import Any

import pytest

from app.phases import implementation, training
from app.phases.warm import warm_up
from app.settings.config import preset_layer
from app.settings.loading import build_config
from app.system.signals import interrupted_by_signals


def swallow_a_sigterm() -> None:
    """What a compile that swallowed a SIGTERM (in an llvmlite callback) leaves: nothing."""
    with contextlib.suppress(KeyboardInterrupt):
        signal.raise_signal(signal.SIGTERM)


class Phase:
    """A stand-in for `train` or `implement`: records the run file it is given, and swallows a
    SIGTERM when told to."""

    def __init__(self, swallows: bool) -> None:
        self.swallows = swallows
        self.paths: list[Path] = []

    def __call__(self, first: Any, second: Any, **_options: Any) -> None:
        self.paths.append(Path(second if isinstance(second, Path) else first))
        if self.swallows:
            swallow_a_sigterm()


@pytest.mark.parametrize(
    ("swallowed_in", "trained", "implemented"), [("train", 1, 0), ("implement", 1, 1)]
)
def test_a_swallowed_stop_ends_the_warm_up_at_the_phase_it_came_in(
    monkeypatch: pytest.MonkeyPatch, swallowed_in: str, trained: int, implemented: int
) -> None:
    """Two controllers to warm: the stop ends the warm-up right after the phase it came in."""
    train, implement = Phase(swallowed_in == "train"), Phase(swallowed_in == "implement")
    monkeypatch.setattr(training, "train", train)
    monkeypatch.setattr(implementation, "implement", implement)
    quick = build_config(preset_layer("quick"))
    with pytest.raises(KeyboardInterrupt), interrupted_by_signals():
        warm_up([quick, quick])
    assert (len(train.paths), len(implement.paths)) == (trained, implemented)


def test_without_a_stop_every_controller_is_warmed(monkeypatch: pytest.MonkeyPatch) -> None:
    train, implement = Phase(False), Phase(False)
    monkeypatch.setattr(training, "train", train)
    monkeypatch.setattr(implementation, "implement", implement)
    quick = build_config(preset_layer("quick"))
    with interrupted_by_signals():
        warm_up([quick, quick])
    assert [p.name for p in train.paths] == ["warm0.h5", "warm1.h5"]
    assert implement.paths == train.paths
