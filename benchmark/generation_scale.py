"""Generate a very large dataset and report samples/s, peak memory per process and disk size:

    python benchmark/generation_scale.py [--samples 10000000] [--small 100000] [--workers 2]
        [--out DIR] [--keep]

Each size runs in a fresh process (peak memory is a process's lifetime high): first ``--small``
samples, then ``--samples``, the same options otherwise (one noise level, 0.2; the default
shard size, so the large run is written as shards; 90 % train, 10 % test). Memory is flat in
the number of samples when the two runs' peaks are about equal. The dataset is written under
``--out`` (default: a temporary folder) and removed unless ``--keep``. docs/performance.md
("Scale") records the figures.
"""

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from simlidar.bench.hardware import MAX_THREADS
from simlidar.generator.config import MAX_SPLIT_SIZE
from simlidar.script_args import integers, run

# a tenth of the samples is the test split, at least one sample of each of the 32 classes
SAMPLES = integers(320, MAX_SPLIT_SIZE, one=True)


def child(samples: int, workers: int, out: str) -> None:
    """One generation in this process; prints its figures as one JSON line."""
    from simlidar.generator.config import GeneratorConfig
    from simlidar.generator.generate import generate
    from simlidar.scene.recipe import load_catalog

    test = samples // 10
    config = GeneratorConfig(train_size=samples - test, test_size=test)
    start = time.perf_counter()
    (written,) = generate(config, [0.2], load_catalog(), out, progress=True, workers=workers)
    seconds = time.perf_counter() - start
    files = [p for p in written.path.iterdir() if p.is_file()]
    print(
        json.dumps(
            {
                "samples": samples,
                "seconds": seconds,
                "samples_per_s": samples / seconds,
                "peak_rss_mb_main": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                "peak_rss_mb_worker": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
                "disk_mb": sum(p.stat().st_size for p in files) / 2**20,
                "split_files": sum(p.suffix == ".h5" for p in files),
            }
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=SAMPLES, default=10_000_000, help="the large run")
    parser.add_argument("--small", type=SAMPLES, default=100_000, help="the small run (memory)")
    parser.add_argument("--workers", type=integers(1, MAX_THREADS, one=True), default=2)
    parser.add_argument("--out", default=None, help="folder for the datasets (default: temp)")
    parser.add_argument("--keep", action="store_true", help="keep the datasets")
    parser.add_argument("--child", type=SAMPLES, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.out is not None and not Path(args.out).is_dir():
        parser.error(f"--out {args.out!r}: expected an existing folder")
    if args.child is not None:
        child(args.child, args.workers, args.out)
        return
    with tempfile.TemporaryDirectory(dir=args.out) as tmp:
        root = Path(args.out) if args.keep and args.out else Path(tmp)
        for size in (args.small, args.samples):
            command = [sys.executable, __file__, "--child", str(size)]
            command += ["--workers", str(args.workers), "--out", str(root / str(size))]
            line = subprocess.run(command, check=True, stdout=subprocess.PIPE, text=True)
            r = json.loads(line.stdout.strip().splitlines()[-1])
            print(
                f"{r['samples']:>11,} samples, --workers {args.workers}: {r['samples_per_s']:,.0f}"
                f" samples/s ({r['seconds'] / 60:.1f} min), peak memory {r['peak_rss_mb_main']:.0f}"
                f" MB (writer) / {r['peak_rss_mb_worker']:.0f} MB (largest worker), "
                f"{r['disk_mb']:,.0f} MB on disk in {r['split_files']} split files",
                flush=True,
            )


if __name__ == "__main__":
    run(main)
