"""Samples per second of ``simlidar generate`` with one worker process and with several, in one
run on the same configuration, and their ratio:

    python benchmark/generation_workers.py [--samples 60000] [--workers 2] [--rounds 2]

Each round generates the dataset once with ``--workers 1`` and once with ``--workers N`` (in
turn, so that a change of load falls on both) into a temporary folder, and checks that both
wrote the same bytes. Target (issue "Scale out"): ``--workers 2`` at least 1.8 times the samples
per second of ``--workers 1`` on the 2-core machine. docs/performance.md records the figures.
"""

import argparse
import hashlib
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from simlidar.bench.hardware import MAX_THREADS
from simlidar.generator.config import MAX_SPLIT_SIZE, GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.scene.recipe import load_catalog
from simlidar.script_args import integers, run

MAX_ROUNDS = 1000


def digest(path: Path) -> str:
    h = hashlib.sha256()
    for file in sorted(path.iterdir()):
        h.update(file.name.encode() + file.read_bytes())
    return h.hexdigest()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--samples",
        type=integers(1, MAX_SPLIT_SIZE, one=True),
        default=60_000,
        help="train + test samples",
    )
    parser.add_argument(
        "--workers",
        type=integers(2, MAX_THREADS, one=True),
        default=2,
        help="the count to compare with 1",
    )
    parser.add_argument(
        "--rounds", type=integers(1, MAX_ROUNDS, one=True), default=2, help="runs of each count"
    )
    args = parser.parse_args()
    test = max(32, args.samples // 6)
    config = GeneratorConfig(train_size=max(32, args.samples - test), test_size=test)
    n = config.train_size + config.test_size
    catalog = load_catalog()
    rates = {1: [], args.workers: []}
    digests = set()
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for workers in rates:
                start = time.perf_counter()
                written = generate(
                    config,
                    [0.2],
                    catalog,
                    f"{tmp}/{r}-{workers}",
                    progress=False,
                    preview=False,
                    workers=workers,
                )
                rates[workers].append(n / (time.perf_counter() - start))
                digests.add(digest(written[0].path))
    one, many = (statistics.median(rates[w]) for w in rates)
    print(f"{n} samples, {args.rounds} rounds, median samples/s:")
    print(f"  --workers 1: {one:7.0f}")
    print(f"  --workers {args.workers}: {many:7.0f}  ratio {many / one:.2f} (target >= 1.8)")
    print(f"  the same bytes for every count: {'yes' if len(digests) == 1 else 'NO'}")


if __name__ == "__main__":
    run(main)
