"""The early-information estimate in the stream (issue 60, item 4): learners trained, as a
network answers, on what the sensor knows at any time around the object's first return, scored
at each delay after each test stream's reference time (:mod:`simlidar.bench.stream_estimate`),
written beside the networks' cells so that ``benchmark/stream_bench.py``'s report reads every
network against it.

    python benchmark/stream_estimate.py DATASET --out DIR
        [--families mlp-latest,cnn-latest,mlp-last2,cnn-last2] [--seeds 0,1,2]

Each (family, seed) learner is appended to DIR/estimate-fits.jsonl with its accuracy at every
delay of the latency grid as it finishes, and skipped when run again (resumable);
DIR/estimate.json holds, per delay, each family's seed mean and the estimate (the best
family's), from the learners trained so far.
"""

import argparse
import json
from pathlib import Path

import numpy as np

from simlidar.bench.bound import BoundConfig, train_learner
from simlidar.bench.latency import DELAYS_MS
from simlidar.bench.stream_estimate import FAMILIES, any_time, family_parts, known, view_at
from simlidar.bench.stream_task import read_cells
from simlidar.errors import ConfigError
from simlidar.script_args import choices, command_line, integers, run

FITS = "estimate-fits.jsonl"
ESTIMATE = "estimate.json"


def summarise(fits: list[dict], command: str) -> dict:
    """Per delay: each family's seed mean and seeds, the estimate and its family."""
    table = {}
    for k, d in enumerate(DELAYS_MS):
        means = {}
        for family in sorted({f["family"] for f in fits}):
            got = [f["accuracy"][k] for f in fits if f["family"] == family]
            means[family] = {"mean": float(np.mean(got)), "seeds": len(got)}
        best = max(means, key=lambda name: means[name]["mean"])
        table[f"{d:g}"] = {"families": means, "estimate": means[best]["mean"], "best": best}
    return {"command": command, "clock": "sensor time from t_reference_us", "delays": table}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--families", type=choices(FAMILIES), default=FAMILIES)
    parser.add_argument("--seeds", type=integers(0, 2**31), default=(0, 1, 2))
    args = parser.parse_args(argv)
    train, test = known(args.dataset, "train"), known(args.dataset, "test")  # before writing
    path = args.out / FITS
    fits = read_cells(path, args.dataset.name)
    if args.out.exists() and not args.out.is_dir():
        raise ConfigError(f"--out {args.out}: expected a folder")
    args.out.mkdir(parents=True, exist_ok=True)
    done = {(f["family"], f["seed"]) for f in fits}
    for family in args.families:
        model, view = family_parts(family)
        tests = [view_at(test, d, view) for d in DELAYS_MS]
        for seed in args.seeds:
            if (family, seed) in done:
                continue
            draw = any_time(train, np.random.default_rng(seed), view)
            scores, record = train_learner(draw(), train.labels, train.classes, seed,
                                           BoundConfig(model=model), draw,
                                           height=train.delays.shape[1])  # fmt: skip
            accuracy = [float((scores(x).argmax(1) == test.labels).mean()) for x in tests]
            cell = {"dataset": args.dataset.name, "family": family, "seed": seed,
                    "delays_ms": list(DELAYS_MS),
                    "accuracy": accuracy, **record}  # fmt: skip
            with path.open("a") as f:
                f.write(json.dumps(cell) + "\n")
            fits.append(cell)
            shown = ", ".join(f"{d:g} ms {a:.3f}" for d, a in zip(DELAYS_MS, accuracy))
            print(f"{family} seed {seed}: {shown}", flush=True)
    summary = summarise(fits, command_line("stream_estimate.py", argv))
    (args.out / ESTIMATE).write_text(json.dumps(summary, indent=1) + "\n")
    print(f"wrote {args.out / ESTIMATE}")
    return 0


if __name__ == "__main__":
    run(main)
