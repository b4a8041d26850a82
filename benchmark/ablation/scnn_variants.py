"""Which change to the spiking CNN closes its gap to the CNN learner on `physical`? (issue 42)

    python benchmark/ablation/scnn_variants.py DATA/simlidar-32c-noise0.2-physical-v1.0.0 \\
        --variants cnn-shape,e120 --seeds 0,1,2 [--device cuda] [--out scnn-variants.json]
    python benchmark/ablation/scnn_variants.py DATA/simlidar-32c-noise0.2-physical-v1.0.0 \\
        --recipe snn_simlidar_tuned --variants tuned,no-return-channel --seeds 0,1,2,3,4
    python benchmark/ablation/scnn_variants.py --summary scnn-variants.json   # the table

On `physical` noise 0.2 the spiking CNN ``scnn_simlidar_tuned`` with every column scores
76.33 % (5 seeds, ``benchmark/results/sweep-decisions-scnn/``) where the early-information
estimate's CNN family (the paper's CNN with the same fresh noise) scores 89.0 % on average and
92.2 % as an ensemble (docs/snn.md). This script trains variants of that network, each changing
one thing, under the committed cells' protocol (``sweep_decisions.committed_cell``: every
training row, a fresh noise draw every epoch, the cosine schedule's last epoch scored):

* ``cnn-shape``: the CNN family's layers (48 channels of 5x5 stride 2, 24 of 5x5 stride 2,
  dense 256) as TTFS layers, the rest of the recipe unchanged;
* ``e120``: 120 epochs instead of 60;
* ``wide``: 96 channels in both convolutions and a dense layer of 800;
* ``tuned``: the recipe as committed (the reference, on the same device);
* ``relu-cnn``: the control of ``cnn-shape``: the same layers with ReLU, the paper's CNN
  baseline (``baselines/cnn.toml``: Adam 1e-3), trained under the same protocol (every training
  row, a fresh noise draw every epoch, 60 epochs of a cosine schedule, the last scored), so
  that ``cnn-shape`` and ``relu-cnn`` differ in the neuron and its training terms only;
* ``no-return-channel``: a missing return is an input spike of a channel of its own at the
  window's end (``missing = "own_channel"``, :func:`simlidar.models.ttfs.encode`), where the
  committed network gets no spike: the arrived-or-not channel of the estimate's view, which is
  worth 6-7 points to the CNN learner (``benchmark/ablation/cnn_learner_inputs.py``).

``--recipe snn_simlidar_tuned`` trains the dense network's committed cells
(``benchmark/results/sweep-decisions/``) instead, with the variants that apply to it
(``tuned``, ``e120``, ``no-return-channel``).

One JSON line a cell (variant, seed, device, test accuracy, the accuracy on the train split as
stored, that is on the file's own noise draw, which no epoch trained on: how well the network
fits its training scenes; seconds, the first epoch's loss), appended to ``--out`` as it
finishes, so an interrupted run keeps what it trained. ``--summary FILE`` prints such a file's
table: per variant and device, the seeds, the test and train accuracy (mean ± sample std over
seeds, the test's 95 % interval of the mean, Student's t) and the gap between the two. On a GPU the
spiking layers run their torch form: the same decisions as the CPU kernels from the same input
spikes, but not the committed cells' bytes (docs/performance.md, "Training on the GPU"); the
committed cells stay the CPU's.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from cell_files import append_cell, grouped_cells, spread
from paper_table import interval
from sweep_decisions import committed_cell

from simlidar.script_args import choices, integers, run

VARIANTS = {  # name -> (architecture overrides, training overrides)
    "tuned": ({}, {}),
    "cnn-shape": ({"conv": [[48, 5, 2], [24, 5, 2]], "dense": [256]}, {}),
    "e120": ({}, {"epochs": 120}),
    "wide": ({"conv": [[96, 3, 1], [96, 3, 2]], "dense": [800]}, {}),
    "relu-cnn": None,  # the paper's CNN under the committed cells' protocol (relu_control)
    "no-return-channel": ({"missing": "own_channel"}, {}),
}
RECIPE = "scnn_simlidar_tuned"
DENSE = "snn_simlidar_tuned"  # the dense network: the variants that change no layer shape
DENSE_VARIANTS = ("tuned", "e120", "no-return-channel")


def relu_control(spiking: dict) -> dict:
    """The paper's CNN (``baselines/cnn.toml``, its optimiser and rate) trained as the spiking
    recipe ``spiking`` is: no validation rows, fresh noise every epoch, its epochs on a cosine
    schedule, the last scored."""
    from simlidar.models.registry import load_recipe

    recipe = load_recipe("cnn")
    protocol = ("validation", "noise_augment", "lr_schedule", "epochs", "batch_size")
    recipe["training"].update({key: spiking["training"][key] for key in protocol})
    return recipe


def variant_recipe(dataset: Path, name: str, network: str = RECIPE) -> dict:
    """The committed cell's recipe of ``network`` (seed 0's: every seed's is the same) with the
    variant's overrides."""
    from simlidar.errors import ConfigError

    if network == DENSE and name not in DENSE_VARIANTS:
        raise ConfigError(f"variant {name!r}: expected one of {list(DENSE_VARIANTS)} for {DENSE}")
    _, recipe = committed_cell(dataset, network, 0)
    if VARIANTS[name] is None:
        return relu_control(recipe)
    architecture, training = VARIANTS[name]
    recipe["architecture"].update(architecture)
    recipe["training"].update(training)
    return recipe


