"""Train a tiny run from Python: a config from a preset plus overrides, then `train`.

    python examples/train_tiny_run.py OUT.h5

The same config and seed give the same file data, whatever the number of workers.
"""

import sys
from pathlib import Path

from app.phases.training import GenerationSummary, train
from app.settings.config import preset_layer
from app.settings.loading import build_config


def main(out: Path) -> None:
    config = build_config(
        preset_layer("quick"),
        {
            "seed": 3,
            "brain": {"controller": {"method": "BS"}},
            "training": {"population": 12, "generations": 3, "steps": 80, "noise_sigma": 50},
        },
    )

    def progress(summary: GenerationSummary) -> None:
        print(f"generation {summary.generation}: best fitness {summary.best_fitness:.6f}")

    train(config, out, workers=1, progress=progress)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
