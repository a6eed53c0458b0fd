"""The compiled loop under `perf`, with numba's functions named: a per-stage profile.

    NUMBA_CACHE_DIR=$(mktemp -d) .venv/bin/python bench/profile_loop.py --lives 40 &
    perf record -F 5000 -p $(cat /tmp/profile_loop.pid) -o loop.data -- sleep 4
    perf report -i loop.data --no-children --sort symbol

Lives `bench/limit.py`'s "rollout analytic" (thesis-ch3, σ = 50, `--robots` × `--steps`) `--lives`
times after writing `/tmp/perf-<pid>.map`, which names every compiled numba function for perf:
the symbols of each function's object code (`nm`), placed where numba loaded them. numba keeps
the object code only of what it compiled in this process, so run it with an empty
NUMBA_CACHE_DIR (a few minutes of compiling; the GC passes that then show up in the profile
belong to the compiler's objects, not to the loop). Numba's reference counting shows as two
unnamed addresses in a one-page anonymous mapping (its atomic increment and decrement, compiled
at start-up). The process id is written to `--pid-file` once the map is, then the lives start
after a second. docs/speed.md reads a profile taken so.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from numba.core.registry import CPUDispatcher


def _symbols(data: bytes) -> list[tuple[int, int, str]]:
    """(offset, size, mangled name) of the functions in an object file's bytes."""
    with tempfile.NamedTemporaryFile(suffix=".o") as handle:
        handle.write(data)
        handle.flush()
        listed = subprocess.run(
            ["nm", "-S", "--defined-only", handle.name], capture_output=True, text=True, check=True
        ).stdout
    found = []
    for line in listed.splitlines():
        fields = line.split()
        if len(fields) == 4 and fields[2] in "Tt":
            found.append((int(fields[0], 16), int(fields[1], 16), fields[3]))
    return found


def write_perf_map() -> int:
    """Write /tmp/perf-<pid>.map for every numba function compiled in this process; the
    number of symbols written."""
    placed: list[tuple[int, int, str]] = []
    dispatchers = {
        id(value): value
        for module in list(sys.modules.values())
        for value in list(getattr(module, "__dict__", {}).values())
        if isinstance(value, CPUDispatcher)
    }
    for dispatcher in dispatchers.values():
        compiled: Any  # numba's CompileResult, whose fields its stubs do not name
        for compiled in dispatcher.overloads.values():
            library = compiled.library
            try:
                data = library.serialize_using_object_code()[2][0]
            except RuntimeError:  # loaded from numba's cache: no object code kept
                continue
            symbols = _symbols(data)
            entry = compiled.fndesc.llvm_func_name
            offsets = [value for value, _, name in symbols if name == entry]
            if offsets:
                base = library.get_pointer_to_function(entry) - offsets[0]
                placed += [(base + value, size, name) for value, size, name in symbols]
    names = subprocess.run(
        ["c++filt"], input="\n".join(name for *_, name in placed), capture_output=True, text=True
    ).stdout.splitlines()
    lines = [
        f"{at:x} {size:x} {name[:160]}" for (at, size, _), name in zip(placed, names, strict=True)
    ]
    Path(f"/tmp/perf-{os.getpid()}.map").write_text("\n".join(lines) + "\n")
    return len(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robots", type=int, default=300)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--lives", type=int, default=40)
    parser.add_argument("--pid-file", type=Path, default=Path("/tmp/profile_loop.pid"))
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).parent))
    import limit

    from app.settings.loading import build_config, load_preset

    config = build_config(
        load_preset("thesis-ch3").model_dump(), {"training": {"noise_sigma": 50.0}}
    )
    life = limit.record(config, args.robots, args.steps)
    run = limit.rollout_life(life, physics="analytic")
    run()  # compiled
    named = write_perf_map()
    args.pid_file.write_text(str(os.getpid()))
    time.sleep(1.0)
    began = time.process_time()
    for _ in range(args.lives):
        run()
    seconds = (time.process_time() - began) / args.lives
    print(
        f"{named} numba symbols mapped; rollout analytic {life.work / seconds:,.0f} robot-steps "
        f"per CPU second ({1e9 * seconds / life.work:.0f} ns per robot-step)"
    )


if __name__ == "__main__":
    main()
