"""Time one training step (forward, loss, backward, optimiser) of a spiking network with the
compiled TTFS kernels and with the torch form (what ``simlidar.models.ttfs`` runs off the CPU,
forced onto the CPU by ``ttfs.torch_form()``), in one process on the same batch:

    python benchmark/ttfs_torch_speed.py [--steps 20] [--threads N] [--model snn_simlidar]

By default the paper's dense network (``snn_simlidar``, 256-400-32, batch 60 x 1 x 16 x 16);
``--model scnn_kitti`` times the spiking CNN (batch 10 x 1 x 50 x 118). The batch, the recipes'
training settings and the timing (median over ``--steps`` steps after two warm-up rounds, the
two forms' steps taken in turn) are those of benchmark/ttfs_speed.py. The ratio is measured in
the same run, so it holds on another machine where the absolute times do not; the target: the
torch form at most about 20 times the kernels' step on a CPU, so that it trains on a GPU.
docs/performance.md records the figures.
"""

import argparse
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from ttfs_speed import MAX_STEPS, PAIRS, batch, step_seconds, trainer

from simlidar.bench.hardware import MAX_THREADS, check_threads
from simlidar.models import ttfs
from simlidar.script_args import integers, run

TARGET = 20.0  # the torch form's step at most this many times the kernels' on a CPU


def in_torch_form(step):
    """``step`` with the TTFS layers' torch form forced on the CPU."""

    def forced():
        with ttfs.torch_form():
            step()

    return forced


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--steps", type=integers(1, MAX_STEPS, one=True), default=20, help="timed steps per form"
    )
    parser.add_argument(
        "--threads",
        type=integers(1, MAX_THREADS, one=True),
        default=None,
        help="torch threads (default: all)",
    )
    parser.add_argument(
        "--model", choices=[p[0] for p in PAIRS], default="snn_simlidar", help="spiking recipe"
    )
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(check_threads(args.threads))
    name, _, shape, size, _ = next(p for p in PAIRS if p[0] == args.model)
    classes = 8 if name == "scnn_kitti" else 32
    x, y = batch(shape, size, classes)
    kernels, torch_form = step_seconds(
        args.steps, trainer(name, x, y, classes), in_torch_form(trainer(name, x, y, classes))
    )
    ratio = torch_form / kernels
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads")
    print(
        f"{name} (batch {size} x {' x '.join(map(str, shape))}): kernels {1e3 * kernels:.1f} ms, "
        f"torch form {1e3 * torch_form:.1f} ms a step: ratio {ratio:.1f} "
        f"(target <= {TARGET:g}: {'met' if ratio <= TARGET else 'not met'})"
    )


if __name__ == "__main__":
    run(main)
