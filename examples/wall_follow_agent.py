"""An outside agent on the wall-following task through Gymnasium, with a fault mid-episode.

    python examples/wall_follow_agent.py [--steps 1000] [--episodes 3] [--arena training]
                                         [--noise 50] [--sensors 4 5] [--mode dead]

The agent is a hand-written Braitenberg-style controller that knows nothing of GNP Lab: it keeps
a wall on the robot's right (sensors 4 and 5) at a steady reading and turns left when one looms
ahead (sensors 2 and 3). Each episode runs twice from the same seed: once healthy (the control)
and once with the named sensors breaking halfway, so the fault's cost is the difference.
"""

from __future__ import annotations

import argparse
from typing import Any

import gymnasium
import numpy as np

ENV = "sim.gym_env:GnpLab/WallFollow-v0"
"""Gymnasium's "module:id" form: make() imports the module that registers the env."""
SIDE_TARGET = 400.0
"""Reading of the right-hand side sensor the agent steers towards (about 30 mm from a wall)."""


def braitenberg(observation: np.ndarray) -> np.ndarray:
    """(left, right) wheel commands for 8 IR readings (0..1023)."""
    front = max(observation[2], observation[3], 0.8 * observation[1])
    side = max(observation[5], 0.7 * observation[4])
    if front < 50 and side < 50:  # no wall in sight: curve right until one appears
        return np.array([8.0, 5.0])
    turn = np.clip(0.012 * (side - SIDE_TARGET) + 0.02 * front, -6.0, 6.0)  # > 0: turn left
    return np.array([8.0 - turn, 8.0 + turn])


def episode(env: gymnasium.Env, seed: int, fault: dict[str, Any] | None) -> list[float]:
    """The rewards of one episode from `seed`, with `fault` as the reset option."""
    observation, _ = env.reset(seed=seed, options={"fault": fault} if fault else None)
    rewards = []
    done = False
    while not done:
        observation, reward, terminated, truncated, _ = env.step(braitenberg(observation))
        rewards.append(float(reward))
        done = terminated or truncated
    return rewards


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--arena", default="training")
    parser.add_argument("--noise", type=float, default=50.0)
    parser.add_argument("--sensors", type=int, nargs="+", default=[4, 5])
    parser.add_argument("--mode", default="dead")
    args = parser.parse_args()
    env = gymnasium.make(ENV, arena=args.arena, noise=args.noise, max_episode_steps=args.steps)
    fault_step = args.steps // 2
    fault = {"sensors": args.sensors, "mode": args.mode, "step": fault_step}
    print(
        f"{args.arena} arena, σ = {args.noise:g}, {args.steps} steps; sensors "
        f"{' '.join(map(str, args.sensors))} {args.mode} from step {fault_step}"
    )
    costs = []
    for seed in range(args.episodes):
        healthy = episode(env, seed, None)
        broken = episode(env, seed, fault)
        after, control = sum(broken[fault_step:]), sum(healthy[fault_step:])
        costs.append(control - after)
        print(
            f"episode {seed}: return {sum(broken):.3f}; before the fault "
            f"{sum(broken[:fault_step]):.3f}, after the fault {after:.3f} "
            f"(healthy control {control:.3f})"
        )
    print(
        f"mean cost of the fault {np.mean(costs):.3f} reward over {args.steps - fault_step} steps"
    )
    env.close()


if __name__ == "__main__":
    main()
