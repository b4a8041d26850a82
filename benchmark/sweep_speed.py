"""Full-sweep speed on one core: VLP-16 frames per second against the window path's rays.

    python benchmark/sweep_speed.py [--frames 128] [--samples 8192] [--sensor vlp16] [--json FILE]

1. ``simulate_frames`` (``simlidar sweep`` without the file writing): every firing of whole
   rotations (16 x 1808 pulses a VLP-16 frame at 600 RPM) over the default catalog's scenes,
   ``FRAME_BATCH`` frames ray-cast together; frames per second, beside the target (100 frames/s
   on one core: 10 times a VLP-16's real time at 10 Hz).
2. The per-sample window path in the same process, on the same core: ``simulate`` of 16 x 16
   VLP-16 windows (``simlidar generate`` without noise and writing; the VLP-16 whatever
   ``--sensor`` says, as the HDL-64E cannot see every class of the shipped catalog through a
   window), batches of 1024. Both are
   printed as pulses (rays) per second, and their ratio: what casting whole rotations saves
   over casting windows.

The process pins itself to one CPU before numpy and Embree start their thread pools; each way
runs once to warm up, then timed.
"""

import os

if hasattr(os, "sched_setaffinity"):
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

from simlidar.generator.config import MAX_SPLIT_SIZE, GeneratorConfig  # noqa: E402
from simlidar.generator.generate import BATCH  # noqa: E402
from simlidar.generator.simulate import simulate  # noqa: E402
from simlidar.generator.sweep import FRAME_BATCH, MAX_FRAMES, simulate_frames  # noqa: E402
from simlidar.scene.recipe import load_catalog  # noqa: E402
from simlidar.script_args import in_folder, integers, run  # noqa: E402
from simlidar.sensor.model import load_sensor  # noqa: E402
from simlidar.sensor.rays import cycles_per_rotation  # noqa: E402

TARGET_FRAMES_PER_S = 100.0


def _timed(run, total: int, batch: int) -> float:
    """Seconds to run ``run(start, stop)`` over ``total`` items in batches, after a warm-up."""
    run(0, min(batch, total))
    start = time.perf_counter()
    for first in range(0, total, batch):
        run(first, min(first + batch, total))
    return time.perf_counter() - start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=integers(1, MAX_FRAMES, one=True), default=128)
    parser.add_argument(  # one window of each of the 32 classes at least
        "--samples", type=integers(32, MAX_SPLIT_SIZE, one=True), default=8192
    )
    parser.add_argument("--sensor", default="vlp16")
    parser.add_argument("--json", type=in_folder, default=None, help="also write the figures here")
    args = parser.parse_args(argv)
    catalog = load_catalog()
    config = GeneratorConfig(sensor=load_sensor(args.sensor), train_size=args.samples)
    window = GeneratorConfig(train_size=args.samples)  # the paper's VLP-16 windows
    sensor = config.sensor
    per_frame = sensor.beams * cycles_per_rotation(sensor)

    sweep_s = _timed(lambda a, b: simulate_frames(config, catalog, a, b), args.frames, FRAME_BATCH)
    window_s = _timed(lambda a, b: simulate(window, catalog, "train", a, b), args.samples, BATCH)
    frames_per_s = args.frames / sweep_s
    sweep_rays = args.frames * per_frame / sweep_s
    window_rays = args.samples * window.sensor.beams * window.width / window_s
    figures = {
        "sensor": sensor.name,
        "pulses_per_frame": per_frame,
        "frames": args.frames,
        "frames_per_s": round(frames_per_s, 1),
        "target_frames_per_s": TARGET_FRAMES_PER_S,
        "sweep_rays_per_s": round(sweep_rays),
        "window_samples_per_s": round(args.samples / window_s, 1),
        "window_rays_per_s": round(window_rays),
        "rays_ratio_sweep_over_window": round(sweep_rays / window_rays, 2),
    }
    print(
        f"sweep ({sensor.name}, {per_frame} pulses a frame): {frames_per_s:.1f} frames/s on one "
        f"core (target {TARGET_FRAMES_PER_S:g}: {frames_per_s / TARGET_FRAMES_PER_S:.2f}x), "
        f"{sweep_rays / 1e6:.2f} M pulses/s"
    )
    print(
        f"window path (VLP-16, 16 x {window.width} samples): {args.samples / window_s:.0f} "
        "samples/s, "
        f"{window_rays / 1e6:.2f} M pulses/s"
    )
    print(f"ratio of pulses/s, sweep over window: {sweep_rays / window_rays:.2f}")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    run(main)
