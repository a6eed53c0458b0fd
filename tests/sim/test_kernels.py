"""numba's cache and the robot constants."""

import shutil
import subprocess
import sys
from pathlib import Path

import sim

SPIN = """
import numpy as np
from sim import kernels
spins = np.zeros(1)
kernels.wheel_spins(np.array([[0.0, 1.0]]), spins)
print(repr(float(spins[0])))
"""


def spin_in_fresh_process(root: Path) -> float:
    """Spin of a robot at commands (0, 1), in a fresh process importing sim from root."""
    done = subprocess.run(
        [sys.executable, "-c", SPIN], cwd=root, capture_output=True, text=True, check=True
    )
    return float(done.stdout)


def test_kernels_recompile_when_khepera_constants_change_under_a_warm_cache(
    tmp_path: Path,
) -> None:
    """numba keys its cache on sim/kernels.py only, not on the constants it froze in."""
    shutil.copytree(
        Path(sim.__file__).parent, tmp_path / "sim", ignore=shutil.ignore_patterns("__pycache__")
    )
    assert spin_in_fresh_process(tmp_path) == 7.5 / 52.0  # cached now, wheel radius 7.5 mm
    khepera = tmp_path / "sim" / "khepera.py"
    text = khepera.read_text()
    assert "WHEEL_RADIUS_MM = 7.5\n" in text
    khepera.write_text(text.replace("WHEEL_RADIUS_MM = 7.5\n", "WHEEL_RADIUS_MM = 8.0\n"))
    assert spin_in_fresh_process(tmp_path) == 8.0 / 52.0
    assert spin_in_fresh_process(tmp_path) == 8.0 / 52.0  # and the fresh cache holds
