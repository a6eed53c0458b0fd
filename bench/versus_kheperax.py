"""Our training loop against Kheperax's on the same CPU: robot-steps per CPU second.

    python3.13 -m venv ../kvenv && ../kvenv/bin/pip install kheperax==0.2.0 jax==0.5.3 \
        jaxlib==0.5.3 flax==0.10.4 chex==0.1.89 orbax-checkpoint==0.11.5   # pyproject's extra
    .venv/bin/python bench/versus_kheperax.py --kheperax-python ../kvenv/bin/python \
        [--robots 300] [--steps 1000] [--rounds 3]

Measured (2026-12-04, the 2-core VM at load ~5, CPU time, 3 alternating rounds × 3 lives):
Kheperax 0.77 M robot-steps per CPU second; ours 2.47 M with box-muller-v1 noise (3.19×),
2.73 M with ziggurat-v1 (3.52×); after merging main, at load ~21: 0.79 M, 2.41 M and 2.63 M
(3.07× and 3.35×). The issue's moonshot is 5×.

Kheperax (a JAX maze task; `pip install gnp-lab[kheperax]`, best in a venv of its own: JAX is no
dependency of the lab nor of its tests) is timed as its users run it: its own
scoring function (`KheperaxTask.create_default_task` on `KheperaxConfig.get_default()`: the
standard maze, its robot with 3 lasers and 2 bumpers, an MLP policy with 8 hidden units, the
episode a `lax.scan` of `--steps` steps), `jit`-compiled, `vmap`-ped over a batch of `--robots`
policies, on the CPU build of jaxlib. Ours is `bench/limit.py`'s "rollout analytic": the lab's
training loop (thesis-ch3, σ = 50, GNP act + Sarsa, analytic physics, 8 IR rays, reward), k
steps in one compiled call, the same batch size and steps, with each noise stream.

Each side runs in its own process of its own interpreter (`--side`), compiles and warms up,
then times `--repeats` lives and prints its best as JSON; the driver alternates the sides
`--rounds` times, so a busy machine's drifts hit both alike. Rates are robot-steps per CPU
second of the process (all its threads: XLA's included), so a side that spreads over cores is
not credited for it: per-core throughput.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def kheperax_side(robots: int, steps: int, repeats: int) -> dict[str, float]:
    """Kheperax's own scoring of `robots` random MLP policies over `steps` steps."""
    import jax
    import jax.numpy as jnp
    from kheperax.tasks.config import KheperaxConfig
    from kheperax.tasks.main import KheperaxTask

    config = KheperaxConfig.get_default()
    config.episode_length = steps
    key = jax.random.key(0)
    key, subkey = jax.random.split(key)
    env, policy, scoring_fn = KheperaxTask.create_default_task(config, random_key=subkey)
    keys = jax.random.split(subkey, robots)
    params = jax.vmap(policy.init)(keys, jnp.zeros((robots, env.observation_size)))
    score = jax.jit(scoring_fn)

    def life(seed: int) -> None:
        fitness, *_ = score(params, jax.random.key(seed))
        jax.block_until_ready(fitness)

    life(1)  # compiled
    best_cpu = best_wall = float("inf")
    for r in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        life(2 + r)
        best_cpu = min(best_cpu, time.process_time() - cpu)
        best_wall = min(best_wall, time.perf_counter() - wall)
    return {"cpu": best_cpu, "wall": best_wall, "version": jax.__version__}


def ours_side(robots: int, steps: int, repeats: int, stream: str) -> dict[str, float]:
    """bench/limit.py's "rollout analytic" life of `robots` thesis-ch3 controllers."""
    sys.path.insert(0, HERE)
    import limit

    from app.settings.loading import build_config, load_preset

    config = build_config(
        load_preset("thesis-ch3").model_dump(), {"training": {"noise_sigma": 50.0}}
    )
    life = limit.record(config, robots, steps)
    run = limit.rollout_life(life, physics="analytic", noise_stream=stream)
    run()  # compiled, loaded
    best_cpu = best_wall = float("inf")
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        run()
        best_cpu = min(best_cpu, time.process_time() - cpu)
        best_wall = min(best_wall, time.perf_counter() - wall)
    return {"cpu": best_cpu, "wall": best_wall}


def kheperax_importable(python: str) -> bool:
    """Whether the interpreter `python` runs and can import kheperax."""
    try:
        probe = subprocess.run([python, "-c", "import kheperax"], capture_output=True, check=False)
    except OSError:  # no such interpreter, or not executable
        return False
    return probe.returncode == 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--kheperax-python", default="python3")
    parser.add_argument("--robots", type=int, default=300)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--side", choices=("kheperax", "box-muller-v1", "ziggurat-v1"), help=argparse.SUPPRESS
    )
    args = parser.parse_args()
    if args.side == "kheperax":
        print(json.dumps(kheperax_side(args.robots, args.steps, args.repeats)))
        return
    if args.side:
        print(json.dumps(ours_side(args.robots, args.steps, args.repeats, args.side)))
        return
    if not kheperax_importable(args.kheperax_python):
        parser.error(
            f"{args.kheperax_python} cannot import kheperax; install it in a venv of its own "
            "(see this file's docstring) and pass that venv's python as --kheperax-python"
        )
    pythons = {
        "kheperax": args.kheperax_python,
        "box-muller-v1": sys.executable,
        "ziggurat-v1": sys.executable,
    }
    best = {side: {"cpu": float("inf"), "wall": float("inf")} for side in pythons}
    for r in range(args.rounds):
        order = list(pythons) if r % 2 == 0 else list(pythons)[::-1]
        for side in order:
            command = [pythons[side], os.path.abspath(__file__), "--side", side]
            command += ["--robots", str(args.robots), "--steps", str(args.steps)]
            command += ["--repeats", str(args.repeats)]
            done = subprocess.run(command, check=True, capture_output=True, cwd=HERE)
            result = json.loads(done.stdout.decode().strip().splitlines()[-1])
            for what in ("cpu", "wall"):
                best[side][what] = min(best[side][what], result[what])
    work = args.robots * args.steps
    rate = {side: work / best[side]["cpu"] for side in pythons}
    print(
        f"{args.robots} robots × {args.steps} steps, robot-steps per CPU second (best of "
        f"{args.rounds} alternating rounds × {args.repeats} lives)"
    )
    for side in pythons:
        name = "Kheperax (jit, vmap, CPU)" if side == "kheperax" else f"ours, {side} noise"
        print(
            f"  {name:30} {rate[side]:12,.0f}   ({best[side]['cpu']:.3f} CPU s, "
            f"{best[side]['wall']:.3f} wall s)"
        )
    for side in ("box-muller-v1", "ziggurat-v1"):
        print(f"  ours ({side}) / Kheperax: {rate[side] / rate['kheperax']:.2f}×")


if __name__ == "__main__":
    main()
