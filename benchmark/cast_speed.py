"""The two forms of the random streams, the scenes and the ray cast, numpy and the compiled
kernels: speed, cost to load, and when they pay.

    python benchmark/cast_speed.py [--samples 22400,100000 | --no-end-to-end] [--runs 3] \
                                   [--rounds 10]

Pins itself to one CPU core and measures, one after the other:

* **the random streams of one batch**: 1,024 samples' streams seeded and drawn as the
  generator's first attempt draws them, in numpy and by the kernel, the best of ``--rounds``
  each, in turn; the draws are checked to be the same to the last bit;
* **the scenes of one batch**: the first 1,024 training samples of ``simlidar generate
  --classes 32 --noise 0.2`` (the users' command: profile ``paper``, the default catalog and
  sensor), their scenes' parameters taken from the generator itself, built by
  :func:`simlidar.scene.build.build_batch` in numpy and with the kernel, the best of
  ``--rounds`` each, in turn; the two batches are checked to be the same to the last bit;
* **the cast of that batch**: their scenes and rays, cast by :func:`simlidar.sensor.raycast.cast`
  in numpy and through the kernels (Embree's BVH and queries included), likewise; the hits of
  the two are checked to be the same to the last bit;
* **the kernels' cost to load**: in fresh processes, the CPU time of the first compiled
  draws, build and cast of one sample (numba's import, its CPU target and the cached kernels)
  less that of the second;
* **end to end**: for each ``--samples`` N, ``simlidar generate --classes 32 --noise 0.2``
  with N samples (5/6 train, 1/6 test), the whole process, with the kernels forced on and
  forced off (``COMPILED_FROM_RAYS`` set before the run), ``--runs`` pairs, in turn; the
  median seconds of each and the median of the pairs' ratios. The two datasets' files are
  checked to be the same bytes.

What the default chooses is :func:`simlidar.sensor.raycast.compiled_for`: the kernels (the
streams', the scenes' and the cast's) from ``COMPILED_FROM_RAYS`` rays a process, where they
start to pay.
"""

import os

if hasattr(os, "sched_setaffinity"):
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import filecmp  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import simlidar.generator.simulate as simulate_module  # noqa: E402
from simlidar.generator.config import GeneratorConfig  # noqa: E402
from simlidar.generator.profiles import load_profile  # noqa: E402
from simlidar.generator.streams import Streams  # noqa: E402
from simlidar.scene.build import build_batch  # noqa: E402
from simlidar.scene.recipe import load_catalog  # noqa: E402
from simlidar.script_args import integers, run  # noqa: E402
from simlidar.sensor import raycast  # noqa: E402

BATCH = 1024

# A fresh process: CPU seconds of its first compiled draws, build and cast of one sample, then
# of its second.
LOAD = """
import sys, time
import numpy as np
sys.path.insert(0, {here!r})
from cast_speed import first_batch
from simlidar.generator.streams import Streams
from simlidar.scene.build import build_batch
from simlidar.sensor.raycast import cast
built, args = first_batch(1)
spent = []
for _ in range(2):
    start = time.process_time()
    Streams(0, 0, np.arange(1), compiled=True).random(1)
    build_batch(*built, compiled=True)
    cast(*args, compiled=True)
    spent.append(time.process_time() - start)
print(spent[0] - spent[1])
"""

# A fresh process: simlidar generate with the kernels forced on or off.
GENERATE = """
import sys
import simlidar.sensor.raycast as raycast
raycast.COMPILED_FROM_RAYS = {threshold}
from simlidar.cli import main
main(sys.argv[1:], prog_name="simlidar")
"""


