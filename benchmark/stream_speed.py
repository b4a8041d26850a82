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
4. **Through the receiver.** The same streams through the calibrated receiver (``--profile
   sensor``) in clear air, fog of 50 m visibility and rain of 50 mm/h, the same way: streams a
   minute, and what the receiver made of them against the streams without one (the same
   scenes): events a stream, the share that are the weather's or the noise's echoes (surface
   0), the share of the object's hits detected, and the objects it never detected.

``--doc FILE`` puts the table between FILE's lines ``<!-- stream-speed:start -->`` and
``<!-- stream-speed:end -->`` (docs/streams.md); ``--from-json FILE`` writes it from committed
figures without measuring.

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
import sys  # noqa: E402
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
import reproduction_table  # noqa: E402

DOC_START, DOC_END = "<!-- stream-speed:start -->", "<!-- stream-speed:end -->"
# the receiver's conditions measured: (name, StreamConfig's fields)
RECEIVER_RUNS = (
    ("clear air", {"profile": "sensor"}),
    ("fog, V = 50 m", {"profile": "sensor", "fog_visibility_m": 50.0}),
    ("rain, 50 mm/h", {"profile": "sensor", "rain_rate_mm_h": 50.0}),
)
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


def _simulated(config: StreamConfig, catalog, repeats: int, batch: int) -> tuple[float, list]:
    """The train split's ``config.train_size`` streams simulated ``batch`` at a time, in
    :func:`_rounds`: the median CPU seconds and the batches."""
    streams = config.train_size

    def streams_run():
        return [simulate_streams(config, catalog, "train", s, min(s + batch, streams))
                for s in range(0, streams, batch)]  # fmt: skip

    return _rounds(streams_run, repeats)


def measure(streams: int, repeats: int, batch: int) -> dict:
    catalog = load_catalog()
    config = StreamConfig(train_size=streams, test_size=max(4, streams // 4))

    stream_s, batches = _simulated(config, catalog, repeats, batch)
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
    receiver = {
        name: _received(StreamConfig(train_size=streams, test_size=max(4, streams // 4), **more),
                        catalog, batches, repeats, batch)
        for name, more in RECEIVER_RUNS
    }  # fmt: skip
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
        "receiver": receiver,
    }


def _received(config: StreamConfig, catalog, plain: list, repeats: int, batch: int) -> dict:
    """Streams through ``config``'s receiver: their speed, and what the receiver made of the
    hits of ``plain`` (the same streams without one)."""
    streams = config.train_size
    seconds, batches = _simulated(config, catalog, repeats, batch)
    events = sum(int(b.event_count.sum()) for b in batches)
    echoes = sum(int((b.event_surface == 0).sum()) for b in batches)
    hits = sum(int(b.object_events.sum()) for b in plain)
    seen = sum(int(b.object_events.sum()) for b in batches)
    objects = sum(int((b.object != 0).sum()) for b in batches)
    unseen = sum(int(((b.object != 0) & (b.object_events == 0)).sum()) for b in batches)
    return {
        "simulate_cpu_s": seconds,
        "simulate_streams_per_min": streams / seconds * 60.0,
        "events_a_stream": events / streams,
        "echo_share": echoes / events,
        "object_hits_detected": seen / hits,
        "objects": objects,
        "objects_unseen": unseen,
    }


def table(f: dict) -> list[str]:
    """The figures as docs/streams.md's table (markdown lines)."""
    rows = [
        "| | figure |",
        "| --- | ---: |",
        f"| pulses a stream ({f['rotations']} rotations x {f['width']} columns x 16 lasers) | "
        f"{f['pulses_a_stream']:,} |",
        f"| draws a stream / events a stream | {f['draws_a_stream']:.2f} / "
        f"{f['events_a_stream']:,.0f} |",
        f"| simulated, streams a minute | {f['simulate_streams_per_min']:,.0f} |",
        f"| written to files (HDF5, card, checksums), streams a minute | "
        f"{f['files_streams_per_min']:,.0f} |",
        f"| CPU us a pulse cast: stream / window in motion (same run) | "
        f"{f['us_per_pulse_stream']:.2f} / {f['us_per_pulse_window_in_motion']:.2f} "
        f"({f['ratio_stream_to_window']:.2f} x) |",
    ]
    if "receiver" in f:
        rows += [
            "",
            "Through the receiver (`--profile sensor`), the same streams:",
            "",
            "| | streams a minute | events a stream | weather's and noise's echoes | object's "
            "hits detected | objects never detected |",
            "| --- | ---: | ---: | ---: | ---: | ---: |",
        ]
        for name, r in f["receiver"].items():
            rows.append(
                f"| {name} | {r['simulate_streams_per_min']:,.0f} | {r['events_a_stream']:,.0f} | "
                f"{100 * r['echo_share']:.2f} % | {100 * r['object_hits_detected']:.1f} % | "
                f"{r['objects_unseen']} of {r['objects']} |"
            )
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--streams", type=integers(4, 100_000, one=True), default=256)
    parser.add_argument("--repeats", type=integers(1, 100, one=True), default=3)
    parser.add_argument("--batch", type=integers(1, OBJECT_CELLS, one=True), default=64)
    parser.add_argument("--json", type=in_folder, default=None, help="also write the figures")
    parser.add_argument(
        "--doc",
        type=reproduction_table.markdown_file,
        metavar="FILE",
        help=f"also put the table into FILE, between its lines {DOC_START} and {DOC_END}",
    )
    parser.add_argument(
        "--from-json",
        type=reproduction_table.markdown_file,
        metavar="FILE",
        help="measure nothing: the table of FILE's figures (with --doc, into the doc)",
    )
    args = parser.parse_args(argv)
    if args.doc is not None:  # its markers, before anything is measured
        reproduction_table.split(args.doc.read_text(), args.doc, DOC_START, DOC_END)
    if args.from_json is not None:
        figures = reproduction_table.read_json(args.from_json)
        print("\n".join(table(figures)))
        _write_doc(args.doc, figures)
        return 0
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
    for name, r in f["receiver"].items():
        print(
            f"  through the receiver, {name}: {r['simulate_streams_per_min']:.0f} streams/min, "
            f"{r['events_a_stream']:.0f} events a stream ({100 * r['echo_share']:.2f} % the "
            f"weather's or noise's), {100 * r['object_hits_detected']:.1f} % of the object's "
            f"hits detected, {r['objects_unseen']} of {r['objects']} objects never"
        )
    if args.json is not None:
        args.json.write_text(json.dumps(figures, indent=2) + "\n")
    _write_doc(args.doc, figures)
    return 0


def _write_doc(doc: Path | None, figures: dict) -> None:
    if doc is None:
        return
    before, _, after = reproduction_table.split(doc.read_text(), doc, DOC_START, DOC_END)
    doc.write_text(before + "\n".join(table(figures)) + "\n" + after)


if __name__ == "__main__":
    run(main)
