"""Generation speed and memory, measured on one core.

    python benchmark/generation_speed.py [--samples 6000] [--naive-samples 300]
                                         [--memory 10000,100000] [--json FILE]

1. simlidar's way, end to end: ``generate`` with the default catalog, 16 x 16 samples, 32
   classes, HDF5 writing included (the preview picture is not).
2. The naive way on the same samples (same random streams, same sampled parameters): per
   sample, every primitive made with ``trimesh.creation`` and placed with a transform, the
   pieces gathered into one trimesh scene (a mesh), and trimesh's ray API
   (``mesh.ray.intersects_id``, itself Embree-backed when embreex is installed); then the same
   pulses and the same HDF5 writer. A second, stronger reference keeps simlidar's numpy builder
   and only casts one sample at a time through trimesh ("per-sample cast"). All ways run in
   this process, on the same core, one after the other, so the ratios are meaningful on a noisy
   machine.
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
from simlidar.dataset.schema import SHUFFLED, generated_shapes  # noqa: E402
from simlidar.dataset.writer import SplitWriter  # noqa: E402
from simlidar.generator.config import MAX_SPLIT_SIZE, GeneratorConfig  # noqa: E402
from simlidar.generator.generate import generate  # noqa: E402
from simlidar.generator.pulses import split_rows  # noqa: E402
from simlidar.generator.shard import generated_split_attrs  # noqa: E402
from simlidar.generator.simulate import simulate  # noqa: E402
from simlidar.scene.build import build_batch, place_instances  # noqa: E402
from simlidar.scene.recipe import load_catalog  # noqa: E402
from simlidar.script_args import in_folder, integers, run  # noqa: E402
from simlidar.sensor.raycast import MAX_BATCH, Hits  # noqa: E402


def _trimesh_hits(mesh, face_surface, face_object, origins, directions, max_range_m):
    """Cast one sample's rays at its mesh with trimesh's ray API: range, surface, on_object."""
    o, d = origins.reshape(-1, 3), directions.reshape(-1, 3)
    tri, ray, where = mesh.ray.intersects_id(o, d, multiple_hits=False, return_locations=True)
    r = np.linalg.norm(where - o[ray], axis=1)
    near = r <= max_range_m + 1.0
    range_m = np.full(len(o), np.nan)
    surface = np.zeros(len(o), np.uint8)
    on_object = np.zeros(len(o), bool)
    range_m[ray[near]] = r[near]
    surface[ray[near]] = face_surface[tri[near]]
    on_object[ray[near]] = face_object[tri[near]]
    shape = origins.shape[:-1]
    return range_m.reshape(shape), surface.reshape(shape), on_object.reshape(shape)


def _unit_mesh(kind: str, segments: int):
    """A trimesh primitive on the recipe's unit template convention (bottom centre at 0)."""
    import trimesh

    if kind == "box":
        mesh = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    elif kind == "cylinder":
        mesh = trimesh.creation.cylinder(radius=0.5, height=1.0, sections=segments)
    else:
        from simlidar.scene.primitives import arch

        return trimesh.Trimesh(**trimesh.triangles.to_kwargs(arch(segments).triangles))
    mesh.apply_translation((0.0, 0.0, 0.5))
    return mesh


def naive_backend(
    catalog, layout, obj, layout_uniforms, object_uniforms, origins, directions, slots, max_range_m,
    **options,
):  # fmt: skip
    """The naive way: per sample, trimesh primitives in one scene and trimesh's ray API
    (``options``, the batched backend's ``compiled`` on a long run, mean nothing here: trimesh
    casts)."""
    import trimesh

    results, poses = [], []
    for k in range(len(layout)):
        placed, pose = place_instances(
            catalog,
            layout[k : k + 1],
            obj[k : k + 1],
            layout_uniforms[k : k + 1],
            object_uniforms[k : k + 1],
        )
        meshes, surfaces, objects = [], [], []
        for inst in placed:
            for at, size, yaw in zip(inst.at, inst.size, inst.yaw_deg):
                mesh = _unit_mesh(inst.primitive.kind, inst.primitive.segments)
                transform = trimesh.transformations.rotation_matrix(np.deg2rad(yaw), (0, 0, 1))
                transform[:3, 3] = at
                mesh.apply_transform(transform @ np.diag([*size, 1.0]))
                meshes.append(mesh)
                surfaces.append(inst.primitive.surface)
                objects.append(inst.is_object)
        counts = [len(m.faces) for m in meshes]
        results.append(
            _trimesh_hits(
                trimesh.util.concatenate(meshes),
                np.repeat(surfaces, counts),
                np.repeat(objects, counts),
                origins[k],
                directions[k],
                max_range_m,
            )
        )
        poses.append(pose[0])
    hits = Hits(*(np.stack([r[i] for r in results]) for i in range(3)))
    return hits, np.stack(poses)