def first_batch(size: int = BATCH):
    """The arguments of ``build_batch`` and of the cast for the first ``size`` training samples
    of the users' command (their first draws: redraws are built and cast apart)."""
    config = GeneratorConfig.from_profile(load_profile("paper"), noise=0.2)
    taken = {"build_batch": [], "cast": []}
    kept = {name: getattr(simulate_module, name) for name in taken}

    def keeper(name):
        def keep(*args, **kwargs):
            taken[name].append(args)
            return kept[name](*args, **kwargs)

        return keep

    for name in taken:
        setattr(simulate_module, name, keeper(name))
    try:
        simulate_module.simulate(config, load_catalog(), "train", 0, size)
    finally:
        for name, function in kept.items():
            setattr(simulate_module, name, function)
    return taken["build_batch"][0], taken["cast"][0]


def best(step, rounds: int) -> float:
    times = []
    for _ in range(rounds):
        start = time.process_time()
        step()
        times.append(time.process_time() - start)
    return min(times)


def draws(n: int, columns: int, compiled: bool):
    """The draws of one batch's first attempt, as the generator makes them (its streams
    seeded, the 2 doubles of the class factors, the 16 x 16 noise variates, the attempt's
    doubles), in numpy or by the compiled kernel."""
    streams = Streams(0, 0, np.arange(n), compiled=compiled)
    return streams.random(2), streams.random_float32((16, 16)), streams.random(columns)


def same_scenes(a, b) -> bool:
    """The two builds' scene batches, byte for byte."""
    fields = ("triangles", "surface", "sample", "closed", "is_object", "object_pose")
    return all(getattr(a, f).tobytes() == getattr(b, f).tobytes() for f in fields)


def same_hits(a, b) -> bool:
    """The two casts' hits, byte for byte."""
    fields = ("range_m", "surface", "on_object")
    return all(getattr(a, f).tobytes() == getattr(b, f).tobytes() for f in fields)


def generate_seconds(samples: int, threshold: int, out: Path) -> float:
    """Wall seconds of one ``simlidar generate`` process with COMPILED_FROM_RAYS = threshold."""
    test = samples // 6
    command = [sys.executable, "-c", GENERATE.format(threshold=threshold), "generate",
               "--classes", "32", "--noise", "0.2", "--train-size", str(samples - test),
               "--test-size", str(test), "--out", str(out), "--force"]  # fmt: skip
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    return time.perf_counter() - start


