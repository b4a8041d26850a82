"""Time one training step (forward, loss, backward, optimiser) of the spiking networks against
the conventional networks of the same shape, in one process on the same batch:

    python benchmark/ttfs_speed.py [--steps 20] [--threads N]

* ``scnn_kitti`` against ``cnn`` on a batch of 10 x 1 x 50 x 118 (KITTI front-view crops; the
  paper's batch of 10), target: the SCNN step at most 5 times the CNN step;
* ``snn_simlidar`` against ``mlp`` on a batch of 60 x 1 x 16 x 16 (Sim LiDAR; the recipes'
  batch), target: at most 3 times.

Inputs are the paper profile's kind of delays: uniform in [0, 1) with a quarter of the pixels
at 1.0 (no return), so that both the spiking and the silent paths run. Each figure is the
median over ``--steps`` steps after two warm-up steps, the two networks' steps taken in turn;
the ratio is measured in the same run, so it holds on another machine where the absolute times
do not. docs/performance.md records
the figures.
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from simlidar.bench.hardware import MAX_THREADS, check_threads
from simlidar.bench.train import batch_loss, make_optimizer
from simlidar.models.registry import build_model, load_recipe
from simlidar.models.training import TrainingConfig
from simlidar.script_args import integers, run

MAX_STEPS = 100_000  # timed steps per model

PAIRS = (  # (spiking, conventional, input shape, batch, target ratio)
    ("scnn_kitti", "cnn", (1, 50, 118), 10, 5.0),
    ("snn_simlidar", "mlp", (1, 16, 16), 60, 3.0),
)


def batch(shape, size: int, classes: int, seed: int = 0):
    generator = torch.Generator().manual_seed(seed)
    x = torch.rand(size, *shape, generator=generator)
    x[torch.rand(x.shape, generator=generator) < 0.25] = 1.0
    return x, torch.randint(0, classes, (size,), generator=generator)


def trainer(name: str, x, y, classes: int):
    """One training step of recipe ``name`` on (x, y), as a function of no arguments."""
    recipe = load_recipe(name)
    training = TrainingConfig.from_table(recipe["training"])
    model = build_model(recipe, tuple(x.shape[1:]), classes, torch.Generator().manual_seed(0))
    optimizer = make_optimizer(model.parameters(), training)

    def step():
        _, total = batch_loss(model, x, y, training)
        optimizer.zero_grad()
        total.backward()
        optimizer.step()

    return step


def step_seconds(steps: int, *trainers) -> list[float]:
    """Median seconds of a step of each trainer, their steps taken in turn (so that a change of
    load on the machine falls on all of them alike), after two warm-up rounds."""
    times = [[] for _ in trainers]
    for i in range(steps + 2):
        for step, spent in zip(trainers, times):
            start = time.perf_counter()
            step()
            if i >= 2:
                spent.append(time.perf_counter() - start)
    return [statistics.median(t) for t in times]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--steps", type=integers(1, MAX_STEPS, one=True), default=20, help="timed steps per model"
    )
    parser.add_argument(
        "--threads",
        type=integers(1, MAX_THREADS, one=True),
        default=None,
        help="torch threads (default: all)",
    )
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(check_threads(args.threads))
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads")
    for spiking, conventional, shape, size, target in PAIRS:
        x, y = batch(shape, size, 8 if spiking == "scnn_kitti" else 32)
        classes = 8 if spiking == "scnn_kitti" else 32
        snn, ann = step_seconds(
            args.steps, trainer(spiking, x, y, classes), trainer(conventional, x, y, classes)
        )
        ratio = snn / ann
        print(
            f"{spiking} {1e3 * snn:8.1f} ms, {conventional} {1e3 * ann:6.1f} ms a step "
            f"(batch {size} x {' x '.join(map(str, shape))}): ratio {ratio:.1f} "
            f"(target <= {target:g}: {'met' if ratio <= target else 'not met'})"
        )


if __name__ == "__main__":
    run(main)
