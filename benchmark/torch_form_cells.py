"""Train committed spiking cells again on another device (the TTFS layers' torch form) and set
them beside the committed CPU cells (the compiled kernels):

    python benchmark/torch_form_cells.py DATA/simlidar-32c-noise0.2-physical-v1.0.0 --device cuda

For each network of ``--recipes`` (``snn_simlidar_tuned``, the dense TTFS network, and
``scnn_simlidar_tuned``, the spiking CNN), the cell ``benchmark/sweep_decisions.py`` trained
with every column on the dataset (``--seed``; the paper's protocol: all 3000 training samples,
fresh noise every epoch, 60 epochs of a cosine schedule, the last scored) is trained again on
``--device``, and the script prints one JSON line a network: test accuracy and wall seconds
there and in the committed cell, and the first epoch's training loss in both (the same batches
and noise). On a CUDA GPU the torch form's layers give the kernels' outputs bit for bit from
the same input spikes, but the input encoding's float32 ``exp`` rounds otherwise there
(``benchmark/ttfs_speed.py --device cuda`` shows both), and after the first steps the two runs
part: the accuracies are two draws of one training, not one figure twice.
docs/performance.md records the runs.
"""

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sweep_decisions import COMMITTED, committed_cell

from simlidar.script_args import integers, run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", type=Path, help="the flash dataset the committed cells name")
    parser.add_argument("--device", default="cuda", help="cuda (default), cuda:N or cpu")
    parser.add_argument("--seed", type=integers(0, 2**31 - 1, one=True), default=0)
    parser.add_argument("--recipes", default=",".join(COMMITTED), help="comma-separated")
    args = parser.parse_args()
    from simlidar.bench.hardware import resolve_device
    from simlidar.bench.train import train
    from simlidar.errors import ConfigError

    device = resolve_device(args.device)
    for name in args.recipes.split(","):
        if name not in COMMITTED:
            raise ConfigError(f"--recipes {name!r}: expected some of {list(COMMITTED)}")
        committed, recipe = committed_cell(args.dataset, name, args.seed)
        start = time.perf_counter()
        result = train(
            recipe, args.dataset, seed=args.seed, max_seconds=float("inf"), progress=False,
            device=device,
        )  # fmt: skip
        row = {
            "recipe": name,
            "device": str(device),
            "test_accuracy": result.test_accuracy,
            "seconds": round(time.perf_counter() - start, 1),
            "first_epoch_loss": result.history[0]["loss"],
            "committed_test_accuracy": committed["test_accuracy"],
            "committed_seconds": round(committed["seconds"], 1),
            "committed_first_epoch_loss": committed["history"][0]["loss"],
        }
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    run(main)
