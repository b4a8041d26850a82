"""Where generation spends its time: CPU microseconds per sample for each stage, on one core.

    python benchmark/generation_stages.py [--samples 6144] [--profile paper] \
        [--cast auto|numpy|compiled]
    python benchmark/generation_stages.py --profile sensor [--beam-samples 2] \
        [--return-mode dual] [--fog 50] [--rain 50] [--waveform-bin 1]

Runs what ``simlidar generate --classes 32 --noise 0.2`` runs (the profile ``--profile``, by
default the command's own, ``paper``; 16 x 16 samples, the default catalog, HDF5 writing, the
preview, card, Croissant file and checksums included) with timers around the pipeline's
stages, after one untimed warm-up run, and prints each stage's share and the mean draws a
sample (the splits' ``attempts``). The preview is drawn by a process of its own while the
train split is written; on the one core both share, its figure is that process's CPU time.
The ray cast and the scenes' template copies take the form the run's size chooses (``--cast
auto``; docs/performance.md), or the one ``--cast`` names; through the compiled kernels, their
packing of vertices and rays, their exact range and the template copies are stages of their
own (the culling is "back-face culling" in either form; in the numpy form the copies are part
of "scene building", with the recipes' parameters and placement). The numpy around the cast
(its checks, the culling's mask to indices, the cells' offsets, the float32 copies of vertices
and rays and, in the numpy form, the exact float64 range) and the draws with their visibility
checks (the batch's factors, each draw's checks of the object's hits and the layout's visible
surfaces, the redraws' bookkeeping, the ranges' quantisation and the pulses' emission times)
are stages of their own, each less the timed stages it calls. "Other" is the whole run less
the timed stages: sharding the splits into batches, the workers' plumbing, claiming and
installing the folder. The timers add a few microseconds a sample;
``benchmark/generation_speed.py`` gives the untimed throughput. The process's start-up imports
are not in the run (``python -X importtime -m simlidar.cli --version`` shows them).

With a receiver (``--profile sensor``, and the options of ``simlidar generate`` that shape its
physics: ``--beam-samples``, ``--return-mode``, ``--fog``, ``--rain``, ``--waveform-bin``) the
receiver's work has stages of its own: the beam's sub-rays, the receiver's random streams, the
fog's backscatter table, the rain's drops and their echoes, the waveforms' echoes and peaks,
the reported returns, the stored waveform, and the rest of the receiver (materials, the range
equation, detection, range noise, intensity). Each stage's time is its own: a timed stage
inside another (the waveform inside the receiver) is not counted twice.
"""

import os

if hasattr(os, "sched_setaffinity"):
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import math  # noqa: E402
import resource  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402

import embreex.rtcore_scene as rtcs  # noqa: E402
import h5py  # noqa: E402
import numpy as np  # noqa: E402

import simlidar.generator.generate as generate_module  # noqa: E402
import simlidar.generator.returns as returns  # noqa: E402
import simlidar.generator.simulate as simulate  # noqa: E402
import simlidar.sensor.raycast as raycast  # noqa: E402
from simlidar.dataset.writer import SplitWriter  # noqa: E402
from simlidar.generator import shard as shard_module  # noqa: E402
from simlidar.generator.config import MAX_SPLIT_SIZE, GeneratorConfig  # noqa: E402
from simlidar.generator.generate import generate  # noqa: E402
from simlidar.generator.profiles import load_profile  # noqa: E402
from simlidar.generator.streams import Streams  # noqa: E402
from simlidar.scene.recipe import load_catalog  # noqa: E402
from simlidar.script_args import integers, numbers, run  # noqa: E402
from simlidar.sensor import embree  # noqa: E402
from simlidar.sensor.receiver import RETURN_MODES  # noqa: E402
from simlidar.sensor.weather import MAX_RAIN_MM_H  # noqa: E402

SPENT: dict[str, float] = defaultdict(float)
_INSIDE: list[float] = []  # per open timed call, the time its timed callees took


def timed(stage: str, fn):
    """``fn`` with its CPU time added to ``stage``, less that of the timed calls inside it."""

    def wrapper(*args, **kwargs):
        start = time.process_time()
        _INSIDE.append(0.0)
        try:
            return fn(*args, **kwargs)
        finally:
            spent = time.process_time() - start
            SPENT[stage] += spent - _INSIDE.pop()
            if _INSIDE:
                _INSIDE[-1] += spent

    return wrapper


# the receiver's stages (a profile with a receiver): module, function, stage
RECEIVER_STAGES = (
    (simulate, "subray_directions", "receiver: beam sub-rays"),
    (simulate, "receiver_stream", "receiver: random streams"),
    (simulate, "receive_hits", "receiver: materials, power, detection, noise"),
    (returns, "fog_table", "receiver: fog backscatter table"),
    (returns, "rain", "receiver: rain drops and echoes"),
    (returns, "_drop_echoes", "receiver: rain drops and echoes"),
    (returns, "echoes", "receiver: waveform echoes and peaks"),
    (returns, "reported", "receiver: reported returns"),
    (returns, "sampled", "receiver: stored waveform"),
)


