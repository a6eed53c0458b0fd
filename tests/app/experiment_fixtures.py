"""A tiny experiment for the experiment tests: 2 arms, 2 seeds, 3 conditions, seconds to run."""

from __future__ import annotations

import copy
import json
import tomllib
from pathlib import Path
from typing import Any

from app.experiments.cluster import NO_DASHBOARD

TINY_TOML = """
name = "tiny"
description = "BS vs RL, tiny"
source = "tests"
preset = "thesis-ch3"
seeds = 2

[config.training]
noise_sigma = 50.0
[config.implementation]
noise_sigma = 50.0
broken_sensors = []

[[arms]]
name = "BS"
label = "Fuzzy GNP-TSRL (BS)"
config = { controller = { method = "BS" } }

[[arms]]
name = "RL"
label = "Fuzzy GNP-RL"
config = { controller = { method = "RL" } }

[[conditions]]
name = "break-1"
label = "1 random sensor"
implementation = { break_count = 1 }

[[conditions]]
name = "fixed-2-3"
label = "sensors 2 and 3"
implementation = { broken_sensors = [2, 3] }

[[conditions]]
name = "no-fault"
label = "no fault"

[[comparisons]]
name = "fitness"
a = "BS"
b = "RL"
metric = "final_best_fitness"
direction = "greater"
source = "Fig. 3.6"

[[comparisons]]
name = "after-1"
a = "BS"
b = "RL"
metric = "mean_reward_after_fault"
condition = "break-1"
direction = "greater"
source = "Fig. 3.7"

[[comparisons]]
name = "BS-fault-hurts"
a = "BS"
b = "BS"
metric = "mean_reward"
condition = "fixed-2-3"
condition_b = "no-fault"
direction = "less"
source = "Fig. 5.6"

[[thesis]]
arm = "BS"
metric = "mean_reward"
condition = "break-1"
value = 0.158
source = "Table 4.3 (for the test)"

[scales.smoke.config.training]
population = 12
generations = 3
steps = 60
shard_size = 5
[scales.smoke.config.implementation]
steps = 100
fault_step = 40
repeats = 1
recorded_trials = 1

[scales.small]
seeds = 2
[scales.small.config.training]
population = 12
generations = 14
steps = 1000  # long enough generations for a test to catch a run mid-training
shard_size = 5
[scales.small.config.implementation]
steps = 100
fault_step = 40
repeats = 1
recorded_trials = 1
"""


COPY_ARM = """
[[arms]]
name = "{name}"
label = "Fuzzy GNP-TSRL (BS), copy {name}"
config = {{ controller = {{ method = "BS" }} }}
"""
CALM_AND_BREAK_1 = """
[[conditions]]
name = "calm"
label = "no fault"

[[conditions]]
name = "break-1"
label = "1 random sensor"
implementation = { break_count = 1 }
"""
SMOKE_SECONDS = """
[scales.smoke.config.training]
population = 6
generations = 2
steps = 40
shard_size = 3
[scales.smoke.config.implementation]
steps = 60
fault_step = 20
repeats = 1
recorded_trials = 1
"""


def copies_toml(name: str, arms: str, comparisons: str, control: str | None = None) -> str:
    """An experiment whose arms (one letter each) are copies of one BS arm, so that every seed
    gives every arm the same values (Δ = 0 exactly between any two): conditions "calm" and
    "break-1", the given comparisons, a smoke scale of seconds."""
    head = f'''
name = "{name}"
description = "{len(arms)} copies of one arm"
source = "tests"
preset = "thesis-ch3"
seeds = 2
'''
    if control is not None:
        head += f'control = "{control}"\n'
    head += "\n[config.implementation]\nbroken_sensors = []\n"
    arms_text = "".join(COPY_ARM.format(name=arm) for arm in arms)
    return head + arms_text + CALM_AND_BREAK_1 + comparisons + SMOKE_SECONDS


def tiny_data() -> dict[str, Any]:
    """The tiny experiment as a fresh dict (to mutate into bad files)."""
    return copy.deepcopy(tomllib.loads(TINY_TOML))


def write_tiny(folder: Path, text: str = TINY_TOML) -> Path:
    path = folder / "tiny.toml"
    path.write_text(text, encoding="utf-8")
    return path


def to_toml(data: dict[str, Any]) -> str:
    """A minimal TOML writer for experiment dicts (tables, arrays of tables, inline values)."""
    lines: list[str] = []

    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, dict):
            return "{ " + ", ".join(f'"{k}" = {value(x)}' for k, x in v.items()) + " }"
        if isinstance(v, list | tuple):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    def is_tables(v: Any) -> bool:
        return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)

    def table(prefix: str, d: dict[str, Any]) -> None:
        # plain keys first: after a [[table]] header they would belong to that table
        lines.extend(
            f'"{k}" = {value(v)}' for k, v in d.items() if not (is_tables(v) or isinstance(v, dict))
        )
        for k, v in d.items():
            if is_tables(v):
                for item in v:
                    lines.append(f"[[{prefix}{k}]]")
                    lines.extend(f'"{kk}" = {value(vv)}' for kk, vv in item.items())
        for k, v in d.items():
            if isinstance(v, dict):
                lines.append(f'[{prefix}"{k}"]')
                table(f'{prefix}"{k}".', v)

    table("", data)
    return "\n".join(lines) + "\n"


def in_process_client() -> Any:
    """A Dask client of one worker in this process, running one task at a time.

    One task thread, as a production worker has (a process of one thread): two task threads
    of one process writing run files take turns at h5py's global lock, and a full suite once
    hung there (a task thread waiting for the lock while no thread was inside h5py).
    """
    from distributed import Client

    return Client(processes=False, n_workers=1, threads_per_worker=1, **NO_DASHBOARD)
