"""How fast pulse streams are made: streams a minute on one core for the default span (issue 60's
target: at least 1,000), and a stream's CPU time a pulse against a window in motion's, measured
in the same run.

    python benchmark/stream_speed.py [--streams 256] [--repeats 3] [--batch 64] [--json FILE]

1. **Simulation.** :func:`simlidar.generator.pulse_streams.simulate_streams` (``simlidar
   stream`` without the file) over ``--streams`` streams of the train split, ``--batch`` at a
   time (the CLI's default), the median of ``--repeats`` rounds after one to warm up: CPU
   seconds, streams a minute, and the µs a pulse cast (every draw counted: a stream redrawn
   three times casts its pulses three times).
2. **Reference.** The same number of pulses as windows in motion (``simlidar generate --timing
   scan --ego-speed 10 --moving-objects``: :func:`simlidar.generator.simulate.simulate`), the
   same way: µs a pulse; the ratio of the two.
3. **Whole files.** :func:`simlidar.generator.stream_files.generate_streams` writing a dataset
   of ``--streams`` train and a quarter as many test streams (no preview): streams a minute,
   the HDF5 writing, card and checksums included.

The process pins itself to one CPU before numpy and Embree start their thread pools and
measures CPU time (the machine is shared: a wall clock would count the others' work).
"""

import os

if hasattr(os, "sched_setaffinity"):
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from simlidar.generator.config import GeneratorConfig  # noqa: E402
from simlidar.generator.pulse_streams import simulate_streams  # noqa: E402
from simlidar.generator.simulate import simulate  # noqa: E402
from simlidar.generator.stream_config import StreamConfig  # noqa: E402
from simlidar.generator.stream_files import generate_streams  # noqa: E402
from simlidar.scene.recipe import load_catalog  # noqa: E402
from simlidar.script_args import in_folder, integers, run  # noqa: E402
from simlidar.sensor.moving import OBJECT_CELLS  # noqa: E402


def _cpu(run) -> tuple[float, object]:
    start = time.process_time()
    out = run()
    return time.process_time() - start, out


def _rounds(run, repeats: int) -> tuple[float, object]:
    run()  # warm up: imports, kernels, caches
    times, out = [], None
    for _ in range(repeats):
        seconds, out = _cpu(run)
        times.append(seconds)
    return statistics.median(times), out


def measure(streams: int, repeats: int, batch: int) -> dict:
    catalog = load_catalog()
    config = StreamConfig(train_size=streams, test_size=max(4, streams // 4))

    def streams_run():
        return [simulate_streams(config, catalog, "train", s, min(s + batch, streams))
                for s in range(0, streams, batch)]  # fmt: skip

    stream_s, batches = _rounds(streams_run, repeats)
    attempts = sum(int(b.attempts.sum()) for b in batches)
    pulses = attempts * config.sensor.beams * config.width * config.rotations
    events = sum(int(b.event_count.sum()) for b in batches)

    window = GeneratorConfig(timing="scan", ego_speed_mps=10.0, moving_objects=True,
                             train_size=64, test_size=64)  # fmt: skip
    windows = pulses // (window.sensor.beams * window.width)  # as many pulses (first draws)

    def windows_run():
        return [simulate(window, catalog, "train", s, min(s + 512, windows))
                for s in range(0, windows, 512)]  # fmt: skip

    window_s, samples = _rounds(windows_run, repeats)
    window_pulses = sum(int(s.attempts.sum()) for s in samples) * window.sensor.beams * window.width

    with tempfile.TemporaryDirectory() as tmp:
        files_s, _ = _cpu(lambda: generate_streams(Path(tmp), train_size=streams,
                                                   test_size=max(4, streams // 4),
                                                   progress=False, preview=False))  # fmt: skip
    written = streams + max(4, streams // 4)
    us_stream = stream_s / pulses * 1e6
    us_window = window_s / window_pulses * 1e6
    return {
        "streams": streams,
        "rotations": config.rotations,
        "width": config.width,
        "pulses_a_stream": config.sensor.beams * config.width * config.rotations,
        "draws_a_stream": attempts / streams,
        "events_a_stream": events / streams,
        "simulate_cpu_s": stream_s,
        "simulate_streams_per_min": streams / stream_s * 60.0,
        "us_per_pulse_stream": us_stream,
        "us_per_pulse_window_in_motion": us_window,
        "ratio_stream_to_window": us_stream / us_window,
        "files_cpu_s": files_s,
        "files_streams_per_min": written / files_s * 60.0,
        "target_streams_per_min": 1000,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--streams", type=integers(4, 100_000, one=True), default=256)
    parser.add_argument("--repeats", type=integers(1, 100, one=True), default=3)
    parser.add_argument("--batch", type=integers(1, OBJECT_CELLS, one=True), default=64)
    parser.add_argument("--json", type=in_folder, default=None, help="also write the figures")
    args = parser.parse_args(argv)
    figures = measure(args.streams, args.repeats, args.batch)
    f = figures
    print(
        f"streams of {f['rotations']} rotations x {f['width']} columns x 16 lasers "
        f"({f['pulses_a_stream']} pulses), one core, CPU time, median of {args.repeats}"
    )
    print(f"  draws a stream {f['draws_a_stream']:.2f}, events a stream {f['events_a_stream']:.0f}")
    print(f"  simulate: {f['simulate_streams_per_min']:.0f} streams/min "
          f"(target {f['target_streams_per_min']}: "
          f"{'met' if f['simulate_streams_per_min'] >= 1000 else 'NOT met'})")  # fmt: skip
    print(f"  whole files: {f['files_streams_per_min']:.0f} streams/min")
    print(
        f"  us a pulse: stream {f['us_per_pulse_stream']:.3f}, window in motion "
        f"{f['us_per_pulse_window_in_motion']:.3f} (ratio {f['ratio_stream_to_window']:.2f})"
    )
    if args.json is not None:
        args.json.write_text(json.dumps(figures, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    run(main)
