"""One sampled scene per layout x object, written as mesh files for any viewer (trimesh)."""

from pathlib import Path

import numpy as np

from simlidar.atomic import write_file
from simlidar.errors import DatasetError
from simlidar.scene.build import build_batch
from simlidar.scene.recipe import Catalog

# One colour per surface label (RGBA), cycled if a catalog has more surfaces.
_PALETTE = np.array(
    [
        [128, 128, 128, 255],
        [70, 70, 70, 255],
        [110, 160, 80, 255],
        [190, 170, 140, 255],
        [150, 150, 170, 255],
        [170, 120, 90, 255],
        [120, 110, 100, 255],
        [200, 200, 210, 255],
        [240, 200, 60, 255],
        [40, 90, 200, 255],
        [220, 60, 60, 255],
        [200, 80, 200, 255],
    ],
    dtype=np.uint8,
)


def export_scenes(catalog: Catalog, out: str | Path, seed: int = 0, fmt: str = "glb"):
    """Write ``<layout>__<object>.<fmt>`` for every pair; return the written paths."""
    import trimesh

    out = Path(out)
    pairs = [(a, b) for a in range(len(catalog.layouts)) for b in range(len(catalog.objects))]
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(2,))))
    layout = np.array([p[0] for p in pairs])
    obj = np.array([p[1] for p in pairs])
    batch = build_batch(
        catalog,
        layout,
        obj,
        rng.random((len(pairs), catalog.layout_columns)),
        rng.random((len(pairs), catalog.object_columns)),
    )
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)  # only once every scene has been built
    except OSError as exc:
        raise DatasetError(f"{out}: cannot create the folder ({exc.strerror})") from None
    paths = []
    try:
        for k, (a, b) in enumerate(pairs):
            mine = batch.sample == k
            tris = batch.triangles[mine]
            mesh = trimesh.Trimesh(
                vertices=tris.reshape(-1, 3),
                faces=np.arange(3 * len(tris)).reshape(-1, 3),
                face_colors=_PALETTE[batch.surface[mine] % len(_PALETTE)],
                process=False,
            )
            path = out / f"{catalog.layouts[a].name}__{catalog.objects[b].name}.{fmt}"
            paths.append(write_file(path, lambda tmp, m=mesh: m.export(tmp, file_type=fmt)))
    except BaseException:  # all or nothing: remove what this call wrote
        for path in paths:
            path.unlink(missing_ok=True)
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise
    return paths
