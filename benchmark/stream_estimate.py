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
from pathlib import Path

from simlidar.bench.stream_bench import ESTIMATE, run_estimate
from simlidar.bench.stream_estimate import FAMILIES
from simlidar.errors import ConfigError
from simlidar.script_args import choices, command_line, integers, run


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--families", type=choices(FAMILIES), default=FAMILIES)
    parser.add_argument("--seeds", type=integers(0, 2**31), default=(0, 1, 2))
    args = parser.parse_args(argv)
    if args.out.exists() and not args.out.is_dir():
        raise ConfigError(f"--out {args.out}: expected a folder")
    run_estimate(
        args.dataset,
        args.out,
        args.families,
        args.seeds,
        command_line("stream_estimate.py", argv),
        note=lambda line: print(line, flush=True),
    )
    print(f"wrote {args.out / ESTIMATE}")
    return 0


if __name__ == "__main__":
    run(main)