class TimedScene(rtcs.EmbreeScene):
    """embreex's scene with its ``run`` timed in two parts: the BVH build (embreex commits the
    scene at its first ``run``; here a run of no rays commits it) and the ray queries.

    Same C layout at the same offsets as the base class, so the shared buffers still attach
    (the layout is checked on the base class, before this one is patched in).
    """

    def run(self, *args, **kwargs):
        if not self.is_committed:
            none = np.zeros((0, 3), np.float32)
            timed("Embree BVH build", super().run)(none, none, dists=np.zeros(0, np.float32))
        return timed("Embree ray queries", super().run)(*args, **kwargs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(  # a sixth of them the test split: at least one of each of 32 classes
        "--samples", type=integers(192, MAX_SPLIT_SIZE, one=True), default=6144, help="train + test"
    )
    parser.add_argument("--profile", default="paper", help="as simlidar generate --profile")
    receiver = parser.add_argument_group("a receiver's physics (as simlidar generate's)")
    receiver.add_argument("--beam-samples", type=integers(1, 8, one=True), default=1)
    receiver.add_argument("--return-mode", choices=RETURN_MODES, default="strongest")
    receiver.add_argument("--fog", type=numbers(1e-9, one=True), default=math.inf, help="m")
    receiver.add_argument("--rain", type=numbers(0.0, MAX_RAIN_MM_H, one=True), default=0.0)
    receiver.add_argument("--waveform-bin", type=numbers(0.0, one=True), default=0.0, help="ns")
    parser.add_argument("--cast", choices=("auto", "numpy", "compiled"), default="auto",
                        help="the form of the ray cast and the scenes' copies (auto: as the "
                             "run's size chooses)")  # fmt: skip
    args = parser.parse_args()
    if args.cast != "auto":
        raycast.COMPILED_FROM_RAYS = 0 if args.cast == "compiled" else 2**62
    physics = {
        "beam_samples": args.beam_samples,
        "return_mode": args.return_mode,
        "fog_visibility_m": args.fog,
        "rain_rate_mm_h": args.rain,
        "waveform_bin_ns": args.waveform_bin,
    }
    plain = {f.name: f.default for f in dataclasses.fields(GeneratorConfig)}
    asked = {k: v for k, v in physics.items() if v != plain[k]}
    config = GeneratorConfig.from_profile(
        load_profile(args.profile),
        train_size=args.samples * 5 // 6,
        test_size=args.samples // 6,
        **asked,
    )
    n = config.train_size + config.test_size
    catalog = load_catalog()
    compiled = raycast.compiled_for(simulate.run_rays(config))
    print(f"shared Embree buffers: {'on' if embree.shared_buffers() else 'off'}; the cast: "
          f"{'compiled kernels' if compiled else 'numpy'}")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        generate(config, [0.2], catalog, f"{tmp}/warm", progress=False, preview=False)
        for method in ("__init__", "random", "random_float32"):  # made and drawn, batched
            setattr(Streams, method, timed("random streams", getattr(Streams, method)))
        simulate.window_rays = timed("window rays", simulate.window_rays)
        stage = "draws and visibility checks"  # simulate's own work, less its timed callees
        generate_module.simulate = timed(stage, generate_module.simulate)
        simulate.cast = timed("numpy around the cast", simulate.cast)
        for name in ("delays_from_range", "shift_delays"):
            setattr(simulate, name, timed("pulses (range to delays)", getattr(simulate, name)))
        simulate.build_batch = timed("scene building", simulate.build_batch)
        raycast.visible_triangles = timed("back-face culling", raycast.visible_triangles)
        raycast.attach_triangles = timed("Embree geometry", raycast.attach_triangles)
        raycast.attach_vertices = timed("Embree geometry", raycast.attach_vertices)
        if compiled:  # loaded by the warm-up run
            from simlidar.sensor import cast_kernels

            for name in ("pack_vertices", "ray_origins"):
                stage = timed("packing vertices and rays (compiled)", getattr(cast_kernels, name))
                setattr(cast_kernels, name, stage)
            cast_kernels.first_hits = timed("exact range (compiled)", cast_kernels.first_hits)
            from simlidar.scene import kernels as scene_kernels

            scene_kernels.place_copies = timed(
                "template copies (compiled)", scene_kernels.place_copies
            )
        rtcs.EmbreeScene = TimedScene
        for module, name, stage in RECEIVER_STAGES if config.receiver is not None else ():
            setattr(module, name, timed(stage, getattr(module, name)))
        shard_module.split_rows = timed("profile and noise", shard_module.split_rows)
        SplitWriter.append = timed("HDF5 writing", SplitWriter.append)
        SplitWriter.close = timed("HDF5 writing", SplitWriter.close)  # the last chunks
        for name in ("write_croissant", "generated_croissant", "write_card", "generated_card",
                     "write_sums"):  # fmt: skip
            stage = timed("card, Croissant, checksums", getattr(generate_module, name))
            setattr(generate_module, name, stage)
        children = resource.getrusage(resource.RUSAGE_CHILDREN)
        start, cpu = time.perf_counter(), time.process_time()
        (written,) = generate(config, [0.2], catalog, f"{tmp}/timed", progress=False)
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu
        drawn = resource.getrusage(resource.RUSAGE_CHILDREN)  # the preview's process, reaped
        SPENT["preview.png (own process)"] = (drawn.ru_utime - children.ru_utime) + (
            drawn.ru_stime - children.ru_stime
        )
        total = cpu + SPENT["preview.png (own process)"]
        attempts = []
        for path in sorted(written.path.glob("*.h5")):
            with h5py.File(path, "r") as split:
                attempts.append(split["attempts"][:])
        attempts = np.concatenate(attempts)
    SPENT["other"] = total - sum(SPENT.values())
    print(
        f"{n} samples ({args.profile}) in {wall:.2f} s ({total:.2f} CPU-seconds, the preview's "
        f"process included): {n / wall:.0f} samples/s with the timers; {attempts.mean():.3f} "
        "draws a sample; CPU time a stage:"
    )
    for stage, seconds in sorted(SPENT.items(), key=lambda kv: -kv[1]):
        print(f"  {stage:46s} {1e6 * seconds / n:6.1f} us/sample  {100 * seconds / total:4.1f} %")


if __name__ == "__main__":
    run(main)
