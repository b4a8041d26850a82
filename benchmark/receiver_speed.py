"""What the receiver's beam footprint and waveform cost, and how often a pulse sees two echoes.

    python benchmark/receiver_speed.py [--samples 1024] [--repeats 3]

Simulates the same ``--samples`` train samples of the ``sensor`` profile (simulation only: no
file writing) with one ray a pulse and its strongest return (the 4.0.0 path, the reference),
one ray through the waveform (``--return-mode dual``), and footprints of Q = 2 and 3 rings
(7 and 19 sub-rays), each the best of ``--repeats`` runs taken in turn, on one core; prints
samples/s, the ratio to the reference measured in the same run, and the share of pulses whose
waveform held two detected echoes or more.
"""

import os

if hasattr(os, "sched_setaffinity"):
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

from simlidar.generator.config import GeneratorConfig  # noqa: E402
from simlidar.generator.profiles import load_profile  # noqa: E402
from simlidar.generator.simulate import simulate  # noqa: E402
from simlidar.scene.recipe import load_catalog  # noqa: E402
from simlidar.script_args import integers, run  # noqa: E402
from simlidar.sensor.footprint import subray_count  # noqa: E402
from simlidar.sensor.raycast import MAX_BATCH  # noqa: E402

CASES = {  # name: (beam_samples, return_mode)
    "one ray, strongest (4.0.0)": (1, "strongest"),
    "one ray, waveform (dual)": (1, "dual"),
    "Q = 2, dual": (2, "dual"),
    "Q = 3, strongest": (3, "strongest"),
}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=integers(32, MAX_BATCH, one=True), default=1024)
    parser.add_argument("--repeats", type=integers(1, 100, one=True), default=3)
    args = parser.parse_args(argv)
    catalog, profile = load_catalog(), load_profile("sensor")
    configs = {
        name: GeneratorConfig.from_profile(
            profile, train_size=args.samples, test_size=32, beam_samples=q, return_mode=mode
        )
        for name, (q, mode) in CASES.items()
    }
    best = {name: float("inf") for name in CASES}
    two = {}
    for _ in range(args.repeats):
        for name, config in configs.items():
            start = time.perf_counter()
            samples = simulate(config, catalog, "train", 0, args.samples)
            best[name] = min(best[name], time.perf_counter() - start)
            if samples.echoes is not None:
                two[name] = float((samples.echoes >= 2).mean())
    reference = best[next(iter(CASES))]
    print(f"{args.samples} sensor samples, best of {args.repeats}, one core")
    print("| case | sub-rays | samples/s | ratio to one ray | pulses with 2+ echoes |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, (q, _) in CASES.items():
        share = f"{100 * two[name]:.3f} %" if name in two else "-"
        print(
            f"| {name} | {subray_count(q)} | {args.samples / best[name]:.0f} | "
            f"{reference / best[name]:.3f} | {share} |"
        )
    return 0


if __name__ == "__main__":
    run(main)
