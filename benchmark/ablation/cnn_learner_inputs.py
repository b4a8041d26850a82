"""What gives the early-information estimate's CNN learner its lead on `physical`? (issue 42)

    python benchmark/ablation/cnn_learner_inputs.py DATA/simlidar-32c-noise0.2-physical-v1.0.0 \\
        [--variants bound,no-mask,channel,no-mask-channel] [--seeds 0,1,2,3,4] \\
        [--out cnn-learner-inputs.jsonl]
    python benchmark/ablation/cnn_learner_inputs.py --summary cnn-learner-inputs.jsonl

On `physical` noise 0.2 with every spike, the estimate's CNN family (``simlidar.bench.bound.
LEARNERS["cnn"]``: the paper's CNN, fresh noise every epoch, its epochs chosen on validation
rows) scores 89.0 % on average (the scan-timed estimate, 5 seeds; this script's ``bound`` row
is the same learner on the flash twin), where the paper's CNN trained as the spiking networks are
(``benchmark/ablation/scnn_variants.py --variants relu-cnn``) scores 78.2 % and the spiking
CNN 75.8-76.3 %. The learner differs from those networks in what it is shown: a view of two
channels (each pixel's spike time, and whether it has arrived: a missing return is a 0 there)
each standardised pixel by pixel over the training rows, where a network reads the delays of
one channel as they are. This script trains that learner (every spike, near returns first, a
missing return no spike: the estimate's ``near_first/as_value`` row) on the view changed one
way at a time:

* ``bound``: the view as the estimate shows it (the variant keeps the estimate's older name);
* ``no-mask``: the arrived channel all zeros (a missing pixel then shows only the sample's
  last spike time, as a late return would);
* ``channel``: each channel standardised by one mean and deviation over every pixel, not
  pixel by pixel (``train_learner(standardise="channel")``);
* ``no-mask-channel``: both.

One JSON line a cell (variant, seed, test accuracy, validation accuracy, epochs), appended to
``--out`` as it finishes. ``--summary FILE`` prints a file's table (mean ± sample std over
seeds, the 95 % interval of the mean, Student's t).
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

from simlidar.script_args import choices, integers, run

VARIANTS = {  # name -> (the arrived channel kept, standardisation)
    "bound": (True, "pixel"),
    "no-mask": (False, "pixel"),
    "channel": (True, "channel"),
    "no-mask-channel": (False, "channel"),
}


def masked(view: np.ndarray, keep: bool) -> np.ndarray:
    """The view (N, 2, P) with its arrived channel kept, or set to zeros."""
    if keep:
        return view
    view = view.copy()
    view[:, 1] = 0.0
    return view


def cell(dataset: Path, variant: str, seed: int) -> dict:
    """The estimate's CNN learner with every spike (near first, a missing return no spike) on
    ``dataset``, the view changed as ``variant`` says, trained with ``seed``."""
    from simlidar.bench.augment import fresh_noise
    from simlidar.bench.bound import LEARNERS, arrived, spike_times, train_learner
    from simlidar.dataset.loaders import load_split, spike_threshold, split_info

    keep, standardise = VARIANTS[variant]
    attrs = split_info(dataset, "train").attrs
    (x, y), (x_test, y_test) = load_split(dataset, "train"), load_split(dataset, "test")
    no_return, height = spike_threshold(attrs), x.shape[1]
    delays = fresh_noise(dataset, attrs, seed, np.arange(len(y)))

    def view(d: np.ndarray) -> np.ndarray:
        return masked(arrived(spike_times(d, no_return), None)[0], keep)

    scores, record = train_learner(
        view(x), y, len(attrs["class_names"]), seed, LEARNERS["cnn"],
        lambda: view(delays()), height, standardise=standardise,
    )  # fmt: skip
    accuracy = float((scores(view(x_test)).argmax(1) == y_test).mean())
    return {"variant": variant, "seed": seed, "test_accuracy": accuracy, **record}


def summary(path: Path) -> str:
    """The table of a file of cells this script wrote (a file from elsewhere: read as such)."""

    def parse(row: dict):
        return str(row["variant"]), {k: float(row[k]) for k in ("seed", "test_accuracy")}

    groups = grouped_cells(path, "cnn_learner_inputs.py", "variant, seed, test_accuracy", parse,
                           str)  # fmt: skip
    lines = ["| variant | seeds | test % | 95 % interval |", "| --- | --- | --- | --- |"]
    for variant, cells in groups.items():
        test = 100 * np.array([c["test_accuracy"] for c in cells])
        low, high = interval(test) or (np.nan, np.nan)
        seeds = ", ".join(str(int(c["seed"])) for c in cells)
        lines.append(f"| {variant} | {seeds} | {spread(test)} | [{low:.2f}, {high:.2f}] |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", type=Path, nargs="?", help="a flash dataset")
    parser.add_argument("--variants", type=choices(VARIANTS), default=",".join(VARIANTS))
    parser.add_argument("--seeds", type=integers(0, 2**31 - 1), default="0,1,2,3,4")
    parser.add_argument("--out", type=Path, default=Path("cnn-learner-inputs.jsonl"))
    parser.add_argument("--summary", type=Path, help="print this file of cells' table, train none")
    args = parser.parse_args()
    if args.summary is not None:
        print(summary(args.summary))
        return
    if args.dataset is None:
        parser.error("expected a dataset directory to train on (or --summary FILE)")
    from simlidar.dataset.loaders import split_info

    split_info(args.dataset, "test")  # a dataset, or one line saying what is wrong
    if not args.out.parent.is_dir():
        parser.error(f"--out: '{args.out}': expected a file in an existing folder")
    for variant in args.variants:
        for seed in args.seeds:
            start = time.perf_counter()
            row = cell(args.dataset, variant, seed)
            row["seconds"] = round(time.perf_counter() - start, 1)
            append_cell(args.out, row)


if __name__ == "__main__":
    run(main)