def per_sample_cast_backend(
    catalog, layout, obj, layout_uniforms, object_uniforms, origins, directions, slots, max_range_m,
    **options,
):  # fmt: skip
    """simlidar's numpy builder, but one trimesh mesh and one ray query per sample
    (``options`` as in :func:`naive_backend`)."""
    import trimesh

    scene = build_batch(catalog, layout, obj, layout_uniforms, object_uniforms)
    results = []
    for k in range(len(layout)):
        mine = np.nonzero(scene.sample == k)[0]
        tris = scene.triangles[mine]
        mesh = trimesh.Trimesh(**trimesh.triangles.to_kwargs(tris), process=False)
        results.append(
            _trimesh_hits(
                mesh,
                scene.surface[mine],
                scene.is_object[mine],
                origins[k],
                directions[k],
                max_range_m,
            )
        )
    hits = Hits(*(np.stack([r[i] for r in results]) for i in range(3)))
    return hits, scene.object_pose


def run_one_at_a_time(config, catalog, count, out: Path, backend):
    """Train samples 0..count-1, one scene at a time, written with the same HDF5 writer."""
    writer = SplitWriter(
        out / "train.h5",
        count,
        generated_shapes(config.sensor.beams, config.width),
        generated_split_attrs(config, catalog, "train"),
        SHUFFLED,
    )
    blocks = []
    for i in range(count):
        samples = simulate(config, catalog, "train", i, i + 1, backend=backend)
        writer.append(split_rows(samples, config))
        blocks.append(samples.clean_delays)
    writer.close()
    return np.concatenate(blocks)


def peak_memory_mb(samples: int, out: Path) -> float:
    """Max RSS of a fresh process that generates ``samples`` train samples (+ 32 test)."""
    code = (
        "import os, resource, sys;"
        "os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]});"
        "from simlidar.generator.config import GeneratorConfig;"
        "from simlidar.generator.generate import generate;"
        "from simlidar.scene.recipe import load_catalog;"
        "generate(GeneratorConfig(train_size=int(sys.argv[1]), test_size=32), [0.2],"
        " load_catalog(), sys.argv[2], progress=False, preview=False);"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(samples), str(out)],
        check=True,
        capture_output=True,
        text=True,
    )
    return int(done.stdout.split()[-1]) / 1024.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(  # a sixth of them the test split: at least one of each of 32 classes
        "--samples",
        type=integers(192, MAX_SPLIT_SIZE, one=True),
        default=6000,
        help="train + test, fast way",
    )
    parser.add_argument(
        "--naive-samples",
        type=integers(1, MAX_BATCH, one=True),
        default=300,
        help="at most the fast way's train samples",
    )
    parser.add_argument(
        "--memory",
        type=lambda text: integers(32, MAX_SPLIT_SIZE)(text) if text else (),  # 32 test samples
        default="10000,100000",
        help="sample counts, or ''",
    )
    parser.add_argument("--json", type=in_folder, default=None, help="also write figures here")
    args = parser.parse_args()
    if args.naive_samples > args.samples * 5 // 6:
        parser.error(
            f"--naive-samples {args.naive_samples}: expected at most the {args.samples * 5 // 6} "
            f"train samples of --samples {args.samples}"
        )

    catalog = load_catalog()
    train = args.samples * 5 // 6
    config = GeneratorConfig(train_size=train, test_size=args.samples - train)
    figures = {
        "simlidar_version": __version__,
        "machine": {
            "cpu": platform.processor() or platform.machine(),
            "cores_used": 1,
            "python": platform.python_version(),
        },
    }
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        generate(
            GeneratorConfig(train_size=64, test_size=32),
            [0.2],
            catalog,
            tmp / "warm",
            progress=False,
            preview=False,
        )
        start = time.perf_counter()
        generate(config, [0.2], catalog, tmp / "fast", progress=False, preview=False)
        fast = args.samples / (time.perf_counter() - start)
        print(f"{'simlidar (batched Embree)':32s}: {fast:8.0f} samples/s  ({args.samples} samples)")
        figures["samples_per_s"] = round(fast)

        batched = simulate(config, catalog, "train", 0, args.naive_samples).clean_delays
        for key, label, backend in (
            ("naive", "naive (trimesh scene per sample)", naive_backend),
            ("per_sample_cast", "per-sample cast (numpy builder)", per_sample_cast_backend),
        ):
            folder = tmp / key
            folder.mkdir()
            start = time.perf_counter()
            clean = run_one_at_a_time(config, catalog, args.naive_samples, folder, backend)
            rate = args.naive_samples / (time.perf_counter() - start)
            same = float(np.mean(clean == batched))
            print(
                f"{label:32s}: {rate:8.0f} samples/s  ({args.naive_samples} samples), "
                f"simlidar is {fast / rate:5.1f} x faster; identical pulses {100 * same:.2f} %"
            )
            figures[key] = {
                "samples_per_s": round(rate, 1),
                "ratio": round(fast / rate, 1),
                "identical_pulses": round(same, 5),
            }

        counts = list(args.memory)
        if counts:
            reference = peak_memory_mb(1000, tmp / "m-ref")
            print(f"peak memory, 1,000 samples (reference): {reference:7.1f} MB")
            figures["peak_memory_mb"] = {"1000": round(reference, 1)}
            for count in counts:
                peak = peak_memory_mb(count, tmp / f"m-{count}")
                print(
                    f"peak memory, {count:,} samples: {peak:7.1f} MB "
                    f"({peak / reference:.2f} x the reference)"
                )
                figures["peak_memory_mb"][str(count)] = round(peak, 1)
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    run(main)
