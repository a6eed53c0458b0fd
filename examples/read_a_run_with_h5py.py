"""Read a run file with plain h5py: no GNP Lab code needed (docs/run-format.md).

python examples/read_a_run_with_h5py.py RUN.h5

A robot's run and a Gymnasium task's share the format; a task run's root attribute `kind` says
"task" (a robot run's file has none), and its fitness is an episode's return.
"""

import json
import sys

import h5py

with h5py.File(sys.argv[1], "r", swmr=True) as run:
    config = json.loads(run.attrs["config"])
    done = int(run["progress/generations_done"][()])
    best = run["generations/best_fitness"][:done]
    brain = config.get("brain", config)  # files before issue #46 keep GNP's sections at the top
    family = brain.get("family", "gnp")
    about = brain["controller"]["method"] if family == "gnp" else family
    print(f"method {about}, seed {run.attrs['seed']}")
    if run.attrs.get("kind", "robot") == "task":
        print(f"task {config['task']['id']}")
    print(f"generations done {done}, best fitness {best.max():.6f}")
    for name, group in run.get("implementation", {}).items():  # a robot run's, once implemented
        print(f"implementation {name}: mean reward {group.attrs['mean_reward']:.6f}")
