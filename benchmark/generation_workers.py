"""Samples per second of the users' ``simlidar generate`` with one worker process and with
several, in one run on the same configuration, and their ratio:

    python benchmark/generation_workers.py [--samples 44800] [--workers 2] [--rounds 3]

Each round runs ``simlidar generate --classes 32 --noise 0.2`` (the ``paper`` profile, the
preview, card and checksums included: the command as users run it, a process of its own, its
start-up imports included) once with ``--workers 1`` and once with ``--workers N``, in turn so
that a change of load falls on both, into a temporary folder, and checks that both wrote the
same bytes. Target (issue 43): ``--workers 2`` at least 1.8 times the samples per second of
``--workers 1`` on the 2-core machine at 44,800 samples. docs/performance.md records the
figures.
"""

import argparse
import hashlib
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from simlidar.bench.hardware import MAX_THREADS
from simlidar.generator.config import MAX_SPLIT_SIZE
from simlidar.script_args import integers, run

MAX_ROUNDS = 1000


def digest(path: Path) -> str:
    h = hashlib.sha256()
    for file in sorted(path.iterdir()):
        h.update(file.name.encode() + file.read_bytes())
    return h.hexdigest()


def generate(out: Path, train: int, test: int, workers: int) -> float:
    """Seconds the users' command takes, in a process of its own."""
    command = [sys.executable, "-m", "simlidar.cli", "generate", "--classes", "32"]
    command += ["--noise", "0.2", "--train-size", str(train), "--test-size", str(test)]
    command += ["--workers", str(workers), "--out", str(out)]
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, cwd=Path(__file__).parents[1])
    if done.returncode:
        lines = done.stderr.strip().splitlines() or ["no message"]
        raise SystemExit(f"simlidar generate --workers {workers} failed: {lines[-1]}")
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--samples",
        type=integers(64, MAX_SPLIT_SIZE, one=True),
        default=44_800,
        help="train + test samples (a seventh of them the test split, as 19,200 + 3,200)",
    )
    parser.add_argument(
        "--workers",
        type=integers(2, MAX_THREADS, one=True),
        default=2,
        help="the count to compare with 1",
    )
    parser.add_argument(
        "--rounds", type=integers(1, MAX_ROUNDS, one=True), default=3, help="runs of each count"
    )
    args = parser.parse_args()
    test = max(32, args.samples // 7)
    train = args.samples - test
    rates = {1: [], args.workers: []}
    digests = set()
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for workers in rates:
                out = Path(tmp) / f"{r}-{workers}"
                rates[workers].append(args.samples / generate(out, train, test, workers))
                (dataset,) = out.iterdir()
                digests.add(digest(dataset))
    one, many = (statistics.median(rates[w]) for w in rates)
    print(f"{args.samples} samples, {args.rounds} rounds, median samples/s:")
    print(f"  --workers 1: {one:7.0f}")
    print(f"  --workers {args.workers}: {many:7.0f}  ratio {many / one:.2f} (target >= 1.8)")
    print(f"  the same bytes for every count: {'yes' if len(digests) == 1 else 'NO'}")


if __name__ == "__main__":
    run(main)
