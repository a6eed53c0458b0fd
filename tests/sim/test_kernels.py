"""numba's cache and the robot constants."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import sim

PROBE = """
import json
import numpy as np
from sim import drive, noise, rays
spins = np.zeros(1)
drive.wheel_spins(np.array([[0.0, 1.0]]), spins)
seen = np.zeros((1, 8))
mode = np.full((1, 8), 2, dtype=np.int8)  # saturated: reads IR_MAX
noise.observe(np.zeros((1, 8)), np.zeros(1, np.uint64), np.uint64(0), 0.0, mode, seen, seen)
wall = rays.wall_table(np.array([[[40.0, -100.0], [40.0, 100.0]]]))
readings = np.zeros((1, 8))
rays.ir_readings(np.zeros((1, 3)), wall, readings)  # s2 faces the wall 12.5 mm off
print(json.dumps([float(spins[0]), float(seen[0, 0]), float(readings[0, 2])]))
"""


def probe_in_fresh_process(root: Path) -> list[float]:
    """A kernel of each kernel module, in a fresh process importing sim from root: the spin of
    a robot at commands (0, 1), a saturated sensor's reading and s2's reading of a wall."""
    done = subprocess.run(
        [sys.executable, "-c", PROBE], cwd=root, capture_output=True, text=True, check=True
    )
    return [float(x) for x in json.loads(done.stdout)]


def test_kernels_recompile_when_khepera_constants_change_under_a_warm_cache(
    tmp_path: Path,
) -> None:
    """numba keys a kernel's cache on its own file only, not on the constants it froze in."""
    shutil.copytree(
        Path(sim.__file__).parent, tmp_path / "sim", ignore=shutil.ignore_patterns("__pycache__")
    )
    before = [7.5 / 52.0, 1023.0, 1023.0 * (1.0 - 12.5 / 50.0)]
    assert probe_in_fresh_process(tmp_path) == before  # cached now
    khepera = tmp_path / "sim" / "khepera.py"
    text = khepera.read_text()
    for line in ("WHEEL_RADIUS_MM = 7.5\n", "IR_MAX = 1023.0\n"):
        assert line in text
    text = text.replace("WHEEL_RADIUS_MM = 7.5\n", "WHEEL_RADIUS_MM = 8.0\n")
    khepera.write_text(text.replace("IR_MAX = 1023.0\n", "IR_MAX = 1000.0\n"))
    after = [8.0 / 52.0, 1000.0, 1000.0 * (1.0 - 12.5 / 50.0)]
    assert probe_in_fresh_process(tmp_path) == after
    assert probe_in_fresh_process(tmp_path) == after  # and the fresh cache holds


def test_a_module_recompiles_when_a_module_its_kernels_call_changed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """numba loads a cached kernel without looking at the modules it calls: one moved away
    (sim.kernels' split) fails to load. `source_fingerprint` changes with any of them, and a
    stale frozen copy makes `drop_stale_cache` recompile every kernel of the module."""
    import types

    import numba as nb
    import numpy as np

    from sim import kernel_cache

    callee = tmp_path / "callee.py"
    callee.write_text("x = 1\n", encoding="utf-8")
    module = types.ModuleType("callee")
    module.__file__ = str(callee)
    before = kernel_cache.source_fingerprint(module, sim.khepera)
    assert before.shape == (32,) and before.dtype == np.uint8
    assert np.array_equal(before, kernel_cache.source_fingerprint(module, sim.khepera))
    callee.write_text("x = 2\n", encoding="utf-8")
    after = kernel_cache.source_fingerprint(module, sim.khepera)
    assert not np.array_equal(before, after)

    kernel = nb.njit(lambda a: a + 1)
    assert kernel(1) == 2
    recompiled: list[object] = []
    monkeypatch.setattr(
        nb.core.dispatcher.Dispatcher, "recompile", lambda self: recompiled.append(self)
    )
    frozen = iter([before, after])  # stale, then today's once recompiled
    kernel_cache.drop_stale_cache({"kernel": kernel}, lambda: next(frozen), after)
    assert recompiled == [kernel]
    recompiled.clear()
    kernel_cache.drop_stale_cache({"kernel": kernel}, lambda: after, after)
    assert recompiled == []  # up to date: nothing recompiles
    with pytest.raises(RuntimeError, match="stale cache"):
        kernel_cache.drop_stale_cache({"kernel": kernel}, lambda: before, after)
