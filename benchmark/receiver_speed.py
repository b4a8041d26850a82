"""What the receiver's model, its beam footprint, waveform and weather cost, and how often a
pulse sees two echoes.

    python benchmark/receiver_speed.py [--samples 1024] [--repeats 3]

Simulates the same ``--samples`` train samples (simulation only: no file writing) without a
receiver (the ``physical`` profile: every hit returns, the reference of issue 41's goal, "within
1.5x of today's samples/s"), through the receiver with one ray a pulse and its strongest
return (the ``sensor`` profile's 4.0.0 path), one ray through the waveform (``--return-mode
dual``), footprints of Q = 2 and 3 rings (7 and 19 sub-rays), fog of 50 m, rain of 50 mm/h and
a stored waveform of 1 ns bins, each the best of ``--repeats`` runs taken in turn, on one core;
prints samples/s, the ratio to the reference and to the 4.0.0 path measured in the same run,
and the share of pulses whose waveform held two detected echoes or more.
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

CASES = {  # name: (profile, config fields)
    "no receiver (physical)": ("physical", {}),
    "one ray, strongest (4.0.0)": ("sensor", {}),
    "one ray, waveform (dual)": ("sensor", {"return_mode": "dual"}),
    "Q = 2, dual": ("sensor", {"beam_samples": 2, "return_mode": "dual"}),
    "Q = 3, strongest": ("sensor", {"beam_samples": 3}),
    "fog 50 m": ("sensor", {"fog_visibility_m": 50.0}),
    "rain 50 mm/h": ("sensor", {"rain_rate_mm_h": 50.0}),
    "waveform stored, 1 ns": ("sensor", {"waveform_bin_ns": 1.0}),
}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=integers(32, MAX_BATCH, one=True), default=1024)
    parser.add_argument("--repeats", type=integers(1, 100, one=True), default=3)
    args = parser.parse_args(argv)
    catalog = load_catalog()
    configs = {
        name: GeneratorConfig.from_profile(
            load_profile(profile), train_size=args.samples, test_size=32, **fields
        )
        for name, (profile, fields) in CASES.items()
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
    reference, receiver = (best[name] for name in list(CASES)[:2])
    print(f"{args.samples} samples, best of {args.repeats}, one core")
    print(
        "| case | sub-rays | samples/s | ratio to no receiver | ratio to one ray, strongest | "
        "pulses with 2+ echoes |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for name, config in configs.items():
        share = f"{100 * two[name]:.3f} %" if name in two else "-"
        print(
            f"| {name} | {subray_count(config.beam_samples)} | {args.samples / best[name]:.0f} | "
            f"{reference / best[name]:.3f} | {receiver / best[name]:.3f} | {share} |"
        )
    return 0


if __name__ == "__main__":
    run(main)