def same_folders(a: Path, b: Path) -> bool:
    names = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    if names != sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file()):
        return False
    return all(filecmp.cmp(a / n, b / n, shallow=False) for n in names)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=integers(12), default=(22400, 100000),
                        help="end-to-end run sizes (comma-separated)")  # fmt: skip
    parser.add_argument("--no-end-to-end", action="store_true", help="skip the end-to-end runs")
    parser.add_argument("--runs", type=integers(1, 20, one=True), default=3)
    parser.add_argument("--rounds", type=integers(1, 100, one=True), default=10)
    args = parser.parse_args()
    print(f"one core (cpu {sorted(os.sched_getaffinity(0))[0]}); default: the kernels from "
          f"{raycast.COMPILED_FROM_RAYS:,} rays a process")  # fmt: skip

    built, batch = first_batch()
    scene, origins = batch[0], batch[1]
    n = len(origins)
    columns = 2 + built[3].shape[1] + built[4].shape[1]  # an attempt's: fixed, layout, object
    numpy_draws = draws(n, columns, False)
    compiled_draws = draws(n, columns, True)  # loads the kernel
    draws_numpy_s = best(lambda: draws(n, columns, False), args.rounds)
    draws_compiled_s = best(lambda: draws(n, columns, True), args.rounds)
    print(f"\nrandom streams of one batch ({n} samples: seeded, the class factors' 2 doubles, "
          f"16 x 16 float32, an attempt's {columns} doubles), CPU us a sample, best of "
          f"{args.rounds}:")  # fmt: skip
    print(f"  numpy              {1e6 * draws_numpy_s / n:8.1f}")
    print(f"  compiled kernel    {1e6 * draws_compiled_s / n:8.1f}")
    print(f"  compiled / numpy   {draws_compiled_s / draws_numpy_s:8.3f}")
    same = all(a.tobytes() == b.tobytes() for a, b in zip(numpy_draws, compiled_draws))
    print(f"  draws the same to the last bit: {same}")
    numpy_scenes = build_batch(*built)
    compiled_scenes = build_batch(*built, compiled=True)  # loads the kernel
    build_numpy_s = best(lambda: build_batch(*built), args.rounds)
    build_compiled_s = best(lambda: build_batch(*built, compiled=True), args.rounds)
    print(f"\nscenes of one batch ({n} samples), CPU us a sample, best of {args.rounds}:")
    print(f"  numpy              {1e6 * build_numpy_s / n:8.1f}")
    print(f"  compiled kernel    {1e6 * build_compiled_s / n:8.1f}")
    print(f"  compiled / numpy   {build_compiled_s / build_numpy_s:8.3f}")
    print(f"  scenes the same to the last bit: {same_scenes(numpy_scenes, compiled_scenes)}")
    numpy_hits = raycast.cast(*batch)
    compiled_hits = raycast.cast(*batch, compiled=True)  # loads the kernels
    numpy_s = best(lambda: raycast.cast(*batch), args.rounds)
    compiled_s = best(lambda: raycast.cast(*batch, compiled=True), args.rounds)
    print(f"\ncast of one batch ({n} samples, {origins[0, ..., 0].size} rays each, "
          f"{len(scene.triangles) / n:.1f} triangles a sample before culling), CPU us a "
          f"sample, best of {args.rounds}:")  # fmt: skip
    print(f"  numpy              {1e6 * numpy_s / n:8.1f}")
    print(f"  compiled kernels   {1e6 * compiled_s / n:8.1f}")
    print(f"  compiled / numpy   {compiled_s / numpy_s:8.3f}")
    print(f"  hits the same to the last bit: {same_hits(numpy_hits, compiled_hits)}")
    saved = (numpy_s + build_numpy_s + draws_numpy_s) - (
        compiled_s + build_compiled_s + draws_compiled_s
    )
    saved_per_ray = saved / numpy_hits.range_m.size

    loads = []
    for _ in range(3):
        probe = [sys.executable, "-c", LOAD.format(here=str(Path(__file__).resolve().parent))]
        loads.append(float(subprocess.run(probe, capture_output=True, check=True).stdout))
    load_s = statistics.median(loads)
    print("\nloading the kernels (a fresh process's first compiled draws, build and cast less its "
          f"second, CPU s, 3 processes): {', '.join(f'{x:.3f}' for x in loads)}; median "
          f"{load_s:.3f}")  # fmt: skip
    if saved_per_ray > 0:
        print("  saved a ray in the batches above (draws, scenes, cast): "
              f"{1e6 * saved_per_ray:.3f} us; the kernels pay from about "
              f"{load_s / saved_per_ray / 1e6:.1f} million rays a process")  # fmt: skip

    sizes = () if args.no_end_to_end else args.samples
    if sizes:
        print(f"\nend to end, simlidar generate --classes 32 --noise 0.2, wall s, {args.runs} "
              "pairs in turn (median):")  # fmt: skip
        print(f"  {'samples':>8} {'numpy':>8} {'kernels':>8} {'ratio':>7}  same bytes")
    with tempfile.TemporaryDirectory() as tmp:
        for samples in sizes:
            folders = Path(tmp) / "numpy", Path(tmp) / "kernels"
            times, ratios = ([], []), []
            for _ in range(args.runs):
                a = generate_seconds(samples, 2**62, folders[0])
                b = generate_seconds(samples, 0, folders[1])
                times[0].append(a)
                times[1].append(b)
                ratios.append(b / a)
            same = same_folders(*folders)
            numpy_s, kernels_s = (statistics.median(t) for t in times)
            ratio = statistics.median(ratios)
            print(f"  {samples:>8} {numpy_s:8.2f} {kernels_s:8.2f} {ratio:7.3f}  {same}")


if __name__ == "__main__":
    run(main)
