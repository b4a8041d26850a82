"""Generation speed and memory, measured on one core.

    python benchmark/generation_speed.py [--samples 6000] [--naive-samples 300]
                                         [--memory 10000,100000] [--json FILE]

1. simlidar's way, end to end: ``generate`` with the default catalog, 16 x 16 samples, 32
   classes, HDF5 writing included (the preview picture is not).
2. The naive way on the same samples: one trimesh mesh per sample and trimesh's ray API
   (``mesh.ray.intersects_id``, Embree-backed when embreex is installed), each sample then
   going through the same pulses and the same HDF5 writer. Both ways run in this process, on
   the same core, one after the other, so their ratio is meaningful on a noisy machine.
3. Peak memory (max RSS) of a fresh process generating 10,000 and 100,000 samples, beside the
   peak of a process that generates 1,000 (the reference measured in the same run).

The process pins itself to one CPU before numpy and Embree start their thread pools.
"""

import os
import sys

if hasattr(os, "sched_setaffinity"):
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from simlidar import __version__  # noqa: E402
from simlidar.dataset.config import GeneratorConfig  # noqa: E402
from simlidar.dataset.generate import generate, split_attrs  # noqa: E402
from simlidar.dataset.h5 import SplitWriter  # noqa: E402
from simlidar.scene.recipe import load_catalog  # noqa: E402
from simlidar.sensor.raycast import Hits  # noqa: E402
from simlidar.simulate import simulate  # noqa: E402


def naive_cast(scene, origins, directions, slots, max_range_m) -> Hits:
    """One trimesh mesh per sample and trimesh's ray API; same contract as ``cast``."""
    import trimesh

    shape = origins.shape[:-1]
    range_m = np.full(shape, np.nan)
    surface = np.zeros(shape, np.uint8)
    on_object = np.zeros(shape, bool)
    for k in range(shape[0]):
        mine = np.nonzero(scene.sample == k)[0]
        tris = scene.triangles[mine]
        mesh = trimesh.Trimesh(
            tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3), process=False
        )
        o, d = origins[k].reshape(-1, 3), directions[k].reshape(-1, 3)
        tri, ray, where = mesh.ray.intersects_id(o, d, multiple_hits=False, return_locations=True)
        r = np.linalg.norm(where - o[ray], axis=1)
        near = r <= max_range_m + 1.0
        flat_range = range_m[k].reshape(-1)
        flat_surface = surface[k].reshape(-1)
        flat_object = on_object[k].reshape(-1)
        flat_range[ray[near]] = r[near]
        flat_surface[ray[near]] = scene.surface[mine[tri[near]]]
        flat_object[ray[near]] = scene.is_object[mine[tri[near]]]
    return Hits(range_m, surface, on_object)


def run_naive(config, catalog, count, out: Path):
    """The naive way over train samples 0..count-1, written with the same HDF5 writer."""
    writer = SplitWriter(out / "train.h5", count, config.width, config.noise,
                         split_attrs(config, catalog, "train"))  # fmt: skip
    blocks = []
    for i in range(count):  # one scene per sample
        samples = simulate(config, catalog, "train", i, i + 1, caster=naive_cast)
        writer.append(samples)
        blocks.append(samples.clean_delays)
    writer.close()
    return np.concatenate(blocks)


def peak_memory_mb(samples: int, out: Path) -> float:
    """Max RSS of a fresh process that generates ``samples`` train samples (+ 32 test)."""
    code = (
        "import os, resource, sys;"
        "os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]});"
        "from simlidar.dataset.config import GeneratorConfig;"
        "from simlidar.dataset.generate import generate;"
        "from simlidar.scene.recipe import load_catalog;"
        "generate(GeneratorConfig(train_size=int(sys.argv[1]), test_size=32), [0.2],"
        " load_catalog(), sys.argv[2], progress=False, preview=False);"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)"
    )
    done = subprocess.run([sys.executable, "-c", code, str(samples), str(out)], check=True,
                          capture_output=True, text=True)  # fmt: skip
    return int(done.stdout.split()[-1]) / 1024.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=6000, help="train + test, fast way")
    parser.add_argument("--naive-samples", type=int, default=300)
    parser.add_argument("--memory", default="10000,100000", help="sample counts, or ''")
    parser.add_argument("--json", type=Path, default=None, help="also write figures here")
    args = parser.parse_args()

    catalog = load_catalog()
    train = args.samples * 5 // 6
    config = GeneratorConfig(train_size=train, test_size=args.samples - train)
    figures = {
        "simlidar_version": __version__,
        "machine": {
            "cpu": platform.processor() or platform.machine(),
            "cores_used": 1,
            "python": platform.python_version(),
        },  # fmt: skip
    }
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        generate(GeneratorConfig(train_size=64, test_size=32), [0.2], catalog, tmp / "warm",
                 progress=False, preview=False)  # fmt: skip
        start = time.perf_counter()
        generate(config, [0.2], catalog, tmp / "fast", progress=False, preview=False)
        fast = args.samples / (time.perf_counter() - start)
        print(f"simlidar (batched Embree) : {fast:8.0f} samples/s  ({args.samples} samples)")

        naive_dir = tmp / "naive"
        naive_dir.mkdir()
        start = time.perf_counter()
        naive_clean = run_naive(config, catalog, args.naive_samples, naive_dir)
        naive = args.naive_samples / (time.perf_counter() - start)
        print(f"naive (trimesh per sample): {naive:8.0f} samples/s  ({args.naive_samples} samples)")
        print(f"ratio                     : {fast / naive:8.1f} x")
        batched = simulate(config, catalog, "train", 0, args.naive_samples).clean_delays
        same = float(np.mean(batched == naive_clean))
        print(f"pulses identical in both ways: {100 * same:.3f} %")
        figures.update(samples_per_s=round(fast), naive_samples_per_s=round(naive, 1),
                       ratio=round(fast / naive, 1), identical_pulses=same)  # fmt: skip

        counts = [int(c) for c in args.memory.split(",") if c]
        if counts:
            reference = peak_memory_mb(1000, tmp / "m-ref")
            print(f"peak memory, 1,000 samples (reference): {reference:7.1f} MB")
            figures["peak_memory_mb"] = {"1000": round(reference, 1)}
            for count in counts:
                peak = peak_memory_mb(count, tmp / f"m-{count}")
                print(f"peak memory, {count:,} samples: {peak:7.1f} MB "
                      f"({peak / reference:.2f} x the reference)")  # fmt: skip
                figures["peak_memory_mb"][str(count)] = round(peak, 1)
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