def train_accuracy(result, dataset: Path) -> float:
    """The trained network's accuracy on the train split as stored (the file's noise draw)."""
    import torch

    from simlidar.bench.scoring import predictions
    from simlidar.dataset.loaders import load_split

    x, y = (torch.from_numpy(a) for a in load_split(dataset, "train"))
    spec, silent_from = result.spec, result.silent_from
    return (
        (predictions(result.model, x[:, None], spec=spec, silent_from=silent_from) == y)
        .float()
        .mean()
        .item()
    )


def summary(path: Path) -> str:
    """The table of a file of cells this script wrote (a file from elsewhere: read as such)."""

    def parse(row: dict):
        cell = {k: float(row[k]) for k in ("seed", "test_accuracy")}
        cell["train_accuracy"] = float(row.get("train_accuracy", np.nan))  # older cells: none
        return (str(row.get("recipe", RECIPE)), str(row["variant"]), str(row["device"])), cell

    groups = grouped_cells(
        path, "scnn_variants.py", "variant, device, seed, test_accuracy, train_accuracy", parse,
        lambda key: f"{key[1]} ({key[0]}, {key[2]})",
    )  # fmt: skip
    lines = [
        "| network | variant | device | seeds | test % | 95 % interval | train % (the file's "
        "draw) | train - test |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for (network, variant, device), cells in groups.items():
        test = 100 * np.array([c["test_accuracy"] for c in cells])
        train = 100 * np.array([c["train_accuracy"] for c in cells])
        low, high = interval(test) or (np.nan, np.nan)
        seeds = ", ".join(str(int(c["seed"])) for c in cells)
        lines.append(
            f"| {network} | {variant} | {device} | {seeds} | {spread(test)} | "
            f"[{low:.2f}, {high:.2f}] | {spread(train)} | {_gap(train, test)} |"
        )
    return "\n".join(lines)


def _gap(train: np.ndarray, test: np.ndarray) -> str:
    """Train minus test accuracy by the means; a dash without train accuracies."""
    return "-" if np.isnan(train).any() else f"{train.mean() - test.mean():+.2f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", type=Path, nargs="?",
                        help="the flash dataset of the committed cells")  # fmt: skip
    parser.add_argument("--variants", type=choices(VARIANTS), default="cnn-shape,e120")
    parser.add_argument("--recipe", choices=(RECIPE, DENSE), default=RECIPE,
                        help="the network whose committed cells are varied")  # fmt: skip
    parser.add_argument("--seeds", type=integers(0, 2**31 - 1), default="0,1,2")
    parser.add_argument("--device", default="auto", help="auto (default), cpu, cuda, cuda:N")
    parser.add_argument("--epochs", type=integers(1, 10_000, one=True), default=None,
                        help="override every variant's epochs (a quick check)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=Path("scnn-variants.json"))
    parser.add_argument("--summary", type=Path, help="print this file of cells' table, train none")
    args = parser.parse_args()
    if args.summary is not None:
        print(summary(args.summary))
        return
    if args.dataset is None:
        parser.error("expected a dataset directory to train on (or --summary FILE)")
    from simlidar.bench.hardware import resolve_device
    from simlidar.bench.train import train

    device = resolve_device(args.device)
    recipes = {name: variant_recipe(args.dataset, name, args.recipe) for name in args.variants}
    for name in args.variants:
        for seed in args.seeds:
            start = time.perf_counter()
            result = train(recipes[name], args.dataset, seed=seed, epochs=args.epochs,
                           max_seconds=float("inf"), progress=False, device=device)  # fmt: skip
            seconds = round(time.perf_counter() - start, 1)  # training and the test, as before
            row = {
                "recipe": args.recipe,
                "variant": name,
                "seed": seed,
                "device": str(device),
                "epochs": args.epochs or recipes[name]["training"]["epochs"],
                "test_accuracy": result.test_accuracy,
                "train_accuracy": train_accuracy(result, args.dataset),
                "seconds": seconds,
                "first_epoch_loss": result.history[0]["loss"],
            }
            append_cell(args.out, row)


if __name__ == "__main__":
    run(main)
