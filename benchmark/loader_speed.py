"""Seconds of one epoch over a split through load_split and through PulseDataset (in order,
and shuffled by a DataLoader), measured in the same run, and each one's ratio to load_split.

    python benchmark/loader_speed.py [--data DIR] [--split train] [--samples 3000] \
        [--rounds 3] [--budget-mib 512] [--json FILE]

``--data`` names a dataset directory; without it, a dataset as ``simlidar generate --classes
32 --noise 0.2 --train-size N --test-size N/5`` makes it (the paper's 3000/600 by default) is
generated into a temporary folder with the generator's Python API and removed afterwards.

Each round times three ways, in turn so that a change of load falls on all: ``load_split``
(the whole split as arrays); a new ``PulseDataset`` read sample by sample, ``ds[i]`` for every
i; a new ``PulseDataset`` through ``torch.utils.data.DataLoader(ds, batch_size=64,
shuffle=True)`` (no worker processes). Each way makes its object in the timed span, so the
split's checks, and PulseDataset's read into memory or its chunk cache, are counted, as a
user's first epoch pays them. The median of ``--rounds`` rounds after one to warm up (the
imports and the page cache). ``--budget-mib`` sets the datasets' ``memory_budget`` (0 forces
the chunk cache). docs/loading.md records the figures.
"""

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import torch

from simlidar.atomic import write_file
from simlidar.data import PulseDataset, load_split
from simlidar.dataset.loaders import MEMORY_BUDGET
from simlidar.generator.config import MAX_SPLIT_SIZE, GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.generator.profiles import DEFAULT_PROFILE, load_profile
from simlidar.resources import size_text
from simlidar.scene.recipe import load_catalog
from simlidar.script_args import command_line, in_folder, integers, run

BATCH = 64  # the shuffling DataLoader's batch
MAX_ROUNDS = 1000
WAYS = ("load_split", "in_order", "shuffled")
TITLES = {
    "load_split": "load_split",
    "in_order": "PulseDataset, ds[i] in order",
    "shuffled": f"PulseDataset, DataLoader shuffled (batch {BATCH})",
}


def make_dataset(out: Path, train: int) -> Path:
    """A dataset of ``train`` train samples and a fifth as many test (32 classes, noise 0.2,
    the default profile) generated under ``out``; its directory."""
    config = GeneratorConfig.from_profile(
        load_profile(DEFAULT_PROFILE),
        classes=32,
        noise=0.2,
        train_size=train,
        test_size=max(32, train // 5),
    )
    (written,) = generate(config, [0.2], load_catalog(), out, progress=False, preview=False)
    return written.path


def epochs(path: Path, split: str, budget: int | None, make=None) -> dict:
    """One epoch of each way (:data:`WAYS`): name -> a callable reading it all once.

    make : ``make(path, split)`` gives the dataset (default: ``PulseDataset``; another class
        to time another loader the same way); its ``memory_budget`` is set to ``budget``
        where that is not None
    """
    make = make or PulseDataset

    def dataset():
        ds = make(path, split)
        if budget is not None:
            ds.memory_budget = budget
        return ds

    def in_order():
        ds = dataset()
        for i in range(len(ds)):
            ds[i]

    def shuffled():
        generator = torch.Generator().manual_seed(0)
        loader = torch.utils.data.DataLoader(
            dataset(), batch_size=BATCH, shuffle=True, generator=generator
        )
        for _ in loader:
            pass

    return {
        "load_split": lambda: load_split(path, split),
        "in_order": in_order,
        "shuffled": shuffled,
    }


def timed(ways: dict, rounds: int) -> dict[str, float]:
    """The median seconds of each of ``ways`` over ``rounds`` rounds, the ways in turn, after
    one round to warm up."""
    times = {name: [] for name in ways}
    for r in range(rounds + 1):
        for name, way in ways.items():
            start = time.perf_counter()
            way()
            if r:
                times[name].append(time.perf_counter() - start)
    return {name: statistics.median(values) for name, values in times.items()}


def figures(path: Path, split: str, rounds: int, budget: int | None, make=None) -> dict:
    """What the script prints and writes: the split, the seconds of each way and each one's
    ratio to ``load_split``'s (``read_whole``: by the budget; a process short of memory takes
    the chunk cache whatever the budget says)."""
    x, y = load_split(path, split)
    held = x.nbytes + y.nbytes
    chosen = MEMORY_BUDGET if budget is None else budget
    seconds = timed(epochs(path, split, budget, make), rounds)
    return {
        "data": str(path),
        "split": split,
        "samples": len(y),
        "sample_shape": list(x.shape[1:]),
        "split_bytes": held,
        "memory_budget_bytes": chosen,
        "read_whole": held <= chosen,
        "rounds": rounds,
        "seconds": seconds,
        "ratio_to_load_split": {w: seconds[w] / seconds["load_split"] for w in WAYS},
    }


def report(record: dict) -> str:
    """The printed lines of ``record`` (:func:`figures`)."""
    how = "read whole" if record["read_whole"] else "chunk cache"
    lines = [
        f"{record['split']} split of {record['data']}: {record['samples']} samples of "
        f"{' x '.join(map(str, record['sample_shape']))}, {size_text(record['split_bytes'])} "
        f"of delays and labels (memory budget {size_text(record['memory_budget_bytes'])}: "
        f"{how}); median of {record['rounds']} rounds, one epoch each:"
    ]
    for way in WAYS:
        lines.append(
            f"  {TITLES[way]:<45} {record['seconds'][way]:9.4f} s  "
            f"ratio {record['ratio_to_load_split'][way]:7.2f}"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--data", type=Path, default=None, help="a dataset directory (default: generate one)"
    )
    parser.add_argument(
        "--split", choices=("train", "test"), default="train", help="the split read"
    )
    parser.add_argument(
        "--samples",
        type=integers(32, MAX_SPLIT_SIZE, one=True),
        default=3000,
        help="train samples of the generated dataset, without --data (test: a fifth)",
    )
    parser.add_argument(
        "--rounds", type=integers(1, MAX_ROUNDS, one=True), default=3, help="timed rounds"
    )
    parser.add_argument(
        "--budget-mib",
        type=integers(0, 2**40, one=True),
        default=None,
        help="PulseDataset's memory_budget in MiB (default: MEMORY_BUDGET, 512; 0: the "
        "chunk cache)",
    )
    parser.add_argument("--json", type=in_folder, default=None, help="also write the figures here")
    args = parser.parse_args(argv)
    budget = None if args.budget_mib is None else args.budget_mib * 2**20
    with tempfile.TemporaryDirectory() as tmp:
        path = args.data if args.data is not None else make_dataset(Path(tmp), args.samples)
        record = figures(path, args.split, args.rounds, budget)
    if args.data is None:
        record["data"] = f"a generated dataset, {path.name}"
    record["command"] = command_line("loader_speed.py", argv)
    record["torch"] = torch.__version__
    print(report(record))
    if args.json:
        text = json.dumps(record, indent=1) + "\n"
        write_file(args.json, lambda temporary: temporary.write_text(text), what="the figures")
    return 0


if __name__ == "__main__":
    run(main)
